"""`TouchZones`: where the hand touches a board's zones, and where it stands
blocked, from the arm's joints alone.

The hand is the pinch site's world position, which the caller computes from
the arm's joints with the arm's own kinematic model
(`hier_agents.estimators.arm_silhouette.ArmSilhouette.pinch`); the zones
come from the public `envs.description.BoardDescription`: each point a
square of the board's half-spacing around its position, then each pass area.

A press that misses goes down and up again; a blocked one stands on what
holds it. The hand blocked over one zone (its pinch site within
`PRESS_HEIGHT` of the zone's top, moving less than `STALL_MOVE` a step for
`STALL_STEPS` steps in a row) with no arm reset (which follows a
registered move) most often means the game refused the move that zone
plays: its point is taken, under the hand where the camera cannot see it.
Not always: the hand also stands still just above a point without touching
it (seen on MuJoGo 1.9-3.2 cm above an empty point, as high as on a stone),
so `BoardCameraEstimator` takes a blocked press for a refusal only where
the camera has not read the point empty since the last registered move.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TouchZones", "PRESS_HEIGHT", "STALL_MOVE", "STALL_STEPS"]

#: Height (m) above a zone's top within which the pinch site presses it.
PRESS_HEIGHT = 0.035
#: Largest movement (m) of the pinch site in a step that still stands.
STALL_MOVE = 0.002
#: Steps the hand stands pressing one zone before the press is blocked.
STALL_STEPS = 4


class TouchZones:
    """A board's touch zones and the hand over them.

    Args:
      description: the board's `envs.description.BoardDescription`
        (``point_positions``, ``pass_action``, ``pass_zones``).
      half: a point zone's half-size (m): half the spacing of points.
    Zones are numbered as the game's touch zones: the points in order, then
    the pass areas. The methods take ``pinch``, the pinch site's world
    position (x, y, z; m).
    """

    def __init__(self, description, half: float):
        points = [np.asarray(p, float) for p in description.point_positions]
        self.centres = [p[:2] for p in points]
        self.halves = [np.array([half, half], float) for _ in points]
        self.tops = [float(p[2]) for p in points]
        if description.pass_action is not None:
            for zone in description.pass_zones.values():
                self.centres.append(np.asarray(zone["centre"][:2], float))
                self.halves.append(np.asarray(zone["half"], float))
                self.tops.append(float(zone["centre"][2]))
        self.reset()

    def reset(self) -> None:
        """Forgets the press being followed (at an arm reset)."""
        self._press: tuple[int | None, float, int] = (None, 0.0, 0)

    def under(self, point) -> int | None:
        """The zone under a point (x, y[, z]; m): the first zone holding its
        (x, y), else the nearest zone centre within 1.5 half-sizes, else None."""
        xy = np.asarray(point, float)[:2]
        for i, (centre, half) in enumerate(zip(self.centres, self.halves)):
            if np.all(np.abs(xy - centre) <= half):
                return i
        dist = [np.max(np.abs(xy - c) / h) for c, h in zip(self.centres, self.halves)]
        best = int(np.argmin(dist))
        return best if dist[best] <= 1.5 else None

    def within(self, pinch, height: float) -> bool:
        """Whether the pinch site at ``pinch`` is over a zone and at most
        ``height`` (m) above its top."""
        pinch = np.asarray(pinch, float)
        zone = self.under(pinch)
        return zone is not None and float(pinch[2]) <= self.tops[zone] + height

    def blocked(self, pinch) -> int | None:
        """Follows the hand, one call per control step: the zone the pinch
        site, now at ``pinch``, has stood blocked on for exactly
        `STALL_STEPS` steps (once per press), else None."""
        pinch = np.asarray(pinch, float)
        zone = self.under(pinch)
        height = float(pinch[2])
        if zone is not None and height > self.tops[zone] + PRESS_HEIGHT:
            zone = None
        last, last_height, steps = self._press
        still = zone is not None and zone == last and abs(height - last_height) < STALL_MOVE
        self._press = (zone, height, steps + 1 if still else 0)
        return zone if zone is not None and self._press[2] == STALL_STEPS else None
