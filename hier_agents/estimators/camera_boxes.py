"""Box geometry from box-coloured pixels in a top-camera frame, for
`hier_agents.estimators.camera.CameraEstimator`: splitting a blob of several
touching boxes (`split_points`, k-means), which of a blob's edges may be hidden
(`hidden_edges`) and a box's centre from its pixels (`box_centre`).
Coordinates are continuous grid (row, col) in cells.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["find_boxes", "split_points", "hidden_edges", "wall_limits", "box_centre"]

#: A blob's edge counts as hidden when at least this share of the pixels
#: just beyond it may hide a box (``hiding`` in `find_boxes`).
HIDDEN_SHARE = 0.5
_STEPS = ((1, 0), (-1, 0), (0, 1), (0, -1))


def find_boxes(box_mask, grid, side, px, walker_g, hiding=None, walls=None, half=None) -> list:
    """Grid (row, col) centres of the boxes in ``box_mask`` ((h, w) bool:
    box-coloured pixels where a box may be), ``grid`` the (h, w, 2) grid
    coordinates of each pixel at box-top height, ``side`` a box's side as
    seen (cells), ``px`` cells per pixel, ``walker_g`` the walker's grid
    coordinates or None, ``hiding`` an (h, w) bool mask of pixels that may
    hide a box's top (where boxes are not looked for, ears, unsure colours)
    or None, ``walls`` the (rows, cols) bool grid of wall cells and
    ``half`` a box's half side (cells), or None. Connected blobs under 12%
    of a box are dropped; a blob of several boxes (by area) is split with
    `split_points`; a single box's centre comes from `box_centre` with its
    `hidden_edges` and, where one is hidden, `wall_limits`."""
    labels, n = ndimage.label(box_mask)
    if n == 0:
        return []
    area1 = (side / px) ** 2  # pixels per box
    objs = ndimage.find_objects(labels)
    found = []
    for k, sl in enumerate(objs, start=1):
        comp = labels[sl] == k
        area = comp.sum()
        if area < 0.12 * area1:
            continue
        g = grid[sl][comp]  # (n, 2) grid coords
        count = max(1, int(round(area / (0.93 * area1))))
        if count == 1:
            hidden = limits = None
            near = (
                slice(max(sl[0].start - 1, 0), sl[0].stop + 1),
                slice(max(sl[1].start - 1, 0), sl[1].stop + 1),
            )
            if hiding is not None and hiding[near].any():  # an edge may be hidden
                hidden = hidden_edges(sl, hiding, grid)
                if walls is not None and hidden.any():
                    limits = wall_limits(g.mean(axis=0), walls, half)
            found.append(box_centre(g, side, px, walker_g, hidden, limits))
        else:
            found.extend(box_centre(pts, side, px, walker_g) for pts in split_points(g, count))
    return found


def hidden_edges(sl, hiding, grid) -> np.ndarray:
    """Which edges of a blob may be hidden: a (2, 2) bool array, ``[axis,
    0]`` its low edge along grid axis ``axis`` (0 row, 1 col), ``[axis,
    1]`` its high edge. ``sl`` is the blob's bounding box (slices of the
    frame), ``hiding`` the (h, w) mask of pixels that may hide a box,
    ``grid`` the (h, w, 2) grid coordinates of each pixel. A box is an
    axis-aligned square seen from above, so its edges are the box's sides:
    an edge is hidden when at least `HIDDEN_SHARE` of the pixels just
    beyond that side are in ``hiding``, or it is the frame's border."""
    h, w = hiding.shape
    r0, r1, c0, c1 = sl[0].start, sl[0].stop, sl[1].start, sl[1].stop
    rc, cc = (r0 + r1) // 2, (c0 + c1) // 2
    out = np.zeros((2, 2), bool)
    for r, c, dr, dc in (
        (r0 - 1, None, -1, 0),
        (r1, None, 1, 0),
        (None, c0 - 1, 0, -1),
        (None, c1, 0, 1),
    ):
        if r is not None:
            hidden = not 0 <= r < h or hiding[r, c0:c1].mean() >= HIDDEN_SHARE
        else:
            assert c is not None  # each side gives its row or its column
            hidden = not 0 <= c < w or hiding[r0:r1, c].mean() >= HIDDEN_SHARE
        if hidden:
            step = grid[min(max(rc + dr, 0), h - 1), min(max(cc + dc, 0), w - 1)] - grid[rc, cc]
            axis = int(np.argmax(np.abs(step)))
            out[axis, int(step[axis] > 0)] = True
    return out


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
        new = np.asarray(
            [points[lab == j].mean(0) if np.any(lab == j) else centres[j] for j in range(k)]
        )
        if np.allclose(new, centres):
            break
        centres = new
    return [points[lab == j] for j in range(k) if np.any(lab == j)]


