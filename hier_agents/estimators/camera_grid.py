"""Reading MuJoBan's static grid (walls and target pads) from one top-camera
frame, for `hier_agents.estimators.camera.CameraEstimator`.

* targets: cells at least 12% pad-coloured or covered by a box in its
  on-a-pad colour (a centred box leaves a thin ring of the pad visible);
* walls: every wall cell shows the same texture (one copy per cell, the
  same phase), and the floor cells another. The grid's outer ring is walls
  (Boxoban levels have a wall border; smaller generated levels are padded
  with walls), so a cell is a wall when its colour distribution (7
  quantiles per channel over its top, at wall height) is within
  `WALL_MATCH` (mean absolute difference) of one ring cell's, and all its
  colours are wall colours (none more than ~8 levels from every ring
  colour).

Also the pixel masks of the walls' footprint (`wall_footprint`). Every
function here is pure: pixel-to-cell maps come in as arrays.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from hier_agents.estimators.base import EstimationError

__all__ = [
    "WALL_MATCH",
    "QUANTILES",
    "cell_pixel_index",
    "read_targets",
    "read_walls",
    "signatures",
    "foreign_fraction",
    "wall_footprint",
    "grid_to_world",
]

#: Quantiles (percent) of a cell's colours compared between cells, and the
#: largest mean absolute difference (0..255 units) of a wall match. With the
#: environment's 8 wall and 6 floor textures (all 48 pairs, 6 Boxoban levels,
#: pegs and not) wall cells differ from the ring's by at most 0.54 (sub-pixel
#: sampling), free floor cells by at least 7.5 (blue walls on the blue_team
#: floor; every other pair >= 15.9); the threshold sits between, nearer the
#: walls. A floor cell below it is still told apart when some of its colours
#: are not wall colours at all (`foreign_fraction`).
QUANTILES = (2, 10, 25, 50, 75, 90, 98)
WALL_MATCH = 3.0


def read_targets(pad_mask, cell_index, grid_shape) -> frozenset:
    """The target cells: (row, col) of every cell more than 12% of whose
    pixels (``cell_index`` = (rows, cols, inside) of each pixel at pad height,
    as `CameraEstimator._cell_index`) are set in ``pad_mask`` (H, W bool: pad
    or box-on-pad colour)."""
    height, width = grid_shape
    pr, pc, pin = cell_index
    ok = pin & (pr >= 0) & (pr < height) & (pc >= 0) & (pc < width)
    pad_count = np.zeros((height, width))
    all_count = np.zeros((height, width))
    np.add.at(pad_count, (pr[ok], pc[ok]), pad_mask[ok])
    np.add.at(all_count, (pr[ok], pc[ok]), 1)
    pad_frac = pad_count / np.maximum(all_count, 1)
    return frozenset((int(r), int(c)) for r, c in zip(*np.nonzero(pad_frac > 0.12)))


def read_walls(frame, index, targets, grid_shape) -> frozenset:
    """The wall cells (row, col) of ``frame`` (H, W, 3 uint8): the outer ring
    and every cell whose `signatures` match a ring cell's within `WALL_MATCH`
    and whose `foreign_fraction` is below 2%; never a target. ``index`` is
    `cell_pixel_index` at wall height. Raises `EstimationError` when more
    than a tenth of the ring cells match no other ring cell (no wall border)."""
    height, width = grid_shape
    sig = signatures(frame, index, grid_shape)
    ring = np.zeros((height, width), bool)
    ring[0, :] = ring[-1, :] = ring[:, 0] = ring[:, -1] = True
    ring_sigs = sig[ring]
    pair = np.abs(ring_sigs[:, None, :] - ring_sigs[None, :, :]).mean(-1)
    np.fill_diagonal(pair, np.inf)
    unmatched = int(np.sum(pair.min(1) >= WALL_MATCH))
    if unmatched > len(ring_sigs) // 10:
        raise EstimationError(
            f"reset: {unmatched} of the grid's {len(ring_sigs)} outer "
            f"cells do not look like the others (no wall border?)"
        )
    dist = np.abs(sig[:, :, None, :] - ring_sigs[None, None, :, :]).mean(-1).min(-1)
    walls = (dist < WALL_MATCH) & (foreign_fraction(frame, index, ring, grid_shape) < 0.02)
    walls[0, :] = walls[-1, :] = walls[:, 0] = walls[:, -1] = True
    for t in targets:
        walls[t] = False
    return frozenset((int(r), int(c)) for r, c in zip(*np.nonzero(walls)))


def cell_pixel_index(cell_index, grid_shape):
    """(order, starts): the frame's flat pixel indices sorted by cell, and per
    cell k (row-major) the slice ``starts[k]:starts[k + 1]`` of ``order``
    holding its pixels. ``cell_index`` = (rows, cols, inside) per pixel."""
    height, width = grid_shape
    r, c, inside = cell_index
    ok = inside & (r >= 0) & (r < height) & (c >= 0) & (c < width)
    flat = np.where(ok, r * width + c, -1).ravel()
    order = np.argsort(flat, kind="stable")
    flat_sorted = flat[order]
    starts = np.searchsorted(flat_sorted, np.arange(height * width + 1))
    return order, starts


def foreign_fraction(frame, index, ring, grid_shape) -> np.ndarray:
    """(H, W): per cell, the fraction of its pixels (``index`` from
    `cell_pixel_index`) whose colour is more than ~8 levels (any channel)
    from every colour of the ``ring`` (H, W bool) cells. A wall cell has none
    (measured: exactly 0)."""
    height, width = grid_shape
    order, starts = index
    q = frame.reshape(-1, 3)[order] // 4
    code = (q[:, 0].astype(np.int32) * 64 + q[:, 1]) * 64 + q[:, 2]
    seen = np.zeros(64**3, np.uint8)
    for k in np.flatnonzero(ring.ravel()):
        seen[code[starts[k] : starts[k + 1]]] = 1
    seen = ndimage.maximum_filter(seen.reshape(64, 64, 64), size=5).ravel().astype(bool)
    out = np.zeros(height * width)
    for cell in range(height * width):
        if starts[cell + 1] > starts[cell]:
            out[cell] = 1.0 - seen[code[starts[cell] : starts[cell + 1]]].mean()
    return out.reshape(height, width)


def signatures(frame, index, grid_shape) -> np.ndarray:
    """(H, W, 21): per cell, the 2/10/25/50/75/90/98 % quantiles of each
    colour channel over its pixels (``index`` from `cell_pixel_index`)."""
    height, width = grid_shape
    order, starts = index
    pixels = frame.reshape(-1, 3)[order].astype(np.float32)
    out = np.zeros((height * width, 3 * len(QUANTILES)), np.float32)
    for k in range(height * width):
        px = pixels[starts[k] : starts[k + 1]]
        if len(px):
            out[k] = np.percentile(px, QUANTILES, axis=0).T.ravel()
    return out.reshape(height, width, -1)


def wall_footprint(grid, wall_grid, margin=0.0) -> np.ndarray:
    """(h, w) bool: pixels whose point at one height (``grid``: (h, w, 2)
    continuous grid coordinates of each pixel there) lies in a wall cell of
    ``wall_grid`` (H, W bool), the cell grown by ``margin`` cells."""
    height, width = wall_grid.shape
    out = np.zeros(grid.shape[:2], bool)
    rc = np.floor(grid + 0.5 + margin).astype(int), np.floor(grid + 0.5 - margin).astype(int)
    for a in rc:
        for b in rc:
            r, c = a[..., 0], b[..., 1]
            ok = (r >= 0) & (r < height) & (c >= 0) & (c < width)
            hit = np.zeros_like(out)
            hit[ok] = wall_grid[r[ok], c[ok]]
            out |= hit
    return out


def grid_to_world(description, g) -> np.ndarray:
    """World (x, y) metres of continuous grid coordinates ``g`` (..., 2:
    row, col) in ``description``'s grid (``grid_shape``, ``cell_size``;
    the grid is centred on the origin, rows going down in y)."""
    height, width = description.grid_shape
    g = np.asarray(g, float)
    x = (g[..., 1] - (width - 1) / 2) * description.cell_size
    y = ((height - 1) / 2 - g[..., 0]) * description.cell_size
    return np.stack([x, y], axis=-1)
