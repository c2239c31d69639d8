"""Small geometry helpers of the arm skill: hand orientations, the smallest
circle around the fingertips, joint-space travel times."""

from __future__ import annotations

import math

import mink
import numpy as np

#: Pinch site pointing straight down (w, x, y, z), the board environments' own down
#: orientation (dm_control's ``manipulators.base.DOWN_QUATERNION``).
DOWN_QUAT = np.array([0.0, 0.70710678118, 0.70710678118, 0.0])
#: Straight down, as a unit vector.
DOWN = np.array([0.0, 0.0, -1.0])


def skew(k: np.ndarray) -> np.ndarray:
    """The cross-product matrix of ``k``."""
    return np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])


def pointing(xmat, direction: np.ndarray = DOWN, roll: float = 0.0) -> mink.SO3:
    """The orientation nearest the site's (``xmat``) whose z axis -- first
    rolled by ``roll`` radians about the site's x axis -- points along the
    unit vector ``direction`` (default straight down).

    Only the smallest rotation is applied: for ``direction`` down the hand's
    heading (rotation about the vertical) is kept.
    """
    rot = np.asarray(xmat, float).reshape(3, 3)
    z = rot @ np.array([0.0, -math.sin(roll), math.cos(roll)])  # (R Rx(roll)) e_z
    axis = np.cross(z, direction)
    sin, cos = float(np.linalg.norm(axis)), float(z @ direction)
    if sin < 1e-9:
        if cos > 0:
            return mink.SO3.from_matrix(rot)
        perpendicular = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        k = skew(perpendicular / np.linalg.norm(perpendicular))
        align = np.eye(3) + 2 * (k @ k)  # half a turn
    else:
        k = skew(axis / sin)
        align = np.eye(3) + sin * k + (1 - cos) * (k @ k)
    return mink.SO3.from_matrix(align @ rot)


def lean_direction(out_xy: np.ndarray, lean_degrees: float) -> np.ndarray:
    """Straight down tilted by ``lean_degrees`` towards the horizontal unit
    vector ``out_xy``."""
    lean = math.radians(lean_degrees)
    return np.array([math.sin(lean) * out_xy[0], math.sin(lean) * out_xy[1], -math.cos(lean)])


def enclosing_circle(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Smallest circle around three 2-D points: (centre, radius)."""
    a, b, c = points
    best = None
    for p, q, r in ((a, b, c), (b, c, a), (c, a, b)):  # a side as the diameter
        centre = 0.5 * (p + q)
        radius = 0.5 * float(np.linalg.norm(p - q))
        if np.linalg.norm(r - centre) <= radius + 1e-12 and (best is None or radius < best[1]):
            best = (centre, radius)
    if best is not None:
        return best
    # Acute triangle: the circumcircle.
    d = 2 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    if abs(d) < 1e-15:
        centre = points.mean(axis=0)
    else:
        sa, sb, sc = a @ a, b @ b, c @ c
        centre = (
            np.array(
                [
                    sa * (b[1] - c[1]) + sb * (c[1] - a[1]) + sc * (a[1] - b[1]),
                    sa * (c[0] - b[0]) + sb * (a[0] - c[0]) + sc * (b[0] - a[0]),
                ]
            )
            / d
        )
    return centre, float(np.max(np.linalg.norm(points - centre, axis=1)))


def trapezoid_time(distance: np.ndarray, speed: np.ndarray, accel: np.ndarray) -> np.ndarray:
    """Least time to move ``distance`` from rest to rest with those limits."""
    distance = np.abs(distance)
    cruise = distance >= speed**2 / accel
    return np.where(cruise, distance / speed + speed / accel, 2 * np.sqrt(distance / accel))
