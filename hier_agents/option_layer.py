"""The option layer: estimate -> plan -> run a skill -> estimate again.

`ModularAgent` is a policy over options. Each control step it either keeps
running the current skill or starts a new option:

1. **estimate** the abstract state from the timestep (`Estimator`);
2. **plan** a `Subgoal` from it (`Planner`; for Sokoban planners that offer
   ``next_push``, one subgoal is "walk to the box, push it once");
3. **run** the `Skill` on the subgoal until it reports success or failure,
   or for at most ``t_abs`` control steps (the paper's T_abs = 50), then go
   back to 1.

A new option also starts as soon as the estimated state stops being one the
current subgoal expects (a box slid to another cell): for planners whose
states are values (Sokoban), the agent re-estimates every ``check_every``
steps while a skill runs and replans when the boxes are neither where the
option started nor where the subgoal's moves put them on the way. For board games the
skill's own status covers it (a different move registered is a failure).

Counters (per episode and in total): subgoals issued, reached (the skill
reported success), failed (the skill reported failure), cut off (``t_abs``
reached first) and unfinished (still running when the episode ended, e.g. at
the time limit). The subgoal success rate is reached / (reached + failed +
cut off + unfinished).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from abstract_planners.base import Planner, Subgoal
from hier_agents.estimators import Estimator
from skills.base import Skill, Status


@dataclass
class OptionStats:
    """Subgoal counters."""

    issued: int = 0
    reached: int = 0
    failed: int = 0
    cut_off: int = 0
    unfinished: int = 0
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
        for reason, count in other.failures.items():
            self.failures[reason] = self.failures.get(reason, 0) + count


class ModularAgent:
    """Estimator + planner + skill, tied by the option layer.

    Args:
      estimator, planner, skill: the three roles.
      t_abs: control steps an option may run before the agent re-estimates.
      use_pushes: give the skill whole "walk, then push" subgoals when the
        planner offers ``next_push`` (Sokoban); single moves otherwise.
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
        self._env = None
        self._option_steps = 0
        self._check_every = max(1, int(check_every))
        self._expected: frozenset | None = None

    def reset(self, env, timestep, seed: int | None = None) -> None:
        """Starts an episode in ``env`` from its first ``timestep``."""
        self._env = env
        self.planner.reset(seed)
        self.estimator.reset(env, timestep)
        self.episode_stats = OptionStats()
        self.subgoal = None
        self._option_steps = 0

    def act(self, timestep) -> np.ndarray:
        """The action for ``env.step`` after ``timestep``."""
        if self.subgoal is not None:
            status = self.skill.status
            if status is Status.SUCCESS:
                self.episode_stats.reached += 1
                self.subgoal = None
            elif status is Status.FAILURE:
                self.episode_stats.failed += 1
                reason = _reason_kind(self.skill.failure_reason)
                self.episode_stats.failures[reason] = self.episode_stats.failures.get(reason, 0) + 1
                self.subgoal = None
            elif self._option_steps >= self.t_abs:
                self.episode_stats.cut_off += 1
                self.subgoal = None
            elif (self._expected is not None and self._option_steps % self._check_every == 0
                  and self.estimator.estimate(self._env, timestep).boxes not in self._expected):
                self.episode_stats.failed += 1
                self.episode_stats.failures["deviation"] = (
                    self.episode_stats.failures.get("deviation", 0) + 1)
                self.subgoal = None
        if self.subgoal is None:
            self._start_option(timestep)
        self._option_steps += 1
        return self.skill.act(timestep)

    def end_episode(self, timestep) -> None:
        """Closes the open option at the episode's last ``timestep``.

        The step that ends an episode usually completes the last subgoal (the
        final push, the winning touch), but `act` is not called after it; the
        skill is shown that timestep once (its action is discarded; skills
        never change the simulation) so the subgoal is counted as reached or
        failed; a Sokoban subgoal whose boxes are all in place counts as
        reached. A subgoal still running then is counted in ``unfinished``.
        """
        if self.subgoal is None:
            return
        self.skill.act(timestep)
        status = self.skill.status
        if status is Status.RUNNING and hasattr(self.subgoal.state, "boxes"):
            # Sokoban: the last push put the boxes where the subgoal wanted them
            # (the walker may still be rolling; where it stops no longer matters).
            if self.estimator.estimate(self._env, timestep).boxes == self.subgoal.state.boxes:
                status = Status.SUCCESS
        if status is Status.SUCCESS:
            self.episode_stats.reached += 1
        elif status is Status.FAILURE:
            self.episode_stats.failed += 1
            reason = _reason_kind(self.skill.failure_reason)
            self.episode_stats.failures[reason] = self.episode_stats.failures.get(reason, 0) + 1
        else:
            self.episode_stats.unfinished += 1
        self.subgoal = None

    def _start_option(self, timestep) -> None:
        state = self.estimator.estimate(self._env, timestep)
        if getattr(state, "is_solved", None) is not None and state.is_solved():
            # Nothing left to plan (the episode ends on this step): hold still.
            subgoal = Subgoal(action=(), state=state)
            self.episode_stats.issued -= 1  # not a subgoal: counted below, taken back here
        elif self._use_pushes:
            subgoal = self.planner.next_push(state)
        else:
            subgoal = self.planner.plan(state)
        self.subgoal = subgoal
        self._option_steps = 0
        self.episode_stats.issued += 1
        self._expected = _states_on_the_way(state, subgoal)
        self.skill.reset(self._env, subgoal, state)


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
