"""`CameraEstimator` (``camera``): MuJoBan's scene from the top camera, by
classical vision. Observation-only (``privileged = False``).

Inputs: the public `envs.description.MujobanDescription` (grid shape, cell
size, box and camera geometry), the ``top_camera`` frames and the walker's
proprioception (``walker/orientation``, ``walker/sensors_velocimeter``).
Nothing from the simulator, ``full_entity_layer`` or ``pixel_layer``.

Method
------
Every pixel is mapped to continuous grid coordinates on a horizontal plane
with the camera's pinhole model (`CameraDescription.unproject`, checked
against rendered frames to a few hundredths of a pixel): z = 1 m for wall
tops, 0.3 m (``2 * box_half_height``) for box tops, 0.6 m for the walker's
ears, 0 for pads.

Colours come from the description, not from one palette: the
description's `MujobanLooks` names the colours of boxes (and of a box on a
pad), pads (and covered pads), the walker's ears, and the light (one
headlight at the camera). An untextured surface facing the camera renders
as ``min(1, rgba * (ambient + diffuse)) * 255`` (`MujobanLooks.facing_rgb`),
exactly; an ear, a shaded sphere, as its colour times a light between
ambient and ambient + diffuse. `colours.colour_table` turns that into a class per
24-bit colour (`hier_agents.estimators.colours`): a pad's saturated red is never an
ear's shaded red, and pixels next to a flat object of an ear's hue (a blue
box's slanted sides) are not read as an ear but as hidden. Walls and floors
are textured (a texture drawn per episode); none of their texels comes near
these colours. With multisampling (`CameraDescription.multisamples`) a pixel
shows an object's own colour only where it covers all samples, so outlines
are measured shrunk by `CameraDescription.coverage_inset`.

``reset`` reads the static grid from the first frame:

* targets: cells at least 12% pad-coloured or covered by a box in its
  on-a-pad colour (a centred box leaves a thin ring of the pad visible);
* walls: every wall cell shows the same texture (one copy per cell, the
  same phase), and the floor cells another. The grid's outer ring is walls
  (Boxoban levels have a wall border; smaller generated levels are padded
  with walls), so a cell is a wall when its colour distribution (7
  quantiles per channel over its top, at wall height) is within
  `WALL_MATCH` (mean absolute difference) of one ring cell's, and all its
  colours are wall colours (none more than ~8 levels from every ring
  colour). Walls and targets are static: read once per episode.
* boxes: as below; their number must equal the number of pads, and their
  order is by cell (the task's order).

Per frame (``estimate``):

* walker: the ears are spheres (radius 0.26 m) at +-0.22 m along the head's
  lateral axis (heading from proprioception), 0.6 m up, so their silhouettes
  fix the walker's (x, y). Start from the ear pixels' centroid; when walls
  (1 m tall, known footprint) hide part of an ear, fit the centre to the
  visible ear outlines (least squares); then refine to sub-pixel by matching
  rendered silhouettes (frames are not antialiased: a pixel shows an ear
  when its centre is on it; nearer ear in front, walls hiding both) over a
  grid of candidate centres, keeping the mean of the best.
* boxes: connected components of box-coloured pixels inside non-wall cells;
  a component holding several touching boxes (by area) is split by k-means.
  A box is an axis-aligned 0.8-cell square that never turns: along each axis
  the first and last box pixel bound each edge within a pixel and the known
  side length narrows the centre to their intersection (the frame size,
  199 px, makes the side 14.5 px, which halves that interval); when an ear
  hides one side, the far edge minus half the side. Boxes keep their order
  (optimal assignment to the previous positions).
* heading and velocity: proprioception (`skills.scene.heading_from_orientation`,
  `skills.scene.world_velocity`).
* abstract state: `rounded_state` (the paper's rounding rule), remembering the
  previous player cell (call ``estimate`` every step, as the task rounds
  every step).

Frame schedule (``estimate``): rendering and reading a frame costs ~8 ms
(render ~4.4, read ~3.5), five times the physics of a level-5 step, so the
estimator reads a frame every ``frame_every`` (3) steps, every
``near_every`` (2) while the walker is within `NEAR_BOX` of a box or a box
moves, and locates the walker in every ``walker_every`` (2)-th frame read;
the environment renders only the frames read (``lazy_cameras=True``, in
``env_overrides``). In between it predicts: the walker by integrating its
velocimeter (trapezoid; drift < 0.03 cells between fixes), a box the walker
touches and rolls into moves with the walker along that axis, any other box
keeps its last measured velocity less the floor's friction deceleration
(`BOX_DECEL`). ``CameraEstimator(frame_every=1, walker_every=1)`` reads and
locates everything in every frame.

Raises `EstimationError` when the walker is not seen, when the number of
boxes seen differs from reset's (or, at reset, from the number of pads), when
the outer ring does not look like walls, or when `rounded_state` finds an
inconsistency.

Assumptions: the grid's outer ring is walls (true for every registered
level source); the camera looks straight down (the environment's); boxes do
not turn (slide joints); the walker is dm_control's rolling ball with ears.
Frame size: 199x199 for the 10x10 arena (18.1 px per cell).

Accuracy and cost: ``benchmarks/estimator_accuracy.py`` (whole-grid
accuracy per level source and per drawn wall/floor appearance, position
errors, ms per estimate), ``results/estimator_accuracy.json``; on the
original environment's own frames: ``benchmarks/original_env.py``.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.optimize import linear_sum_assignment

from hier_agents.estimators.base import EstimationError, Estimator
from hier_agents.estimators.colours import masks as _masks
from hier_agents.estimators.grid import rounded_state
from skills.scene import BallScene, heading_from_orientation, world_velocity

__all__ = ["CameraEstimator", "FRAME_SHAPE"]

#: The top camera's frame size this estimator asks for.
FRAME_SHAPE = (199, 199)
#: Read every this many-th frame by default (the environment renders only
#: those with ``lazy_cameras``); predict the scene in between.
FRAME_EVERY = 3
#: Box speeds (m/s) below this, measured between two frames, are noise: still.
BOX_STILL = 0.1
#: Every ``near_every``-th frame is read while the walker's centre is within
#: this distance (m, along both axes) of a box's centre: contact is at 0.6
#: (ball radius plus half a box), so a box may be pushed soon.
NEAR_BOX = 0.95
NEAR_EVERY = 2
#: The walker is located in every this many-th frame read; in between, and
#: between frames, its velocimeter is integrated (drift < 0.03 cells).
WALKER_EVERY = 2
#: A box slides to rest on floor friction 0.5 at ~4.9 m/s^2 (measured).
BOX_DECEL = 4.9
#: The walker counts as touching a box up to this far (m) beyond contact.
CONTACT_SLACK = 0.03

# Scene geometry (metres) the estimator relies on; public facts of the walker
# model (dm_control's RollingBallWithHead with ears) and the props.
EAR_RADIUS = 0.26
EAR_OFFSET = 0.22
EAR_HEIGHT = 0.6
WALL_HEIGHT = 1.0
#: Quantiles (percent) of a cell's colours compared between cells, and the
#: largest mean absolute difference (0..255 units) of a wall match. With the
#: environment's 8 wall and 6 floor textures (all 48 pairs, 6 Boxoban levels,
#: pegs and not) wall cells differ from the ring's by at most 0.54 (sub-pixel
#: sampling), free floor cells by at least 7.5 (blue walls on the blue_team
#: floor; every other pair >= 15.9); the threshold sits between, nearer the
#: walls. A floor cell below it is still told apart when some of its colours
#: are not wall colours at all (`CameraEstimator._foreign_fraction`).
_QUANTILES = (2, 10, 25, 50, 75, 90, 98)
WALL_MATCH = 3.0


class CameraEstimator(Estimator):
    """The scene from the top camera's frames and proprioception. See the
    module docstring for the method, its assumptions, accuracy and cost."""

    name = "camera"
    privileged = False
    #: The frame size it reads, rendered only when it reads a frame.
    env_overrides = {"top_camera": FRAME_SHAPE, "lazy_cameras": True}

    def __init__(self, camera: str = "top_camera", frame_every: int = FRAME_EVERY,
                 near_every: int = NEAR_EVERY, walker_every: int = WALKER_EVERY) -> None:
        for label, value in (("frame_every", frame_every), ("near_every", near_every),
                             ("walker_every", walker_every)):
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{label} must be an integer >= 1, got {value!r}")
        self._camera_key = camera
        self.frame_every = frame_every
        self.near_every = min(near_every, frame_every)
        self.walker_every = walker_every
        self._desc = None
        #: Frames looked at and steps predicted since construction (for benchmarks).
        self.frames_read = 0
        self.steps_predicted = 0

    # -- geometry ---------------------------------------------------------

    def _setup_geometry(self, description, shape) -> None:
        if description.looks is None:
            raise EstimationError("the task description names no looks (object colours and "
                                  "light): the camera estimator needs them")
        if self._desc == description and self._shape == shape:
            return
        self._desc, self._shape = description, shape
        self._sig_index = None
        cam = description.top_camera
        h, w = shape
        rows, cols = np.mgrid[0:h, 0:w]
        pix = np.stack([rows + 0.5, cols + 0.5], axis=-1).reshape(-1, 2)
        self._grid = {}
        self._box_z = 2.0 * float(description.box_half_height)   # box tops
        for z in (0.0, self._box_z, EAR_HEIGHT, WALL_HEIGHT):
            xy = cam.unproject(pix, z=z, shape=shape)[:, :2]
            self._grid[z] = description.world_to_grid(xy).reshape(h, w, 2)
        # metres per pixel at each height (for sizes)
        f = cam.focal(h)
        self._m_per_px = {z: (cam.position[2] - z) / f for z in self._grid}
        # With multisampling, a pixel shows an object's own colour only where
        # its centre lies `coverage_inset` pixels inside the outline: the
        # estimator measures outlines shrunk by that much.
        self._inset = float(cam.coverage_inset)
        self._ear_radius = EAR_RADIUS - self._inset * self._m_per_px[EAR_HEIGHT]

    def _cell_index(self, z, margin=0.0):
        """(rows, cols) int arrays of each pixel's cell at height z, and a mask
        of pixels within ``0.5 - margin`` of their cell centre (both axes)."""
        g = self._grid[z]
        rc = np.rint(g).astype(int)
        inside = np.all(np.abs(g - rc) <= 0.5 - margin, axis=-1)
        return rc[..., 0], rc[..., 1], inside

    # -- reset: the static grid -------------------------------------------

    def reset(self, description, timestep) -> None:
        frame = np.asarray(timestep.observation[self._camera_key])
        self._setup_geometry(description, frame.shape[:2])
        height, width = description.grid_shape
        masks = _masks(frame, self._desc.looks)
        self._walls, self._targets = self._read_static(frame, masks)
        wall_grid = np.zeros((height, width), bool)
        for r, c in self._walls:
            wall_grid[r, c] = True
        self._wall_grid = wall_grid
        self._precompute_masks()
        self._num_boxes = None
        self._box_xy = None
        self._player = None
        boxes = self._detect_boxes(frame, masks, self._walker_guess(masks, timestep))
        if len(boxes) != len(self._targets):
            raise EstimationError(f"reset: {len(boxes)} boxes seen but {len(self._targets)} "
                                  f"target pads")
        cells = [description.world_to_cell(xy) for xy in boxes]
        order = sorted(range(len(boxes)), key=lambda i: cells[i])
        self._num_boxes = len(boxes)
        self._box_xy = np.asarray(boxes, float)[order].reshape(-1, 2)
        self._dt = float(description.control_timestep)
        self._since = 0          # steps since the last frame read
        self._walker_xy = None   # the last estimate (frame or prediction)
        self._velocity = None
        self._box_v = np.zeros_like(self._box_xy)
        self._frame_boxes = None  # boxes at the last frame read
        self._walker_reads = 0    # frames read since the walker was last located

    def _read_static(self, frame, masks):
        desc = self._desc
        height, width = desc.grid_shape
        # Pads (z = 0): a cell is a target when enough of it is pad-coloured
        # (a centred box leaves a 0.1-cell ring of the pad visible).
        pr, pc, pin = self._cell_index(0.0, margin=0.05)
        ok = pin & (pr >= 0) & (pr < height) & (pc >= 0) & (pc < width)
        pad_count = np.zeros((height, width))
        all_count = np.zeros((height, width))
        # A box's top in its on-a-pad colour shows a pad under it too (with
        # multisampling the covered pad's ring is only ~1 pixel wide).
        np.add.at(pad_count, (pr[ok], pc[ok]), (masks["pad"] | masks["box_on_pad"])[ok])
        np.add.at(all_count, (pr[ok], pc[ok]), 1)
        pad_frac = pad_count / np.maximum(all_count, 1)
        targets = frozenset((int(r), int(c)) for r, c in zip(*np.nonzero(pad_frac > 0.12)))

        # Every wall cell shows one copy of the episode's wall texture, every
        # floor cell one of its floor texture. A cell is a wall when the distribution of its
        # colours (per-channel quantiles over the cell's top at wall height)
        # matches one of the outer ring's cells, which are all walls.
        sig = self._signatures(frame)
        ring = np.zeros((height, width), bool)
        ring[0, :] = ring[-1, :] = ring[:, 0] = ring[:, -1] = True
        ring_sigs = sig[ring]
        pair = np.abs(ring_sigs[:, None, :] - ring_sigs[None, :, :]).mean(-1)
        np.fill_diagonal(pair, np.inf)
        unmatched = int(np.sum(pair.min(1) >= WALL_MATCH))
        if unmatched > len(ring_sigs) // 10:
            raise EstimationError(f"reset: {unmatched} of the grid's {len(ring_sigs)} outer "
                                  f"cells do not look like the others (no wall border?)")
        dist = np.abs(sig[:, :, None, :] - ring_sigs[None, None, :, :]).mean(-1).min(-1)
        walls = (dist < WALL_MATCH) & (self._foreign_fraction(frame, ring) < 0.02)
        walls[0, :] = walls[-1, :] = walls[:, 0] = walls[:, -1] = True
        for t in targets:
            walls[t] = False
        return (frozenset((int(r), int(c)) for r, c in zip(*np.nonzero(walls))), targets)

    def _foreign_fraction(self, frame, ring) -> np.ndarray:
        """(H, W): per cell, the fraction of its pixels (as in `_signatures`)
        whose colour is more than ~8 levels (any channel) from every colour
        of the ring cells. A wall cell has none (measured: exactly 0)."""
        height, width = self._desc.grid_shape
        order, starts = self._sig_index
        q = frame.reshape(-1, 3)[order] // 4
        code = (q[:, 0].astype(np.int32) * 64 + q[:, 1]) * 64 + q[:, 2]
        seen = np.zeros(64 ** 3, np.uint8)
        for k in np.flatnonzero(ring.ravel()):
            seen[code[starts[k]:starts[k + 1]]] = 1
        seen = ndimage.maximum_filter(seen.reshape(64, 64, 64), size=5).ravel().astype(bool)
        out = np.zeros(height * width)
        for k in range(height * width):
            if starts[k + 1] > starts[k]:
                out[k] = 1.0 - seen[code[starts[k]:starts[k + 1]]].mean()
        return out.reshape(height, width)

    def _signatures(self, frame) -> np.ndarray:
        """(H, W, 21): per cell, the 2/10/25/50/75/90/98 % quantiles of each
        colour channel over the cell's central 0.9 x 0.9 at wall-top height."""
        height, width = self._desc.grid_shape
        if self._sig_index is None:
            r, c, inside = self._cell_index(WALL_HEIGHT, margin=0.05)
            ok = inside & (r >= 0) & (r < height) & (c >= 0) & (c < width)
            flat = np.where(ok, r * width + c, -1).ravel()
            order = np.argsort(flat, kind="stable")
            flat_sorted = flat[order]
            starts = np.searchsorted(flat_sorted, np.arange(height * width + 1))
            self._sig_index = (order, starts)
        order, starts = self._sig_index
        pixels = frame.reshape(-1, 3)[order].astype(np.float32)
        out = np.zeros((height * width, 3 * len(_QUANTILES)), np.float32)
        for k in range(height * width):
            px = pixels[starts[k]:starts[k + 1]]
            if len(px):
                out[k] = np.percentile(px, _QUANTILES, axis=0).T.ravel()
        return out.reshape(height, width, -1)

    def _precompute_masks(self) -> None:
        """Pixel masks of the wall footprint: the cells whose walls hide the
        ears (z 0.34..0.86 m) and a safety band around walls for boxes."""
        height, width = self._desc.grid_shape

        def wall_at(z, margin=0.0):
            g = self._grid[z]
            out = np.zeros(g.shape[:2], bool)
            rc = np.floor(g + 0.5 + margin).astype(int), np.floor(g + 0.5 - margin).astype(int)
            for a in rc:
                for b in rc:
                    r, c = a[..., 0], b[..., 1]
                    ok = (r >= 0) & (r < height) & (c >= 0) & (c < width)
                    hit = np.zeros_like(out)
                    hit[ok] = self._wall_grid[r[ok], c[ok]]
                    out |= hit
            return out

        g0 = self._grid[0.0]
        outside = ((g0[..., 0] < -0.5) | (g0[..., 0] > height - 0.5)
                   | (g0[..., 1] < -0.5) | (g0[..., 1] > width - 0.5))
        self._occluder = wall_at(WALL_HEIGHT) | wall_at(EAR_HEIGHT)
        # Box pixels must lie (at box height) in a non-wall cell, away from
        # the walls' footprint by a small band.
        self._box_allowed = ~(wall_at(self._box_z, margin=0.04)
                              | wall_at(WALL_HEIGHT, margin=0.04) | outside)

    # -- per frame ----------------------------------------------------------

    def _walker_guess(self, masks, timestep):
        try:
            return self._find_walker(masks, timestep)
        except EstimationError:
            return None

    def _find_walker(self, masks, timestep) -> np.ndarray:
        """World (x, y) of the walker from its ears' silhouettes."""
        red, blue = masks["red_ear"], masks["blue_ear"]
        ears = red | blue
        n = int(ears.sum())
        px_area = self._m_per_px[EAR_HEIGHT] ** 2
        full = (2 * np.pi * EAR_RADIUS ** 2) / px_area
        if n < 0.1 * full:
            raise EstimationError(f"walker not found: {n} ear pixels (expected ~{full:.0f})")
        rows, cols = np.nonzero(ears)
        grid = self._grid[EAR_HEIGHT]
        obs_g = grid[rows, cols].mean(axis=0)            # grid coords (row, col)
        centre = self._grid_to_world(obs_g)
        heading = heading_from_orientation(timestep.observation["walker/orientation"])
        lateral = np.array([np.sin(heading), -np.cos(heading)])
        # Refine against the wall occlusion (only when walls are near).
        r0, r1 = rows.min(), rows.max() + 1
        c0, c1 = cols.min(), cols.max() + 1
        pad = int(np.ceil(EAR_RADIUS * 2 / self._m_per_px[EAR_HEIGHT])) + 2
        h, w = ears.shape
        r0, c0 = max(r0 - pad, 0), max(c0 - pad, 0)
        r1, c1 = min(r1 + pad, h), min(c1 + pad, w)
        occ = self._occluder[r0:r1, c0:c1] | masks["unsure"][r0:r1, c0:c1]
        world = self._grid_to_world(grid[r0:r1, c0:c1])
        red_w, blue_w = red[r0:r1, c0:c1], blue[r0:r1, c0:c1]
        if occ.any():
            centre = self._fit_ears(centre, lateral, red_w, blue_w, occ, world, self._ear_radius)
        step = self._m_per_px[EAR_HEIGHT]
        for span, n in ((1.0, 17), (0.15, 13)):
            centre = self._match_ears(centre, lateral, red_w, blue_w, occ, world, self._ear_radius,
                                      np.linspace(-span, span, n) * step)
        return centre

    @staticmethod
    def _match_ears(centre, lateral, red, blue, occ, world, radius, offsets):
        """Sub-pixel refinement: a pixel shows an ear when its centre is on
        the ear's disk of ``radius`` (the outline shrunk by the coverage
        inset); among candidate centres (``centre`` + a grid of ``offsets``)
        keep those whose silhouettes (nearer ear in front, walls hiding both)
        disagree with the observed ones on fewest pixels, and return their
        mean. Only pixels whose prediction can differ between candidates are
        compared: within the largest shift of an ear's outline or of the line
        between the ears (the others add the same count to every candidate)."""
        vis = ~occ
        pts = world[vis]                                   # (n, 2)
        shift = float(np.max(np.abs(offsets))) * np.sqrt(2.0) + 1e-9
        dr0 = np.linalg.norm(pts - (np.asarray(centre) + EAR_OFFSET * lateral), axis=1)
        db0 = np.linalg.norm(pts - (np.asarray(centre) - EAR_OFFSET * lateral), axis=1)
        near = ((np.abs(dr0 - radius) <= shift) | (np.abs(db0 - radius) <= shift)
                | (np.abs(dr0 - db0) <= 2 * shift))
        vis[vis] = near
        pts = pts[near]
        obs_r, obs_b = red[vis], blue[vis]
        dx, dy = np.meshgrid(offsets, offsets, indexing="ij")
        cands = np.asarray(centre)[None, :] + np.stack([dx.ravel(), dy.ravel()], 1)
        er = cands + EAR_OFFSET * lateral                  # (m, 2)
        eb = cands - EAR_OFFSET * lateral
        dr = ((pts[None, :, 0] - er[:, None, 0]) ** 2 + (pts[None, :, 1] - er[:, None, 1]) ** 2)
        db = ((pts[None, :, 0] - eb[:, None, 0]) ** 2 + (pts[None, :, 1] - eb[:, None, 1]) ** 2)
        r2 = radius ** 2
        pred_r = (dr <= r2) & (dr <= db)
        pred_b = (db <= r2) & (db < dr)
        miss = (pred_r != obs_r[None]).sum(1) + (pred_b != obs_b[None]).sum(1)
        best = cands[miss == miss.min()]
        return best.mean(axis=0)

    @staticmethod
    def _fit_ears(centre, lateral, red, blue, occ, world, radius):
        """Least-squares fit of the walker's centre to the ears' visible
        outlines: every ear pixel next to a pixel that is neither ear nor wall
        gives an edge point (the two pixels' midpoint) that lies on its ear's
        circle. Used when walls hide part of an ear (the centroid is then
        biased)."""
        points, signs = [], []
        for ear, other, sign in ((red, blue, 1.0), (blue, red, -1.0)):
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                inner = ear[max(-dr, 0):ear.shape[0] - max(dr, 0),
                            max(-dc, 0):ear.shape[1] - max(dc, 0)]
                sl = (slice(max(dr, 0), ear.shape[0] + min(dr, 0)),
                      slice(max(dc, 0), ear.shape[1] + min(dc, 0)))
                outer_ok = ~ear[sl] & ~other[sl] & ~occ[sl]
                hit = inner & outer_ok
                if not hit.any():
                    continue
                pin = world[max(-dr, 0):ear.shape[0] - max(dr, 0),
                            max(-dc, 0):ear.shape[1] - max(dc, 0)][hit]
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

    def _grid_to_world(self, g) -> np.ndarray:
        desc = self._desc
        height, width = desc.grid_shape
        g = np.asarray(g, float)
        x = (g[..., 1] - (width - 1) / 2) * desc.cell_size
        y = ((height - 1) / 2 - g[..., 0]) * desc.cell_size
        return np.stack([x, y], axis=-1)

    def _detect_boxes(self, frame, masks, walker_xy) -> list:
        """World (x, y) of every box seen."""
        desc = self._desc
        box = masks["box"] & self._box_allowed
        labels, n = ndimage.label(box)
        if n == 0:
            return []
        grid = self._grid[self._box_z]
        px = self._m_per_px[self._box_z] / desc.cell_size          # cells per pixel
        # box side (cells) as seen: pixels fully covered by the box's top
        side = 2 * desc.box_half / desc.cell_size - 2 * self._inset * px
        area1 = (side / px) ** 2                             # pixels per box
        objs = ndimage.find_objects(labels)
        walker_g = (None if walker_xy is None else desc.world_to_grid(np.asarray(walker_xy)))
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
                groups = self._split(g, count)
            for pts in groups:
                found.append(self._box_centre(pts, side, px, walker_g))
        return [self._grid_to_world(c) for c in found]

    @staticmethod
    def _split(points, k):
        """k-means (a few iterations) of pixel grid coordinates."""
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

    @staticmethod
    def _box_centre(pts, side, px, walker_g):
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

    def estimate(self, timestep) -> BallScene:
        """The scene of ``timestep``: from its frame when one is due (see
        `_frame_due`), predicted in between (see the module docstring)."""
        if self._desc is None or self._box_xy is None:
            raise EstimationError("estimate called before reset")
        obs = timestep.observation
        heading = heading_from_orientation(obs["walker/orientation"])
        velocity = np.asarray(world_velocity(obs["walker/orientation"],
                                             obs["walker/sensors_velocimeter"]), float)
        self._since += 1
        dt = self._dt
        if self._walker_xy is None:
            walker = None
        else:  # the velocimeter, integrated (trapezoid)
            walker = self._walker_xy + 0.5 * (self._velocity + velocity) * dt
        box_v = self._predict_box_velocity(walker, velocity)
        boxes = self._box_xy + box_v * dt
        if walker is None or self._frame_due(walker, boxes):
            locate = walker is None or self._walker_reads + 1 >= self.walker_every
            walker, boxes = self._from_frame(obs, timestep, None if locate else walker)
            self._walker_reads = 0 if locate else self._walker_reads + 1
            since = self._since
            if self._frame_boxes is not None and since:
                box_v = (boxes - self._frame_boxes) / (since * dt)
                box_v[np.linalg.norm(box_v, axis=1) < BOX_STILL] = 0.0
            self._frame_boxes = boxes
            self._since = 0
            self.frames_read += 1
        else:
            self.steps_predicted += 1
        state, box_cells = rounded_state(self._desc, self._walls, self._targets, boxes, walker,
                                         self._player)
        self._player = state.player
        self._box_xy, self._box_v = boxes, box_v
        self._walker_xy, self._velocity = np.asarray(walker, float), velocity
        return BallScene(state=state, walker_xy=self._walker_xy.copy(),
                         walker_velocity=velocity, heading=float(heading),
                         box_xy=boxes.copy(), box_cells=tuple(box_cells))

    def _frame_due(self, walker, boxes) -> bool:
        """Every ``frame_every``-th step; every ``near_every``-th while a box
        may move (the walker within `NEAR_BOX` of one, or one moving): boxes
        move only when pushed, and coast a few cm after."""
        if self._since >= self.frame_every:
            return True
        if self._since < self.near_every or not len(boxes):
            return False
        if np.any(self._box_v):
            return True
        return bool(np.abs(boxes - walker).max(axis=1).min() < NEAR_BOX)

    def _predict_box_velocity(self, walker, velocity) -> np.ndarray:
        """Box velocities for the step to come: a box the walker touches and
        rolls into moves with the walker along that axis; any other keeps its
        last velocity, slowed by the floor's friction (`BOX_DECEL`)."""
        box_v = self._box_v.copy()
        if not len(box_v):
            return box_v
        speed = np.linalg.norm(box_v, axis=1)
        moving = speed > 0
        box_v[moving] *= (np.maximum(speed[moving] - BOX_DECEL * self._dt, 0.0)
                          / speed[moving])[:, None]
        if walker is None:
            return box_v
        desc = self._desc
        contact = desc.box_half + desc.ball_radius
        gap = self._box_xy - walker
        for i, (dx, dy) in enumerate(gap):
            axis = 0 if abs(dx) >= abs(dy) else 1
            along, across = (dx, dy) if axis == 0 else (dy, dx)
            push = velocity[axis] * np.sign(along)
            if abs(along) < contact + CONTACT_SLACK and abs(across) < desc.box_half and push > 0:
                box_v[i, axis] = velocity[axis]
        return box_v

    def _from_frame(self, obs, timestep, walker=None):
        """(walker xy, boxes (k, 2) in the tracked order) from the frame; the
        walker is located in the frame unless given."""
        frame = np.asarray(obs[self._camera_key])
        if frame.shape[:2] != self._shape:
            raise EstimationError(f"frame shape {frame.shape[:2]} differs from reset's "
                                  f"{self._shape}")
        masks = _masks(frame, self._desc.looks)
        try:
            if walker is None:
                walker = self._find_walker(masks, timestep)
            boxes = self._detect_boxes(frame, masks, walker)
        except EstimationError:
            self._walker_xy = None  # look again at the next frame
            raise
        if len(boxes) != self._num_boxes:
            self._walker_xy = None
            raise EstimationError(f"{len(boxes)} boxes seen, expected {self._num_boxes}")
        boxes = np.asarray(boxes, float).reshape(-1, 2)
        if self._num_boxes:
            cost = np.sum((self._box_xy[:, None, :] - boxes[None, :, :]) ** 2, -1)
            rows, cols = linear_sum_assignment(cost)
            ordered = np.empty_like(boxes)
            ordered[rows] = boxes[cols]
            boxes = ordered
        return np.asarray(walker, float), boxes

    # convenience for tests and tools
    @property
    def walls(self) -> frozenset:
        return self._walls

    @property
    def targets(self) -> frozenset:
        return self._targets
