"""The walker's position from its ears' silhouettes in a top-camera frame,
for `hier_agents.estimators.camera.CameraEstimator`.

The ears are spheres (radius `EAR_RADIUS`) at +-`EAR_OFFSET` along the head's
lateral axis, `EAR_HEIGHT` up. When walls hide part of an ear, `fit_ears`
fits the centre to the visible ear outlines (least squares); `match_ears`
refines to sub-pixel by matching rendered silhouettes over a grid of
candidate centres. Positions are world metres (x, y); ``lateral`` is the
head's unit lateral axis (red ear at ``+EAR_OFFSET * lateral``).
"""

from __future__ import annotations

import numpy as np

from hier_agents.estimators.base import EstimationError

__all__ = ["EAR_RADIUS", "EAR_OFFSET", "EAR_HEIGHT", "locate_walker", "match_ears", "fit_ears"]

# Scene geometry (metres): public facts of the walker model (dm_control's
# RollingBallWithHead with ears).
EAR_RADIUS = 0.26
EAR_OFFSET = 0.22
EAR_HEIGHT = 0.6
#: `match_ears` passes of `locate_walker`: (half-width in pixels, candidates
#: per axis); each pass is centred on the previous one's result.
MATCH_PASSES = ((1.0, 9), (0.3, 9), (0.075, 9))


def locate_walker(red, blue, occluder, grid, m_per_px, heading, radius, to_world) -> np.ndarray:
    """World (x, y) of the walker from its ears' silhouettes.

    ``red``, ``blue``: (h, w) bool masks of the ear colours; ``occluder``:
    (h, w) bool, pixels where walls (or unsure colours) may hide an ear;
    ``grid``: (h, w, 2) grid coordinates of each pixel at `EAR_HEIGHT`;
    ``m_per_px``: metres per pixel there; ``heading``: the head's yaw
    (rad); ``radius``: the ear's outline as seen (m); ``to_world``: grid
    coordinates (..., 2) -> world (..., 2). Starts from the ear pixels'
    centroid, fits the visible outlines when occluders are near
    (`fit_ears`), then refines (`match_ears`, `MATCH_PASSES`). Raises `EstimationError`
    when fewer than a tenth of one ear's pixels are seen.
    """
    ears = red | blue
    n = int(ears.sum())
    px_area = m_per_px**2
    full = (2 * np.pi * EAR_RADIUS**2) / px_area
    if n < 0.1 * full:
        raise EstimationError(f"walker not found: {n} ear pixels (expected ~{full:.0f})")
    rows, cols = np.nonzero(ears)
    obs_g = grid[rows, cols].mean(axis=0)  # grid coords (row, col)
    centre = to_world(obs_g)
    lateral = np.array([np.sin(heading), -np.cos(heading)])
    # Refine against the wall occlusion (only when walls are near).
    r0, r1 = rows.min(), rows.max() + 1
    c0, c1 = cols.min(), cols.max() + 1
    pad = int(np.ceil(EAR_RADIUS * 2 / m_per_px)) + 2
    h, w = ears.shape
    r0, c0 = max(r0 - pad, 0), max(c0 - pad, 0)
    r1, c1 = min(r1 + pad, h), min(c1 + pad, w)
    occ = occluder[r0:r1, c0:c1]
    world = to_world(grid[r0:r1, c0:c1])
    red_w, blue_w = red[r0:r1, c0:c1], blue[r0:r1, c0:c1]
    if occ.any():
        centre = fit_ears(centre, lateral, red_w, blue_w, occ, world, radius)
    step = m_per_px
    for span, n in MATCH_PASSES:
        centre = match_ears(
            centre, lateral, red_w, blue_w, occ, world, radius, np.linspace(-span, span, n) * step
        )
    return centre


