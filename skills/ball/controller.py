"""The low-level controller: where the walker is along its leg, the pursuit
carrot, the speed profile, meeting and pushing the box, and the yaw-rate
and roll loops that turn a carrot and a speed target into [roll, steer].

See the package docstring, *Control*. Everything here is deterministic and
reads only the values it is given.
"""

from __future__ import annotations

import math

from skills.ball.config import BallConfig
from skills.ball.paths import CONTACT

_PI = math.pi
_TWO_PI = 2.0 * math.pi


def wrap(angle: float) -> float:
    """``angle`` in [-pi, pi)."""
    return (angle + _PI) % _TWO_PI - _PI


def locate(seg, i, px, py):
    """Where the walker (px, py) is along the segments ``seg`` of a leg,
    starting from segment ``i`` (never going back).

    Returns (segment index, coordinate along it (negative only before the
    first one), arc length).
    """
    n = len(seg)
    x0, y0, ux, uy, length, s0 = seg[i]
    t = (px - x0) * ux + (py - y0) * uy
    while i + 1 < n:
        tc = min(max(t, 0.0), length)
        d_here = (px - x0 - ux * tc) ** 2 + (py - y0 - uy * tc) ** 2
        x1, y1, u1x, u1y, len1, s1 = seg[i + 1]
        t1 = min(max((px - x1) * u1x + (py - y1) * u1y, 0.0), len1)
        d_next = (px - x1 - u1x * t1) ** 2 + (py - y1 - u1y * t1) ** 2
        if t >= length or d_next < d_here:
            i += 1
            x0, y0, ux, uy, length, s0 = x1, y1, u1x, u1y, len1, s1
            t = (px - x0) * ux + (py - y0) * uy
        else:
            break
    t = max(t, 0.0) if i > 0 else t
    return i, t, s0 + min(t, length)


def carrot(seg, i, t, s_here, look):
    """The pure-pursuit carrot: ``look`` metres ahead of arc length ``s_here``
    (beyond the path's end: straight on; behind its start: on its line)."""
    n = len(seg)
    s_c = s_here + look
    j = i
    while j + 1 < n and seg[j + 1][5] <= s_c:
        j += 1
    cx0, cy0, cux, cuy, _, cs0 = seg[j]
    along = s_c - cs0
    if i == j and t < 0.0:  # behind the start: aim at the path's line
        x0, y0, ux, uy = seg[i][:4]
        return x0 + ux * look, y0 + uy * look
    return cx0 + cux * along, cy0 + cuy * along


def speed_limit(limits, s_here, v_max, two_a):
    """The speed target at arc length ``s_here``: at most ``v_max`` and, for
    every (arc length, speed) constraint ahead (or up to 0.05 m behind),
    ``sqrt(v^2 + two_a * distance)``."""
    v_des = v_max
    for s_k, v_k in limits:
        ahead = s_k - s_here
        if ahead < -0.05:
            continue
        v = math.sqrt(v_k * v_k + two_a * max(ahead, 0.0))
        if v < v_des:
            v_des = v
    return v_des


class BoxReading:
    """The pushed box, this step: its centre (bx, by), its remaining distance
    ``rem`` to the target along the push, the ``gap`` between ball and box
    (0: touching) and its offset ``off_line`` from the push line."""

    __slots__ = ("bx", "by", "rem", "gap", "off_line")

    def __init__(self, bx, by, rem, gap, off_line):
        self.bx, self.by, self.rem, self.gap, self.off_line = bx, by, rem, gap, off_line