def wall_limits(centre, walls, half) -> np.ndarray:
    """Bounds a wall puts on a box's centre: (2, 2), ``[axis, 0]`` the
    lowest and ``[axis, 1]`` the highest grid coordinate along ``axis``
    (infinite without a wall there). ``centre`` is a rough grid (row, col)
    of the box, ``walls`` the bool grid of wall cells, ``half`` the box's
    half side (cells): a box in cell ``(r, c)`` with a wall at ``(r, c + 1)``
    has its centre at most at ``c + 0.5 - half``."""
    r, c = (int(v) for v in np.rint(centre))
    rows, cols = walls.shape
    out = np.array([[-np.inf, np.inf], [-np.inf, np.inf]])
    for axis, cell in enumerate((r, c)):
        for side_, step in ((0, -1), (1, 1)):
            nr, nc = (r + step, c) if axis == 0 else (r, c + step)
            if not (0 <= nr < rows and 0 <= nc < cols) or walls[nr, nc]:
                out[axis, side_] = cell + step * (0.5 - half)
    return out


def box_centre(pts, side, px, walker_g, hidden=None, limits=None):
    """Grid (row, col) of a box's centre from its visible pixels (their
    centres' grid coordinates ``pts``; ``px`` cells per pixel).

    Frames are not antialiased: a pixel is box-coloured when its centre
    lies on the box. Along each axis the first and last box pixel (``vmin``,
    ``vmax``) lie on the box, so the centre is at most ``side / 2`` past
    either; an edge that is not hidden also lies within one pixel beyond
    its last pixel, which bounds the centre from the other side. The centre
    is the midpoint of the interval these bounds leave. ``hidden`` (2, 2)
    (`hidden_edges`) says which edges may be hidden (they give only their
    one-sided bound); where it flags neither (or is None), a blob more than
    1.2 pixels shorter than the box along an axis is taken to be cut on the
    side nearer the walker (an ear or the ball hides the near side).
    ``limits`` (`wall_limits`) narrows the interval where walls stop the box.
    """
    centre = np.empty(2)
    for axis in range(2):
        v = pts[:, axis]
        vmin, vmax = v.min(), v.max()
        cut_lo, cut_hi = (False, False) if hidden is None else map(bool, hidden[axis])
        if not (cut_lo or cut_hi) and walker_g is not None and vmax - vmin + px < side - 1.2 * px:
            near_lo = abs(walker_g[axis] - vmin) < abs(walker_g[axis] - vmax)
            cut_lo, cut_hi = near_lo, not near_lo
        lo = vmax - side / 2 if cut_lo else max(vmin - px + side / 2, vmax - side / 2)
        hi = vmin + side / 2 if cut_hi else min(vmin + side / 2, vmax + px - side / 2)
        mid = 0.5 * (lo + hi) if lo <= hi else 0.5 * (vmin + vmax)
        if limits is not None:
            lo, hi = max(lo, limits[axis, 0]), min(hi, limits[axis, 1])
            mid = 0.5 * (lo + hi) if lo <= hi else min(max(mid, limits[axis, 0]), limits[axis, 1])
        centre[axis] = mid
    return centre
