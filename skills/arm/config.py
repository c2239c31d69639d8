"""`ArmTouchConfig`: the arm-touch skill's tuning parameters (one frozen record)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass


def _pairs(value) -> tuple[tuple[float, float], ...]:
    return tuple((float(a), float(b)) for a, b in value)


@dataclass(frozen=True)
class ArmTouchConfig:
    """How `skills.arm.ArmTouchSkill` plans and moves (see `skills.arm`).

    Posture planning:
      pre_height: height (m) of the tool above the pad top in the pre-touch
        posture.
      press_depth: depth (m) below the pad top of the tool in the touch
        posture (and of the touch phase's aim).
      orientations: (heading, roll) pairs in degrees tried for the pre-touch
        posture: the down orientation turned by ``heading`` about the
        vertical and tilted by ``roll`` about the hand's x axis (which lowers
        one side of the closed fingers: a smaller footprint).
      tilt_costs, max_tilt: more candidates, (weight, roll) pairs: postures
        near the start, pulled with that weight towards pointing down (or
        leant, see below) rolled by ``roll`` degrees (so they may tilt towards
        the start), at most ``max_tilt`` degrees from vertical (the near
        Go rows, 0.2 m from the base, are reached fastest well tilted).
      lean_start, lean_rate, lean_step, max_lean: targets beyond ``lean_start``
        (m, horizontally from the arm's base) are tried with the hand leant
        away from the base by ``lean_rate`` degrees per metre beyond, and
        ``lean_step`` degrees more (more leans if none lands), at most
        ``max_lean`` (+ ``lean_step`` in the fallback).
      min_clearance: no fingertip comes closer (m) to the pads at the
        pre-touch posture, whatever the fingers' closing (it is raised).
      ik_iterations: iterations per posture IK.

    Travel and descent:
      switch_time: the descent starts when the pre-touch posture is this many
        seconds away at full joint speed.
      guard, lookahead: the skill recovers when, travelling, the tool is (or
        at its current velocity will be within ``lookahead`` seconds) closer
        than ``guard`` (m) to the pad tops away from the target; the descent
        recovers when within ``2.5 * guard`` the fingertips would land off the
        pad.
      accel_margin: fraction of `JOINT_ACCELERATION` the travel plans with.
      band, fast_band, touch_speed, landing_decel: the fingertip vertices
        within ``fast_band`` (m) of the lowest one may touch pads in the
        control step of the first contact when the descent lands at full
        speed; within ``band`` when it lands at ``touch_speed`` (m/s, the cap
        growing as ``sqrt(touch_speed**2 + 2 * landing_decel * height)``).
        The descent starts only when those vertices lie over the target pad,
        ``safety`` from its edge; it lands fast when it can.
      finger_reach: how far (rad) the fingers may close during a descent;
        the footprint must stay over the pad over that range.
      safety: margin (m) kept between the fingertips and the pad's edge.
      wait_steps: steps the travel may wait at the pre-touch posture for the
        fingertips to be landable before it recovers.

    Touch phase (Cartesian):
      speed, gain: the touch phase's (and the lift's) largest tool speed
        (m/s), and the touch phase's proportional gain (1/s).
      slope, clearance, cruise: the touch phase's funnel.
      damping, orientation_cost, wrist_damping: touch-phase IK weights
        (against 1 for the pinch site's position).

    Giving up:
      max_steps: steps per touch (a move game's move is two) before FAILURE ``"timeout"``.
      stall_steps: steps without progress before FAILURE ``"no progress"``.
      max_presses: presses without a registered move before FAILURE
        ``"no registration"``.
      max_recoveries: re-plans after which the skill fails (``"no progress"``).
    """

    pre_height: float = 0.025
    press_depth: float = 0.012
    orientations: tuple = ((0, 0), (0, 12), (0, -12))
    tilt_costs: tuple = ((0.02, 0), (0.01, 12), (0.01, -12))
    max_tilt: float = 55.0
    max_lean: float = 55.0
    lean_start: float = 0.7
    lean_rate: float = 250.0
    lean_step: float = 8.0
    min_clearance: float = 0.012
    ik_iterations: int = 12
    switch_time: float = 0.1
    guard: float = 0.008
    lookahead: float = 0.05
    accel_margin: float = 0.85
    band: float = 0.006
    fast_band: float = 0.015
    touch_speed: float = 0.1
    landing_decel: float = 1.5
    finger_reach: float = 0.4
    safety: float = 0.003
    wait_steps: int = 12
    speed: float = 0.3
    gain: float = 5.0
    slope: float = 1.6
    clearance: float = 0.008
    cruise: float = 0.04
    damping: float = 1e-3
    orientation_cost: float = 0.1
    wrist_damping: float = 0.05
    max_steps: int = 60
    stall_steps: int = 12
    max_presses: int = 3
    max_recoveries: int = 2

    def __post_init__(self) -> None:
        # Normalise (lists from a JSON file or a CLI become tuples of floats).
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in ("orientations", "tilt_costs"):
                value = _pairs(value)
            elif f.type in ("int", int):
                value = int(value)
            else:
                value = float(value)
            object.__setattr__(self, f.name, value)
        if self.max_steps < 1 or self.stall_steps < 1 or self.ik_iterations < 1:
            raise ValueError("max_steps, stall_steps and ik_iterations must be positive")
        if not self.orientations:
            raise ValueError("orientations must name at least one (heading, roll) pair")

    def replace(self, **overrides) -> "ArmTouchConfig":
        """A copy with ``overrides``; unknown names raise `TypeError`."""
        return dataclasses.replace(self, **overrides)