class Contact:
    """Meeting and pushing a leg's box (package docstring, *Pushing*).

    Attributes:
      touched: the ball has met the box on this leg (it then pushes it).
      backing: the ball is backing off to meet the box again, aligned.
      backoffs: back-offs so far (each widens the alignment tolerance).
      stalled: control steps the touched box has not advanced.
    """

    __slots__ = ("touched", "backing", "backoffs", "stalled", "_last_rem")

    def __init__(self) -> None:
        self.new_leg()

    def new_leg(self) -> None:
        self.touched = False
        self.backing = False
        self.backoffs = 0
        self.stalled = 0
        self._last_rem = None

    def push(
        self, config: BallConfig, leg, on_last_segment, px, py, box_xy, carrot_xy, v_des, two_a
    ):
        """Adjusts the carrot and speed target for the push of ``leg``.

        Returns (carrot x, carrot y, speed target, whether backing off this
        step, `BoxReading`).
        """
        carrot_x, carrot_y = carrot_xy
        backing_now = False
        index, (dx, dy), (tx, ty), lateral, chain = leg.push
        bx, by = box_xy[index]
        rem = (tx - bx) * dx + (ty - by) * dy
        gap = (bx - px) * dx + (by - py) * dy - CONTACT
        if on_last_segment:
            if gap < 0.02:
                self.touched = True
            elif not self.touched:
                # Boxes are light and slide on floor friction: a ball that
                # meets one off its line or askew drags it sideways. Near
                # the box, off the line: back off along the line first.
                ball_off = (py - lateral) if dx else (px - lateral)
                # A short push (centring a box left short) has no room
                # to steer the box back onto its line: meet it aligned.
                tol_align = config.finish_align_tol if chain == 0 else config.align_tol
                # Each back-off widens the tolerance (no endless shuttling).
                if gap < config.align_gap and abs(ball_off) > tol_align * (1 + self.backoffs):
                    if not self.backing:
                        self.backoffs += 1
                    self.backing = True
                elif gap > config.align_gap + 0.25 or abs(ball_off) < 0.5 * tol_align:
                    self.backing = False
                if self.backing:
                    back = CONTACT + config.align_gap + 0.35
                    carrot_x, carrot_y = bx - dx * back, by - dy * back
                    if dx:
                        carrot_y = lateral
                    else:
                        carrot_x = lateral
                    v_des = min(v_des, 0.6)
                    backing_now = True
            if self.touched:
                if v_des > config.push_speed:
                    v_des = config.push_speed
                # The ball drags the box sideways (friction 1 on its
                # face): steer across the push line to bring the box
                # back onto its cell's centre line before pegs catch it.
                box_off = (by if dx else bx) - leg.cell_lat
                shift = max(
                    -config.max_recentre, min(config.max_recentre, -config.k_recentre * box_off)
                )
                lat = leg.cell_lat + shift
                # A box off its line that stops advancing is caught on a
                # peg: the ball drags it sideways, towards its line, from
                # wherever the ball is (the fixed aim may lie behind it).
                last, self._last_rem = self._last_rem, rem
                self.stalled = self.stalled + 1 if last is not None and rem > last - 0.002 else 0
                if self.stalled >= config.stall_steps and abs(box_off) > config.stall_off:
                    lat = (px if not dx else py) - math.copysign(config.max_recentre, box_off)
                if dx:
                    carrot_y = lat
                else:
                    carrot_x = lat
            elif gap > 0.0:
                v = math.sqrt(config.contact_speed**2 + two_a * gap)
                if v < v_des:
                    v_des = v
        # The box's remaining distance caps the pushing speed; before the
        # ball meets the box, only what it can still brake to by then.
        v2 = 2.0 * config.push_decel * max(rem - config.push_lead, 0.0)
        if not self.touched and gap > 0.0:
            v2 += two_a * gap
        v = math.sqrt(v2)
        if v < v_des:
            v_des = v
        off_line = (by - lateral) if dx else (bx - lateral)
        return carrot_x, carrot_y, v_des, backing_now, BoxReading(bx, by, rem, gap, off_line)


class Drive:
    """The yaw-rate and roll loops (package docstring, *Steering*, *Speed*).

    Keeps the walker's last heading (for its yaw rate) and the drive
    direction ``sign`` (+1: rolling towards the face) between steps.
    """

    __slots__ = ("prev_heading", "sign")

    def __init__(self) -> None:
        self.prev_heading = None
        self.sign = 1.0

    def yaw_rate(self, heading, dt) -> float:
        """The yaw rate since the last heading (0 for the first)."""
        prev = self.prev_heading
        rate = 0.0 if prev is None else wrap(heading - prev) / dt
        self.prev_heading = heading
        return rate

    def command(
        self,
        config: BallConfig,
        px,
        py,
        vx,
        vy,
        heading,
        rate,
        speed,
        carrot_x,
        carrot_y,
        v_des,
        pushing,
    ):
        """[roll, steer] towards the carrot at speed target ``v_des``;
        ``pushing`` adds the push bias.

        Returns (roll, steer, heading error, speed target scaled by the
        heading error, speed along the drive direction).
        """
        want = math.atan2(carrot_y - py, carrot_x - px)
        sign = self.sign
        err = wrap(want - heading - (0.0 if sign > 0 else _PI))
        # The ball rolls either way: drive the way needing the smaller turn,
        # with hysteresis.
        if abs(err) > 1.75 or (abs(err) > _PI / 2 and speed < 0.3):
            sign = -sign
            self.sign = sign
            err = wrap(err + _PI)
        cos_err = math.cos(err)
        floor = config.align_cos
        if cos_err < floor:
            v_des = 0.0
        else:
            v_des *= (cos_err - floor) / (1.0 - floor)
        v_along = sign * (vx * math.cos(heading) + vy * math.sin(heading))
        # Pure pursuit's turn rate (2 v sin(err) / distance) plus a term that
        # turns the head on the spot.
        reach = max(math.hypot(carrot_x - px, carrot_y - py), 0.2)
        w_des = config.k_heading * err + 2.0 * max(v_along, 0.0) * math.sin(err) / reach
        w_max = config.max_yaw_rate
        w_des = max(-w_max, min(w_max, w_des))
        u = (
            w_des / config.steer_gain
            + config.steer_deadband * math.tanh(w_des / 0.3)
            + config.k_rate * (w_des - rate)
        )
        steer = -max(-1.0, min(1.0, u))  # a positive steer command turns clockwise
        f = config.k_speed * (v_des - v_along) + config.k_speed_ff * v_des
        if pushing and v_des > 0.0:
            f += config.push_bias
        roll = -sign * max(-1.0, min(1.0, f))  # a negative roll rolls towards the face
        return roll, steer, err, v_des, v_along