def match_ears(centre, lateral, red, blue, occ, world, radius, offsets):
    """Sub-pixel refinement: a pixel shows an ear when its centre is on
    the ear's disk of ``radius`` (the outline shrunk by the coverage
    inset); among candidate centres (``centre`` + a grid of ``offsets``)
    keep those whose silhouettes (nearer ear in front, walls hiding both)
    disagree with the observed ones on fewest pixels, and return their
    mean. Only pixels whose prediction can differ between candidates are
    compared: within the largest shift of an ear's outline or of the line
    between the ears (the others add the same count to every candidate)."""
    vis = ~occ
    pts = world[vis]  # (n, 2)
    shift = float(np.max(np.abs(offsets))) * np.sqrt(2.0) + 1e-9
    dr0 = np.linalg.norm(pts - (np.asarray(centre) + EAR_OFFSET * lateral), axis=1)
    db0 = np.linalg.norm(pts - (np.asarray(centre) - EAR_OFFSET * lateral), axis=1)
    near = (
        (np.abs(dr0 - radius) <= shift)
        | (np.abs(db0 - radius) <= shift)
        | (np.abs(dr0 - db0) <= 2 * shift)
    )
    vis[vis] = near
    pts = pts[near]
    obs_r, obs_b = red[vis], blue[vis]
    # Candidate centres form a grid (x offset i, y offset j), so a squared
    # distance splits into an x term of i and a y term of j: computed per
    # axis and added, bit for bit the direct sums.
    cx = (centre[0] + offsets) + EAR_OFFSET * lateral[0]  # red ear x per i
    cy = (centre[1] + offsets) + EAR_OFFSET * lateral[1]
    bx = (centre[0] + offsets) - EAR_OFFSET * lateral[0]  # blue ear
    by = (centre[1] + offsets) - EAR_OFFSET * lateral[1]
    k = len(offsets)
    dr = ((pts[None, :, 0] - cx[:, None]) ** 2)[:, None, :] + (
        (pts[None, :, 1] - cy[:, None]) ** 2
    )[None, :, :]
    db = ((pts[None, :, 0] - bx[:, None]) ** 2)[:, None, :] + (
        (pts[None, :, 1] - by[:, None]) ** 2
    )[None, :, :]
    dr, db = dr.reshape(k * k, -1), db.reshape(k * k, -1)
    r2 = radius**2
    pred_r = (dr <= r2) & (dr <= db)
    pred_b = (db <= r2) & (db < dr)
    miss = np.count_nonzero(pred_r != obs_r[None], axis=1) + np.count_nonzero(
        pred_b != obs_b[None], axis=1
    )
    dx, dy = np.meshgrid(offsets, offsets, indexing="ij")
    cands = np.asarray(centre)[None, :] + np.stack([dx.ravel(), dy.ravel()], 1)
    best = cands[miss == miss.min()]
    return best.mean(axis=0)


def fit_ears(centre, lateral, red, blue, occ, world, radius):
    """Least-squares fit of the walker's centre to the ears' visible
    outlines: every ear pixel next to a pixel that is neither ear nor wall
    gives an edge point (the two pixels' midpoint) that lies on its ear's
    circle. Used when walls hide part of an ear (the centroid is then
    biased)."""
    points, signs = [], []
    for ear, other, sign in ((red, blue, 1.0), (blue, red, -1.0)):
        for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            inner = ear[
                max(-dr, 0) : ear.shape[0] - max(dr, 0), max(-dc, 0) : ear.shape[1] - max(dc, 0)
            ]
            sl = (
                slice(max(dr, 0), ear.shape[0] + min(dr, 0)),
                slice(max(dc, 0), ear.shape[1] + min(dc, 0)),
            )
            outer_ok = ~ear[sl] & ~other[sl] & ~occ[sl]
            hit = inner & outer_ok
            if not hit.any():
                continue
            pin = world[
                max(-dr, 0) : ear.shape[0] - max(dr, 0), max(-dc, 0) : ear.shape[1] - max(dc, 0)
            ][hit]
            pout = world[sl][hit]
            points.append(0.5 * (pin + pout))
            signs.append(np.full(len(pin), sign))
    if not points:
        return centre
    pts = np.concatenate(points)
    off = np.concatenate(signs)[:, None] * EAR_OFFSET * lateral[None, :]
    keep = np.ones(len(pts), bool)
    c = np.asarray(centre, float)
    for it in range(8):
        d = pts - (c + off)
        dist = np.linalg.norm(d, axis=1)
        res = dist - radius
        if it >= 2:
            keep = np.abs(res) < 0.06
        if keep.sum() < 6:
            break
        jac = -d[keep] / np.maximum(dist[keep], 1e-9)[:, None]
        step, *_ = np.linalg.lstsq(jac, -res[keep], rcond=None)
        c = c + step
        if np.abs(step).max() < 1e-5:
            break
    return c
