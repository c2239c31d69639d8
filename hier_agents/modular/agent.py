"""The option layer: estimate -> plan -> run a skill -> estimate again.

`ModularAgent` is a policy over options behind the observation boundary: it
is given the task's public description and timesteps, nothing else. Each
control step it estimates the scene (`Estimator`) and either keeps running
the current skill on it or starts a new option:

1. **plan** a `Subgoal` from the scene's abstract state (`Planner`; for
   Sokoban planners that offer ``next_push``, one subgoal is "walk to the
   box, push it once");
2. **run** the `Skill` on the subgoal and the scene until it reports success
   or failure, or for at most ``t_abs`` control steps (the paper's T_abs =
   50), then go back to 1.

A new option also starts as soon as the estimated state stops being one the
current subgoal expects (a box slid to another cell): for planners whose
states are values (Sokoban), the agent checks every ``check_every`` steps
while a skill runs and replans when the boxes are neither where the option
started nor where the subgoal's moves put them on the way. For board games
the skill's own status covers it (a different move registered is a failure).

Runs never abort:

* an estimate that cannot be made (`EstimationError`: two boxes in one
  cell, the walker not found) makes the agent hold still (the skill's
  ``hold`` action) and estimate again on the next step
  (``episode_stats.estimation_failures`` counts them);
* a planner with no plan (`NoPlanError`: a box pushed into a deadlock, the
  solver's budget) ends the episode for the agent: ``gave_up`` holds the
  reason and the agent holds still from then on (the run CLI stops the
  episode there and records it as a failure with that reason).

Counters (per episode and in total): subgoals issued, reached (the skill
reported success), failed (the skill reported failure), cut off (``t_abs``
reached first) and unfinished (still running when the episode ended, e.g. at
the time limit). The subgoal success rate is reached / (reached + failed +
cut off + unfinished).

`run_option` runs one skill on one subgoal to its end (tests, benchmarks).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from abstract_planners.base import NoPlanError, Planner, Subgoal
from hier_agents.estimators.base import EstimationError, Estimator
from skills.base import Skill, Status


@dataclass
class OptionStats:
    """Subgoal counters."""

    issued: int = 0
    reached: int = 0
    failed: int = 0
    cut_off: int = 0
    unfinished: int = 0
    estimation_failures: int = 0
    failures: dict = field(default_factory=dict)

    @property
    def success_rate(self) -> float:
        ended = self.reached + self.failed + self.cut_off + self.unfinished
        return self.reached / ended if ended else float("nan")

    def add(self, other: "OptionStats") -> None:
        self.issued += other.issued
        self.reached += other.reached
        self.failed += other.failed
        self.cut_off += other.cut_off
        self.unfinished += other.unfinished
        self.estimation_failures += other.estimation_failures
        for reason, count in other.failures.items():
            self.failures[reason] = self.failures.get(reason, 0) + count

    def fail(self, reason: str) -> None:
        self.failed += 1
        self.failures[reason] = self.failures.get(reason, 0) + 1


class ModularAgent:
    """Estimator + planner + skill, tied by the option layer.

    Args:
      estimator, planner, skill: the three roles.
      t_abs: control steps an option may run before the agent re-plans.
      use_pushes: give the skill whole "walk, then push" subgoals when the
        planner offers ``next_push`` (Sokoban); single moves otherwise.
      check_every: control steps between checks that the estimated boxes
        are still on the subgoal's path.
    """

    def __init__(self, estimator: Estimator, planner: Planner, skill: Skill, *, t_abs: int = 50,
                 use_pushes: bool = True, check_every: int = 5):
        if int(t_abs) < 1:
            raise ValueError(f"t_abs must be a positive number of control steps, got {t_abs!r}")
        self.estimator, self.planner, self.skill = estimator, planner, skill
        self.t_abs = int(t_abs)
        self._use_pushes = bool(use_pushes) and hasattr(planner, "next_push")
        self.episode_stats = OptionStats()
        self.subgoal: Subgoal | None = None
        self.description = None
        #: Why the agent gave up on the episode (a planner found no plan), or None.
        self.gave_up: str | None = None
        self.scene = None
        self._option_steps = 0
        self._check_every = max(1, int(check_every))
        self._expected: frozenset | None = None
        self._counted = True

    def close(self) -> None:
        """Closes the planner (a GNU Go subprocess), the skill and the
        estimator, each even if another one raised. Idempotent. The agent is
        also a context manager: ``with ModularAgent(...) as agent:``."""
        errors = []
        for part in (self.planner, self.skill, self.estimator):
            close = getattr(part, "close", None)
            if close is None:
                continue
            try:
                close()
            except Exception as exc:  # noqa: BLE001 - close the others first
                errors.append(exc)
        if errors:
            raise errors[0]

    def __enter__(self) -> "ModularAgent":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    @property
    def privileged(self) -> bool:
        """True when the estimator reads more than a robot observes."""
        return bool(getattr(self.estimator, "privileged", False))

    def reset(self, description, timestep, seed: int | None = None) -> None:
        """Starts an episode from the task's public ``description`` (see
        `envs.description`, ``env.description()``) and its first ``timestep``."""
        self.description = description
        self.planner.reset(seed)
        self.estimator.reset(description, timestep)
        self.episode_stats = OptionStats()
        self.subgoal = None
        self.gave_up = None
        self.scene = None
        self._option_steps = 0

    def act(self, timestep) -> np.ndarray:
        """The action for ``env.step`` after ``timestep``."""
        if self.gave_up is not None:
            return self.skill.hold()
        try:
            scene = self.estimator.estimate(timestep)
        except EstimationError:
            self.episode_stats.estimation_failures += 1
            return self.skill.hold()
        self.scene = scene
        if self.subgoal is not None:
            status = self.skill.status
            if not self._counted:  # holding still on a solved estimate: not a subgoal
                if status is not Status.RUNNING or self._option_steps >= self.t_abs:
                    self.subgoal = None
            elif status is Status.SUCCESS:
                self.episode_stats.reached += 1
                self.subgoal = None
            elif status is Status.FAILURE:
                self.episode_stats.fail(_reason_kind(self.skill.failure_reason))
                self.subgoal = None
            elif self._option_steps >= self.t_abs:
                self.episode_stats.cut_off += 1
                self.subgoal = None
            elif (self._expected is not None and self._option_steps % self._check_every == 0
                  and scene.state.boxes not in self._expected):
                self.episode_stats.fail("deviation")
                self.subgoal = None
        if self.subgoal is None:
            try:
                self._start_option(scene)
            except NoPlanError as exc:
                self.gave_up = f"no plan ({exc.reason}): {exc}"
                return self.skill.hold()
        self._option_steps += 1
        return self.skill.act(timestep, scene)

    def end_episode(self, timestep) -> None:
        """Closes the open option at the episode's last ``timestep``.

        The step that ends an episode usually completes the last subgoal (the
        final push, the winning touch), but `act` is not called after it; the
        skill is shown that timestep once (its action is discarded) so the
        subgoal is counted as reached or failed; a Sokoban subgoal whose boxes
        are all in place counts as reached. A subgoal still running then is
        counted in ``unfinished``.
        """
        if self.subgoal is None:
            return
        if not self._counted:
            self.subgoal = None
            return
        try:
            scene = self.estimator.estimate(timestep)
        except EstimationError:
            scene = None
        status = Status.RUNNING
        if scene is not None:
            self.skill.act(timestep, scene)
            status = self.skill.status
            if status is Status.RUNNING and hasattr(self.subgoal.state, "boxes"):
                # Sokoban: the last push put the boxes where the subgoal wanted
                # them (the walker may still be rolling; where no longer matters).
                if scene.state.boxes == self.subgoal.state.boxes:
                    status = Status.SUCCESS
        if status is Status.SUCCESS:
            self.episode_stats.reached += 1
        elif status is Status.FAILURE:
            self.episode_stats.fail(_reason_kind(self.skill.failure_reason))
        else:
            self.episode_stats.unfinished += 1
        self.subgoal = None

    def _start_option(self, scene) -> None:
        state = scene.state
        self._counted = True
        if getattr(state, "is_solved", None) is not None and state.is_solved():
            # Nothing left to plan (the boxes round onto the pads; the episode
            # ends once they cover them): hold, which the ball skill uses to
            # centre a box left short. Not counted as a subgoal.
            subgoal = Subgoal(action=(), state=state)
            self._counted = False
        elif self._use_pushes:
            subgoal = self.planner.next_push(state)
        else:
            subgoal = self.planner.plan(state)
        self.subgoal = subgoal
        self._option_steps = 0
        self.episode_stats.issued += int(self._counted)
        self._expected = _states_on_the_way(state, subgoal)
        self.skill.reset(self.description, subgoal, scene)


@dataclass
class OptionResult:
    """How one option ended: ``status`` (``SUCCESS``, ``FAILURE`` or
    ``RUNNING`` when cut off by ``t_abs`` or the episode's end), the skill's
    ``reason`` for a failure, the control ``steps`` taken and the last
    ``timestep``."""

    status: Status
    steps: int
    timestep: object
    reason: str | None = None


def run_option(env, estimator: Estimator, skill: Skill, subgoal: Subgoal, timestep, *,
               t_abs: int = 50, scene=None, on_step=None) -> OptionResult:
    """Runs ``skill`` on ``subgoal`` in ``env`` from ``timestep`` until it
    succeeds, fails, ``t_abs`` steps pass or the episode ends.

    The estimator must have been reset for this episode
    (``estimator.reset(env.description(), first_timestep)``). ``scene``
    (default: an estimate of ``timestep``) is the scene the subgoal was
    planned from. ``on_step(timestep, scene)``, if given, is called after
    every step (for tests that disturb the scene mid-option). Estimation
    failures hold the skill still, as in `ModularAgent`.
    """
    description = env.description()
    if scene is None:
        scene = estimator.estimate(timestep)
    skill.reset(description, subgoal, scene)
    steps, seen = 0, True
    while skill.status is Status.RUNNING and steps < t_abs and not timestep.last():
        action = skill.act(timestep, scene) if seen else skill.hold()
        if skill.status is not Status.RUNNING:
            break  # the skill saw its outcome in this timestep
        timestep = env.step(action)
        steps += 1
        try:
            scene, seen = estimator.estimate(timestep), True
        except EstimationError:
            seen = False
            continue
        if on_step is not None:
            on_step(timestep, scene)
    if timestep.last() and seen and skill.status is Status.RUNNING:
        skill.act(timestep, scene)  # let the skill see the final outcome
    return OptionResult(skill.status, steps, timestep, skill.failure_reason)


def _reason_kind(reason: str | None) -> str:
    """The kind of a skill's failure reason, for counting: the text before any
    colon (``"box off line: ... by 0.21 m"`` -> ``"box off line"``)."""
    return (reason or "unknown").split(":", 1)[0].strip() or "unknown"


def _states_on_the_way(state, subgoal: Subgoal) -> frozenset | None:
    """Box placements the subgoal's moves pass through, for Sokoban-like states
    (with ``boxes`` and ``apply``); None otherwise. Where the walker is between
    cells is the skill's business, so only boxes are checked."""
    if not (hasattr(state, "apply") and hasattr(state, "boxes")):
        return None
    moves = subgoal.action if isinstance(subgoal.action, tuple) else (subgoal.action,)
    states = [state]
    for move in moves:
        states.append(states[-1].apply(move))
    return frozenset(s.boxes for s in states)
