"""`BallConfig`: the ball skill's tuning parameters and gains (one frozen record)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

_CASTS = {"float": float, "int": int, "bool": bool}


@dataclass(frozen=True)
class BallConfig:
    """How `skills.ball.BallSkill` plans its legs and drives the ball (see
    `skills.ball`): speeds, trajectory shaping, the pushing rules, when it
    gives up, and the controller's gains, tuned on generated levels and
    Boxoban. ``BallSkill(**overrides)`` or ``BallSkill(config)`` sets them;
    `replace` makes a changed copy.
    """

    # -- speeds ------------------------------------------------------------------
    #: Top speed on straight walks, m/s.
    cruise_speed: float = 3.5
    #: Speed through a sharp (unrounded) 90-degree corner, m/s.
    corner_speed: float = 1.4
    #: Speed through a sharp turn into a push line, m/s.
    push_turn_speed: float = 0.5
    #: Speed when the ball meets the box, m/s.
    contact_speed: float = 1.2
    #: Top speed while pushing, m/s.
    push_speed: float = 1.5
    #: Planned deceleration before corners, the box and stops, m/s^2 (the
    #: ball brakes at ~8-9).
    decel: float = 8.5
    #: Planned deceleration of the ball and the box it pushes, m/s^2.
    push_decel: float = 3.5
    #: The ball stops pushing this far (m) before the box centre reaches its
    #: target; the box slides the rest.
    push_lead: float = 0.0

    # -- status --------------------------------------------------------------------
    #: How far (cells) from its cell centre a settled box may be.
    center_tol: float = 0.08
    #: Control steps without progress before failing.
    stuck_steps: int = 30
    #: Metres a box that should stay put may move before failing.
    disturb_tol: float = 0.15
    #: Chaining: when more of the plan is known after a push (the next walk),
    #: the push ends as soon as the box, sliding on alone at its floor
    #: deceleration ``box_decel`` (m/s^2), will stop within half of
    #: ``center_tol`` of its cell centre; the ball turns away without waiting
    #: for the box to come to rest.
    chain: bool = True
    box_decel: float = 4.9

    # -- trajectory ----------------------------------------------------------------
    #: Extend the trajectory with ``subgoal.plan`` (module doc).
    lookahead: bool = True
    #: Join cells in clear sight and round corners (module doc); without it
    #: the ball follows the cell centres.
    smooth: bool = True
    #: Corner arcs: largest radius (cells), lateral acceleration (m/s^2) and
    #: yaw rate (rad/s) that set their speed, straight run (m) kept before
    #: meeting a box.
    max_radius: float = 1.0
    lateral_accel: float = 12.0
    max_turn_rate: float = 5.0
    push_straight: float = 0.3
    #: Clearance (m) kept between the ball and a peg when cutting corners.
    peg_margin: float = 0.1
    #: A box further than this (cells) from its cell centre, with the walker
    #: behind it, is first pushed on to the centre.
    finish_tol: float = 0.08

    # -- pushing -------------------------------------------------------------------
    #: Meeting a box: within ``align_gap`` metres of it, a ball more than
    #: ``align_tol`` metres off the push line (``finish_align_tol`` when
    #: centring a box left short: too short a push to steer the box back)
    #: backs off and comes in again.
    align_gap: float = 0.3
    align_tol: float = 0.25
    finish_align_tol: float = 0.04
    #: While pushing, the carrot sits ``k_recentre`` times the box's offset
    #: from its cell's centre line on the other side of it (at most
    #: ``max_recentre`` m), so the ball's sideways motion drags it back.
    k_recentre: float = 1.0
    max_recentre: float = 0.3
    #: A touched box that has not advanced for ``stall_steps`` control steps
    #: while more than ``stall_off`` metres off its line is caught on a peg:
    #: the carrot moves ``max_recentre`` sideways from the ball, towards the
    #: line, so the ball's motion drags the box free.
    stall_steps: int = 5
    stall_off: float = 0.02

    # -- controller gains ----------------------------------------------------------
    #: Pure pursuit look-ahead: ``look_base + look_gain * speed`` metres.
    look_base: float = 0.45
    look_gain: float = 0.35
    #: Heading loop: desired yaw rate per radian of error (1/s), yaw-rate
    #: feedback (steer per rad/s), and the steer actuator's measured model:
    #: ~7.3 rad/s per unit command above a deadband of ~0.13; the largest
    #: yaw rate asked for (rad/s).
    k_heading: float = 4.0
    k_rate: float = 0.12
    steer_gain: float = 7.3
    steer_deadband: float = 0.13
    max_yaw_rate: float = 6.5
    #: Roll loop: command per m/s of speed error, feed-forward per m/s, extra
    #: command while pushing (the box's floor friction).
    k_speed: float = 2.0
    k_speed_ff: float = 0.2
    push_bias: float = 0.15
    #: Below this cosine of the heading error the ball turns without rolling;
    #: above it the speed target scales up linearly.
    align_cos: float = 0.5

    def __post_init__(self) -> None:
        # Normalise the types (ints for floats, values from a JSON file or a CLI).
        for f in dataclasses.fields(self):
            cast = _CASTS[f.type if isinstance(f.type, str) else f.type.__name__]
            object.__setattr__(self, f.name, cast(getattr(self, f.name)))

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))

    def replace(self, **overrides) -> "BallConfig":
        """A copy with ``overrides``; unknown names raise `TypeError` naming the valid ones."""
        names = self.field_names()
        unknown = sorted(set(overrides) - set(names))
        if unknown:
            raise TypeError(
                f"unknown BallConfig parameter(s) {', '.join(unknown)}; valid: {', '.join(names)}"
            )
        return dataclasses.replace(self, **overrides)
