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

* targets (pads) and walls, by their colours and textures
  (`hier_agents.estimators.camera_grid`: the grid's outer ring is walls, and
  a cell is a wall when its colour distribution matches a ring cell's).
  Walls and targets are static: read once per episode.
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
  grid of candidate centres, keeping the mean of the best
  (`hier_agents.estimators.camera_ears`).
* boxes: connected components of box-coloured pixels inside non-wall cells;
  a component holding several touching boxes (by area) is split by k-means.
  A box is an axis-aligned 0.8-cell square that never turns: along each axis
  the first and last box pixel bound each edge within a pixel and the known
  side length narrows the centre to their intersection (the frame size,
  199 px, makes the side 14.5 px, which halves that interval); an edge
  beyond which the frame may hide the box (the walls' safety band, an ear,
  unsure colours; else, for a blob too short, the side nearer the walker)
  bounds the centre from one side only, and an adjacent wall from the other
  (`hier_agents.estimators.camera_boxes`). Boxes keep their order
  (optimal assignment to the previous positions).
* heading and velocity: proprioception (`skills.scene.heading_from_orientation`,
  `skills.scene.world_velocity`).
* abstract state: `rounded_state` (the paper's rounding rule), remembering the
  previous player cell (call ``estimate`` every step, as the task rounds
  every step).

Its camera (``env_overrides``): the top camera at `FRAME_SHAPE`, one sample
per pixel (``multisamples=0``: its own sensor setting; frames the
environment's original multisampling draws are read too, as on the original
environment), rendered only when read (``lazy_cameras=True``).

Frame schedule (``estimate``): rendering and reading a frame costs about
twice the physics of a level-5 step (``benchmarks/agent_speed.py``), so the
estimator reads a frame every ``frame_every`` (3) steps, every
``near_every`` (2) while the walker is within `NEAR_BOX` of a box or a box
moves, and locates the walker in every ``walker_every`` (2)-th frame read.
In between it predicts: the walker by integrating its
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
from scipy.optimize import linear_sum_assignment

from envs.description import MujobanDescription
from hier_agents.estimators.base import EstimationError, Estimator
from hier_agents.estimators.camera_boxes import find_boxes
from hier_agents.estimators.camera_ears import (
    EAR_HEIGHT,
    EAR_OFFSET,  # noqa: F401
    EAR_RADIUS,  # noqa: F401
    locate_walker,
)
from hier_agents.estimators.camera_grid import (
    QUANTILES as _QUANTILES,  # noqa: F401
    WALL_MATCH,  # noqa: F401
    cell_pixel_index,
    grid_to_world,
    read_targets,
    read_walls,
    wall_footprint,
)
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

#: Wall tops (m) above the floor.
WALL_HEIGHT = 1.0


class CameraEstimator(Estimator):
    """The scene from the top camera's frames and proprioception. See the
    module docstring for the method, its assumptions, accuracy and cost."""

    name = "camera"
    privileged = False
    #: Its camera (see the module docstring): `FRAME_SHAPE`, no
    #: multisampling, rendered only when it reads a frame.
    env_overrides = {"top_camera": FRAME_SHAPE, "multisamples": 0, "lazy_cameras": True}

    def __init__(
        self,
        camera: str = "top_camera",
        frame_every: int = FRAME_EVERY,
        near_every: int = NEAR_EVERY,
        walker_every: int = WALKER_EVERY,
    ) -> None:
        for label, value in (
            ("frame_every", frame_every),
            ("near_every", near_every),
            ("walker_every", walker_every),
        ):
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{label} must be an integer >= 1, got {value!r}")
        self._camera_key = camera
        self.frame_every = frame_every
        self.near_every = min(near_every, frame_every)
        self.walker_every = walker_every
        self._desc: MujobanDescription | None = None
        #: Frames looked at and steps predicted since construction (for benchmarks).
        self.frames_read = 0
        self.steps_predicted = 0

    #: The frame shape (rows, cols) of the geometry (set with ``_desc``).
    _shape: tuple[int, ...]

    @property
    def _description(self) -> MujobanDescription:
        """The description of the last `reset` (the methods using it run after one)."""
        assert self._desc is not None, "used before reset"
        return self._desc

    # -- geometry ---------------------------------------------------------

    def _setup_geometry(self, description, shape) -> None:
        if description.looks is None:
            raise EstimationError(
                "the task description names no looks (object colours and "
                "light): the camera estimator needs them"
            )
        if self._desc == description and self._shape == shape:
            return
        self._desc, self._shape = description, shape
        self._sig_index = None
        cam = description.top_camera
        h, w = shape
        rows, cols = np.mgrid[0:h, 0:w]
        pix = np.stack([rows + 0.5, cols + 0.5], axis=-1).reshape(-1, 2)
        self._grid = {}
        self._box_z = 2.0 * float(description.box_half_height)  # box tops
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
        masks = _masks(frame, self._description.looks)
        self._walls, self._targets = self._read_static(frame, masks)
        wall_grid = np.zeros((height, width), bool)
        for r, c in self._walls:
            wall_grid[r, c] = True
        self._wall_grid = wall_grid
        self._precompute_masks()
        self._num_boxes: int | None = None
        self._box_xy: np.ndarray | None = None
        self._player: tuple[int, int] | None = None
        boxes = self._detect_boxes(frame, masks, self._walker_guess(masks, timestep))
        if len(boxes) != len(self._targets):
            raise EstimationError(
                f"reset: {len(boxes)} boxes seen but {len(self._targets)} target pads"
            )
        cells = [description.world_to_cell(xy) for xy in boxes]
        order = sorted(range(len(boxes)), key=lambda i: cells[i])
        self._num_boxes = len(boxes)
        self._box_xy = np.asarray(boxes, float)[order].reshape(-1, 2)
        self._dt = float(description.control_timestep)
        self._since = 0  # steps since the last frame read
        # The last estimate (frame or prediction), with its velocity.
        self._walker_xy: np.ndarray | None = None
        self._velocity: np.ndarray | None = None
        self._box_v = np.zeros_like(self._box_xy)
        self._frame_boxes: np.ndarray | None = None  # boxes at the last frame read
        self._walker_reads = 0  # frames read since the walker was last located

    def _read_static(self, frame, masks):
        """(walls, targets): frozensets of (row, col) cells read from the
        reset frame (`hier_agents.estimators.camera_grid`)."""
        shape = self._description.grid_shape
        # Pads (z = 0). A box's top in its on-a-pad colour shows a pad under
        # it too (with multisampling the covered pad's ring is ~1 pixel wide).
        targets = read_targets(
            masks["pad"] | masks["box_on_pad"], self._cell_index(0.0, margin=0.05), shape
        )
        # Walls: per-cell colour distributions at wall-top height.
        if self._sig_index is None:
            self._sig_index = cell_pixel_index(self._cell_index(WALL_HEIGHT, margin=0.05), shape)
        return read_walls(frame, self._sig_index, targets, shape), targets

    def _precompute_masks(self) -> None:
        """Pixel masks of the wall footprint: the cells whose walls hide the
        ears (z 0.34..0.86 m) and a safety band around walls for boxes."""
        height, width = self._description.grid_shape
        g0 = self._grid[0.0]
        outside = (
            (g0[..., 0] < -0.5)
            | (g0[..., 0] > height - 0.5)
            | (g0[..., 1] < -0.5)
            | (g0[..., 1] > width - 0.5)
        )
        walls = self._wall_grid
        self._occluder = wall_footprint(self._grid[WALL_HEIGHT], walls) | wall_footprint(
            self._grid[EAR_HEIGHT], walls
        )
        # Box pixels must lie (at box height) in a non-wall cell, away from
        # the walls' footprint by a small band.
        self._box_allowed = ~(
            wall_footprint(self._grid[self._box_z], walls, margin=0.04)
            | wall_footprint(self._grid[WALL_HEIGHT], walls, margin=0.04)
            | outside
        )
        self._box_hidden = ~self._box_allowed

    # -- per frame ----------------------------------------------------------

    def _walker_guess(self, masks, timestep):
        try:
            return self._find_walker(masks, timestep)
        except EstimationError:
            return None

    def _find_walker(self, masks, timestep) -> np.ndarray:
        """World (x, y) of the walker from its ears' silhouettes
        (`hier_agents.estimators.camera_ears.locate_walker`)."""
        heading = heading_from_orientation(timestep.observation["walker/orientation"])
        return locate_walker(
            masks["red_ear"],
            masks["blue_ear"],
            self._occluder | masks["unsure"],
            self._grid[EAR_HEIGHT],
            self._m_per_px[EAR_HEIGHT],
            heading,
            self._ear_radius,
            self._grid_to_world,
        )

    def _grid_to_world(self, g) -> np.ndarray:
        return grid_to_world(self._description, g)

    def _detect_boxes(self, frame, masks, walker_xy) -> list:
        """World (x, y) of every box seen."""
        desc = self._description
        px = self._m_per_px[self._box_z] / desc.cell_size  # cells per pixel
        # box side (cells) as seen: pixels fully covered by the box's top
        side = 2 * desc.box_half / desc.cell_size - 2 * self._inset * px
        walker_g = None if walker_xy is None else desc.world_to_grid(np.asarray(walker_xy))
        # What may hide a box's edge: where boxes are not looked for, ears, unsure colours.
        hiding = self._box_hidden | masks["unsure"] | masks["red_ear"] | masks["blue_ear"]
        found = find_boxes(
            masks["box"] & self._box_allowed,
            self._grid[self._box_z],
            side,
            px,
            walker_g,
            hiding,
            self._wall_grid,
            desc.box_half / desc.cell_size,
        )
        return [self._grid_to_world(c) for c in found]

    def estimate(self, timestep) -> BallScene:
        """The scene of ``timestep``: from its frame when one is due (see
        `_frame_due`), predicted in between (see the module docstring)."""
        if self._desc is None or self._box_xy is None:
            raise EstimationError("estimate called before reset")
        obs = timestep.observation
        heading = heading_from_orientation(obs["walker/orientation"])
        velocity = np.asarray(
            world_velocity(obs["walker/orientation"], obs["walker/sensors_velocimeter"]), float
        )
        self._since += 1
        dt = self._dt
        if self._walker_xy is None:
            walker = None
        else:  # the velocimeter, integrated (trapezoid)
            assert self._velocity is not None  # set with every walker estimate
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
        state, box_cells = rounded_state(
            self._desc, self._walls, self._targets, boxes, walker, self._player
        )
        self._player = state.player
        self._box_xy, self._box_v = boxes, box_v
        self._walker_xy, self._velocity = np.asarray(walker, float), velocity
        return BallScene(
            state=state,
            walker_xy=self._walker_xy.copy(),
            walker_velocity=velocity,
            heading=float(heading),
            box_xy=boxes.copy(),
            box_cells=tuple(box_cells),
        )

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
        box_v[moving] *= (np.maximum(speed[moving] - BOX_DECEL * self._dt, 0.0) / speed[moving])[
            :, None
        ]
        if walker is None:
            return box_v
        desc = self._description
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
            raise EstimationError(
                f"frame shape {frame.shape[:2]} differs from reset's {self._shape}"
            )
        masks = _masks(frame, self._description.looks)
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
