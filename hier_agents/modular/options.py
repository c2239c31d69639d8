"""The option runner: the one place that steps a skill until its option ends.

An *option* is a planner's `Subgoal` paired with the `Skill` that carries it
out. `OptionRunner` runs one option at a time, one control step at a time,
and decides when it ends; everything that runs options (the modular agent,
the semi-MDP environment `hier_agents.learning.option_env`, the skill
environments, benchmarks and tests) goes through it::

    runner = OptionRunner(skill, adapter("mujoban"), t_abs=T_ABS)   # families.adapter
    runner.start(description, subgoal, scene)
    while (action := runner.act(timestep, scene)) is not None:
        timestep = env.step(action)
        scene = estimate(timestep)          # None when no estimate can be made
    result = runner.result                  # an OptionResult

`run_option` is that loop for an environment and an estimator.

Termination (checked in this order at every ``act``, on the timestep that
the option's last action produced):

1. no scene estimate (``scene is None``): the skill holds still
   (``skill.hold()``); the step counts towards ``t_abs``;
2. the skill's status after ``skill.act(timestep, scene)``: ``SUCCESS`` ->
   **reached**, ``FAILURE`` -> **failed** (the skill's reason);
3. the episode's last timestep -> **reached** if the family adapter judges
   the subgoal done by the final scene (a Sokoban push that solved the level
   ends the episode before the skill can confirm it), else **interrupted**
   (reason ``"episode ended"``);
4. ``t_abs`` control steps taken -> **cut off**;
5. the family adapter's deviation check (every ``check_every`` steps; Sokoban:
   the boxes are neither where the option started nor where its moves put
   them; board games: the estimate rewrote a move the subgoal was planned
   after) -> **failed** (reason ``"deviation"``).

``interrupt(reason)`` ends a running option from outside (**interrupted**).

Rewards: the runner sums the rewards of the timesteps its actions produced,
``sum_k gamma^k r_k``, and multiplies their discounts,
``prod_k gamma * d_k`` (``gamma`` per control step, default 1).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from envs.profile import PROFILE
from skills.base import Status

__all__ = ["T_ABS", "Outcome", "OptionResult", "OptionRunner", "run_option", "failure_kind"]

#: The paper's T_abs: control steps an option may take before the agent re-plans.
T_ABS = 50


class Outcome(enum.Enum):
    """How an option ended."""

    REACHED = "reached"
    FAILED = "failed"
    CUT_OFF = "cut off"
    INTERRUPTED = "interrupted"


@dataclass
class OptionResult:
    """One option's end.

    ``outcome``; ``reason`` (why it failed or was interrupted; None when
    reached or cut off); ``duration`` (control steps its actions took);
    ``reward`` (``sum_k gamma^k r_k`` over them); ``discount`` (``prod_k gamma
    * d_k``; 0 after a terminal step); ``timestep`` and ``scene`` (the last
    ones seen; ``scene`` None if that timestep could not be estimated).
    """

    outcome: Outcome
    reason: str | None
    duration: int
    reward: float
    discount: float
    timestep: object = None
    scene: object = None

    @property
    def reached(self) -> bool:
        return self.outcome is Outcome.REACHED


class OptionRunner:
    """Runs options of one skill, a control step at a time (module docstring).

    Args:
      skill: the `Skill`.
      adapter: the game family's `hier_agents.modular.families.FamilyAdapter`
        (the end-of-episode and deviation rules); None: neither rule.
      t_abs: control steps an option may take before it is cut off (>= 1).
      gamma: per-control-step discount of ``result.reward``.
      check_every: control steps between deviation checks.
    """

    def __init__(
        self, skill, adapter=None, *, t_abs: int = T_ABS, gamma: float = 1.0, check_every: int = 5
    ):
        if int(t_abs) < 1:
            raise ValueError(f"t_abs must be a positive number of control steps, got {t_abs!r}")
        if not 0.0 < float(gamma) <= 1.0:
            raise ValueError(f"gamma must be in (0, 1], got {gamma!r}")
        self.skill, self.adapter = skill, adapter
        self.t_abs, self.gamma = int(t_abs), float(gamma)
        self.check_every = max(1, int(check_every))
        self.subgoal = None
        self.result: OptionResult | None = None
        self._running = False
        self._duration = 0

    @property
    def running(self) -> bool:
        """True between `start` and the option's end."""
        return self._running

    @property
    def duration(self) -> int:
        """Control steps the current (or last) option's actions took."""
        return self._duration

    def clear(self) -> None:
        """Forgets any running option (a new episode)."""
        self.subgoal, self.result, self._running = None, None, False

    def start(self, description, subgoal, scene) -> None:
        """Starts ``subgoal`` from ``scene`` (the estimate it was planned from)."""
        self.subgoal, self.result = subgoal, None
        self._duration, self._reward, self._discount = 0, 0.0, 1.0
        self._awaiting = False
        self._expected = (
            self.adapter.expected(scene.state, subgoal) if self.adapter is not None else None
        )
        self._running = True
        self.skill.reset(description, subgoal, scene)

    def act(self, timestep, scene) -> np.ndarray | None:
        """The next action after ``timestep`` (``scene``: its estimate, or None
        when none could be made); None when the option has ended (`result`)."""
        if not self._running:
            raise RuntimeError("no option is running: call start()")
        if self._awaiting:
            self._record(timestep)
        skill = self.skill
        if scene is None:
            if timestep.last():
                self._end(Outcome.INTERRUPTED, "episode ended", timestep, scene)
                return None
            if self._duration >= self.t_abs:
                self._end(Outcome.CUT_OFF, None, timestep, scene)
                return None
            return self._issue(skill.hold())
        with PROFILE.section("skill"):
            action = skill.act(timestep, scene)
        if skill.status is Status.SUCCESS:
            self._end(Outcome.REACHED, None, timestep, scene)
            return None
        if skill.status is Status.FAILURE:
            self._end(Outcome.FAILED, skill.failure_reason or "unknown", timestep, scene)
            return None
        if timestep.last():
            if self.adapter is not None and self.adapter.done_at_end(self.subgoal, scene):
                self._end(Outcome.REACHED, None, timestep, scene)
                return None
            self._end(Outcome.INTERRUPTED, "episode ended", timestep, scene)
            return None
        if self._duration >= self.t_abs:
            self._end(Outcome.CUT_OFF, None, timestep, scene)
            return None
        if (
            self._expected is not None
            and self._duration % self.check_every == 0
            and self.adapter.deviates(self._expected, scene)
        ):
            self._end(Outcome.FAILED, "deviation", timestep, scene)
            return None
        return self._issue(action)

    def interrupt(self, reason: str, timestep=None, scene=None) -> OptionResult | None:
        """Ends the running option as **interrupted** with ``reason``;
        returns `result` (None when no option ran since `clear`)."""
        if self._running:
            if self._awaiting and timestep is not None:
                self._record(timestep)
            self._end(Outcome.INTERRUPTED, reason, timestep, scene)
        return self.result

    def _issue(self, action) -> np.ndarray:
        self._duration += 1
        self._awaiting = True
        return action

    def _record(self, timestep) -> None:
        self._awaiting = False
        k = self._duration - 1
        self._reward += (self.gamma**k) * float(timestep.reward or 0.0)
        discount = 1.0 if timestep.discount is None else float(timestep.discount)
        self._discount *= self.gamma * discount

    def _end(self, outcome: Outcome, reason, timestep, scene) -> None:
        self._running = False
        self.result = OptionResult(
            outcome, reason, self._duration, self._reward, self._discount, timestep, scene
        )
        return None


