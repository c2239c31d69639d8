"""`ModularAgent`: estimate -> plan -> run an option -> estimate again.

`ModularAgent` is a policy over options behind the observation boundary: it
is given the task's public description and timesteps, nothing else. Each
control step it estimates the scene (`Estimator`) and either keeps the
current option running or starts a new one:

1. **plan** a `Subgoal` from the scene's abstract state (`Planner`, through
   the family adapter: Sokoban planners that offer ``next_push`` give "walk
   to the box, push it once");
2. **run** the `Skill` on it with the option runner
   (`hier_agents.modular.options.OptionRunner`: reached, failed, cut off
   after ``t_abs`` control steps (the paper's T_abs), or off the subgoal's
   path), then go back to 1 on the same timestep.

Runs never abort:

* an estimate that cannot be made (`EstimationError`: two boxes in one
  cell, the walker not found) makes the skill hold still for that step
  (``episode_stats.estimation_failures`` counts them);
* a planner with no plan (`NoPlanError`: a box pushed into a deadlock, the
  solver's budget) ends the episode for the agent: ``gave_up`` holds the
  reason and the agent holds still from then on (the run CLI stops the
  episode there and records it as a failure with that reason).

Counters (per episode): subgoals issued, reached, failed (by reason kind),
cut off and unfinished (interrupted by the episode's end). The subgoal
success rate is reached / (reached + failed + cut off + unfinished). A
solved Sokoban estimate is not a subgoal: the agent holds (the ball skill
centres a box left short) and counts nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from abstract_planners.base import NoPlanError, Planner, Subgoal
from envs.profile import PROFILE
from hier_agents.estimators.base import EstimationError, Estimator
from hier_agents.modular.families import adapter_for
from hier_agents.modular.options import T_ABS, Outcome, OptionResult, OptionRunner, failure_kind
from skills.base import Skill

__all__ = ["ModularAgent", "OptionStats"]


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

    def count(self, result: OptionResult) -> None:
        """Counts one ended option."""
        if result.outcome is Outcome.REACHED:
            self.reached += 1
        elif result.outcome is Outcome.FAILED:
            self.fail(failure_kind(result.reason))
        elif result.outcome is Outcome.CUT_OFF:
            self.cut_off += 1
        else:
            self.unfinished += 1


class ModularAgent:
    """Estimator + planner + skill, tied by the option runner.

    Args:
      estimator, planner, skill: the three roles.
      t_abs: control steps an option may run before the agent re-plans.
      use_pushes: give the skill whole "walk, then push" subgoals when the
        planner offers ``next_push`` (Sokoban); single moves otherwise.
      check_every: control steps between checks that the estimated scene is
        still on the subgoal's path.
    """

    def __init__(
        self,
        estimator: Estimator,
        planner: Planner,
        skill: Skill,
        *,
        t_abs: int = T_ABS,
        use_pushes: bool = True,
        check_every: int = 5,
    ):
        self.estimator, self.planner, self.skill = estimator, planner, skill
        self.runner = OptionRunner(skill, t_abs=t_abs, check_every=check_every)
        self.t_abs = self.runner.t_abs
        self._use_pushes = bool(use_pushes)
        self.episode_stats = OptionStats()
        self.description = None
        #: Why the agent gave up on the episode (a planner found no plan), or None.
        self.gave_up: str | None = None
        self.scene = None
        self._counted = True

    @property
    def subgoal(self) -> Subgoal | None:
        """The running option's subgoal (None between options)."""
        return self.runner.subgoal if self.runner.running else None

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

    #: The scene holds an estimate of the abstract state (the harness may judge it).
    estimates = True

    @property
    def training_frames(self) -> int:
        """Environment frames spent training the learned parts: the sum of the
        parts' ``training_frames`` (a learned skill's, a learned planner's; 0
        for scripted parts). Frames, not wall time: what `hier_agents.compare`
        puts beside the end-to-end agents' frames."""
        parts = (self.planner, self.skill, self.estimator)
        return int(sum(int(getattr(part, "training_frames", 0) or 0) for part in parts))

    def reset(self, description, timestep, seed: int | None = None) -> None:
        """Starts an episode from the task's public ``description`` (see
        `envs.description`, ``env.description()``) and its first ``timestep``."""
        self.description = description
        self.runner.adapter = adapter_for(description)
        self.runner.clear()
        self.skill.forget_history()  # an episode plays the same whatever came before
        with PROFILE.section("planner"):
            self.planner.reset(seed)
        with PROFILE.section("estimator"):
            self.estimator.reset(description, timestep)
        self.episode_stats = OptionStats()
        self.gave_up = None
        self.scene = None

    def act(self, timestep) -> np.ndarray:
        """The action for ``env.step`` after ``timestep``."""
        if self.gave_up is not None:
            return self.skill.hold()
        try:
            with PROFILE.section("estimator"):
                scene = self.estimator.estimate(timestep)
        except EstimationError:
            self.episode_stats.estimation_failures += 1
            scene = None
        else:
            self.scene = scene
        runner = self.runner
        if runner.running:
            action = runner.act(timestep, scene)
            if action is not None:
                return action
            assert runner.result is not None  # `act` returned None: the option ended
            self._count(runner.result)
        if scene is None:
            return self.skill.hold()
        for _ in range(2):  # a new option may end at once (it sees its outcome)
            try:
                self._start_option(scene)
            except NoPlanError as exc:
                self.gave_up = f"no plan ({exc.reason}): {exc}"
                return self.skill.hold()
            action = runner.act(timestep, scene)
            if action is not None:
                return action
            assert runner.result is not None  # `act` returned None: the option ended
            self._count(runner.result)
        return self.skill.hold()

    def end_episode(self, timestep) -> None:
        """Closes the open option at the episode's last ``timestep``.

        The step that ends an episode usually completes the last subgoal (the
        final push, the winning touch), but `act` is not called after it; the
        option runner is shown that timestep once (its action is discarded)
        so the subgoal is counted as reached, failed or unfinished.
        """
        runner = self.runner
        if not runner.running:
            return
        try:
            with PROFILE.section("estimator"):
                scene = self.estimator.estimate(timestep)
        except EstimationError:
            scene = None
        if runner.act(timestep, scene) is None:
            assert runner.result is not None  # `act` returned None: the option ended
            self._count(runner.result)
        else:
            result = runner.interrupt("episode ended", timestep, scene)
            assert result is not None  # an option was running: it has a result now
            self._count(result)

    def _count(self, result: OptionResult) -> None:
        if self._counted:
            self.episode_stats.count(result)

    def _start_option(self, scene) -> None:
        state = scene.state
        adapter = self.runner.adapter
        self._counted = not adapter.idle(state)
        if not self._counted:
            # Nothing left to plan (the boxes round onto the pads; the episode
            # ends once they cover them): hold, which the ball skill uses to
            # centre a box left short. Not counted as a subgoal.
            subgoal = Subgoal(action=(), state=state)
        else:
            with PROFILE.section("planner"):
                if self._use_pushes:
                    subgoal = adapter.next_subgoal(self.planner, state, self.description)
                else:
                    subgoal = self.planner.plan(state)
        self.episode_stats.issued += int(self._counted)
        with PROFILE.section("skill"):
            self.runner.start(self.description, subgoal, scene)
