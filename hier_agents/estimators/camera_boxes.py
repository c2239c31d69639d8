"""Box geometry from box-coloured pixels in a top-camera frame, for
`hier_agents.estimators.camera.CameraEstimator`: splitting a blob of several
touching boxes (`split_points`, k-means) and a box's centre from its pixels
(`box_centre`). Coordinates are continuous grid (row, col) in cells.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["find_boxes", "split_points", "box_centre"]


def find_boxes(box_mask, grid, side, px, walker_g) -> list:
    """Grid (row, col) centres of the boxes in ``box_mask`` ((h, w) bool:
    box-coloured pixels where a box may be), ``grid`` the (h, w, 2) grid
    coordinates of each pixel at box-top height, ``side`` a box's side as
    seen (cells), ``px`` cells per pixel, ``walker_g`` the walker's grid
    coordinates or None. Connected blobs under 12% of a box are dropped; a
    blob of several boxes (by area) is split with `split_points`."""
    labels, n = ndimage.label(box_mask)
    if n == 0:
        return []
    area1 = (side / px) ** 2                             # pixels per box
    objs = ndimage.find_objects(labels)
    found = []
    for k, sl in enumerate(objs, start=1):
        comp = labels[sl] == k
        area = comp.sum()
        if area < 0.12 * area1:
            continue
        g = grid[sl][comp]                                # (n, 2) grid coords
        count = max(1, int(round(area / (0.93 * area1))))
        if count == 1:
            groups = [g]
        else:
            groups = split_points(g, count)
        for pts in groups:
            found.append(box_centre(pts, side, px, walker_g))
    return found


def split_points(points, k):
    """``points`` (n, 2) split into at most ``k`` groups by k-means
    (farthest-point seeding, at most 10 iterations): a list of (m, 2)
    arrays, empty groups dropped."""
    # Initialise with farthest-point seeding.
    centres = [points[0]]
    for _ in range(1, k):
        d = np.min([np.sum((points - c) ** 2, 1) for c in centres], axis=0)
        centres.append(points[int(np.argmax(d))])
    centres = np.asarray(centres, float)
    for _ in range(10):
        d = np.stack([np.sum((points - c) ** 2, 1) for c in centres], 1)
        lab = np.argmin(d, 1)
        new = np.asarray([points[lab == j].mean(0) if np.any(lab == j) else centres[j]
                          for j in range(k)])
        if np.allclose(new, centres):
            break
        centres = new
    return [points[lab == j] for j in range(k) if np.any(lab == j)]


def box_centre(pts, side, px, walker_g):
    """Grid (row, col) of a box's centre from its visible pixels (their
    centres' grid coordinates ``pts``; ``px`` cells per pixel).

    Frames are not antialiased: a pixel is box-coloured when its centre
    lies on the box, so the first and last box pixel along an axis bound
    each edge within one pixel; with the known side length the centre
    lies in the intersection of the two bounds (its midpoint is taken).
    When the blob is shorter than the box (an ear hides one side) only
    the far edge is used.
    """
    centre = np.empty(2)
    for axis in range(2):
        v = pts[:, axis]
        vmin, vmax = v.min(), v.max()
        span = vmax - vmin + px
        if span >= side - 1.2 * px or walker_g is None:
            lo = max(vmin - px + side / 2, vmax - side / 2)
            hi = min(vmin + side / 2, vmax + px - side / 2)
            centre[axis] = 0.5 * (lo + hi) if lo <= hi else 0.5 * (vmin + vmax)
        elif abs(walker_g[axis] - vmin) < abs(walker_g[axis] - vmax):
            centre[axis] = vmax + px / 2 - side / 2   # near side hidden
        else:
            centre[axis] = vmin - px / 2 + side / 2
    return centre