def run_option(
    env,
    estimator,
    skill,
    subgoal,
    timestep,
    *,
    adapter=None,
    t_abs: int = T_ABS,
    gamma: float = 1.0,
    scene=None,
    on_step=None,
    description=None,
) -> OptionResult:
    """Runs ``skill`` on ``subgoal`` in ``env`` from ``timestep`` until the
    option ends (`OptionRunner`'s rules) and returns its `OptionResult`.

    The estimator must have been reset for this episode
    (``estimator.reset(env.description(), first_timestep)``); its
    `EstimationError` makes the skill hold still for that step. ``scene``
    (default: an estimate of ``timestep``) is the scene the subgoal was
    planned from. ``on_step(timestep, scene)``, if given, is called after
    every step with a scene (tests that disturb the scene mid-option; callers
    that keep the last estimate). ``description`` (default:
    ``env.description()``) is passed to the skill: give the same object across
    options of an episode so that skills keep their per-task state.
    """
    from hier_agents.estimators.base import EstimationError

    if scene is None:
        scene = estimator.estimate(timestep)
    runner = OptionRunner(skill, adapter, t_abs=t_abs, gamma=gamma)
    runner.start(env.description() if description is None else description, subgoal, scene)
    while (action := runner.act(timestep, scene)) is not None:
        timestep = env.step(action)
        try:
            scene = estimator.estimate(timestep)
        except EstimationError:
            scene = None
        if on_step is not None and scene is not None:
            on_step(timestep, scene)
    assert runner.result is not None  # `act` returned None: the option ended
    return runner.result


def failure_kind(reason: str | None) -> str:
    """The kind of a failure reason, for counting: the text before any colon
    (``"box off line: ... by 0.21 m"`` -> ``"box off line"``)."""
    return (reason or "unknown").split(":", 1)[0].strip() or "unknown"
