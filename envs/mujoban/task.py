"""The MuJoBan task: Sokoban played by a rolling ball in a 3D maze.

Rules and physics are those of the original implementation
(physics_planning_games' ``mujoban``), with the paper's 0.05 s control step
(Mirza et al. 2020, section "MuJoBan" and appendix):

* reward +1 at the control step a box comes to cover a target pad, -1 when a
  box leaves one, 0 otherwise; when every pad is covered the episode ends and
  that step's reward additionally carries a +10 bonus (so it is 11 when the
  last box arrives, the +1 shaping for that box plus the bonus);
* a pad counts as covered while some box centre lies within ``pad_tolerance``
  (default 0.1 cells) of the pad centre along both axes; the pad turns green.
  The default is the original's rule: a full-cell pad (half-size 0.5) is
  activated by a box (half-size 0.4) lying entirely on it, with detection
  tolerance 0, i.e. within 0.5 - 0.4 = 0.1 m;
* boxes (half-size 0.4 x 0.4, half-height 0.15 m, 2.5 kg) slide on three
  slide joints without rotating, on floor friction 0.5 (a box-floor contact
  pair, ``condim=6``); the walker meets them, walls and pegs with friction 1;
* physics steps of 1 ms, 50 per control step of 0.05 s, with the solver
  options of composer's base arena (elliptic cones, 5 noslip iterations);
  episodes last 45 s
  (900 control steps), then truncation (discount 1);
* the episode terminates (discount 0) when solved, or when the walker's
  ``aliveness`` drops below -0.5 (the original's rule; the rolling ball's
  aliveness is always 0, so for it only solving ends an episode early);
* the walker starts in the level's player cell with a heading drawn
  uniformly in [-pi, pi);
* the abstract state (``full_entity_layer``) rounds every box to its nearest
  cell first, then the walker; if the walker's cell holds a box, the walker
  keeps its previous cell (the paper's appendix).

Pads are evaluated once per control step, after its last physics substep. The
original updates pad activation after every substep, but its rewards, its
solved test and its termination read only the activation left by the last
substep (its ``after_step`` and ``get_reward``), so checking at the end of
the control step gives the same rewards, discounts and episode ends.

One default deviates from the original: MuJoCo sleeps resting bodies
(``sleep=True``: 4-5x cheaper physics on Boxoban levels, the bodies'
behaviour within 1% of the original's, `envs.mujoban.behaviour`);
``sleep=False`` (`envs.original_options`) is the original's. Other
deviations are explicit options of `Mujoban` (and of `envs.mujoban.make`):
``physics_timestep=0.005`` (5x cheaper physics, the value used before this
package followed the original), ``pad_tolerance=0.3`` (a more lenient pad),
``noslip_iterations=0`` (no noslip solver: about 2x faster on level 5),
``control_timestep``.
"""

from __future__ import annotations

import numbers
from typing import Callable, Mapping

import numpy as np
from dm_control.locomotion.walkers import jumping_ball
from dm_env import specs

from envs.core import PhysicsTask
from envs.mujoban import arena as arena_lib
from envs.mujoban.levels import Level, LevelError  # noqa: F401  (LevelError: re-export)
from envs.mujoban.props import BOX_FLOOR_FRICTION, Box

# The task's parts by concern; their public names stay importable from here.
from envs.mujoban.task_layout import _PARKED_Z, LayoutMixin  # noqa: F401
from envs.mujoban.task_looks import (
    _TEXROLE_RGB,  # noqa: F401
    BALL_RADIUS,  # noqa: F401
    EAR_RGBA,  # noqa: F401
    LooksMixin,
)
from envs.mujoban.task_observations import (
    _CHANNEL_WEIGHTS,  # noqa: F401
    _COLOUR_TABLE,  # noqa: F401
    BOX,  # noqa: F401
    ENTITY_CHANNELS,  # noqa: F401
    PIXEL_COLOURS,  # noqa: F401
    PLAYER,  # noqa: F401
    TARGET,  # noqa: F401
    WALL,  # noqa: F401
    ObservationsMixin,
    _as_slice,  # noqa: F401
    _build_colour_table,  # noqa: F401
    entity_layer_to_pixels,  # noqa: F401
)
from envs.rendering import CameraConfig

LevelSource = Callable[[np.random.Generator], Level]

#: Aliveness in [-1, 0] below which the walker counts as dead (the original's
#: ``_ALIVE_THRESHOLD``).
ALIVE_THRESHOLD = -0.5
#: Damping (N s/m) of the joints of a box the level does not use: it stays
#: parked in the air outside the arena (sinking ~1 mm per episode under
#: MuJoCo's implicit damping) instead of resting on the floor, which would
#: cost contacts.
_PARKED_DAMPING = 1e6


def _check_task_options(
    level_source, grid_shape, max_boxes, pad_tolerance, time_limit, sleep, noslip_iterations
) -> tuple[int, ...]:
    """Checks `Mujoban`'s options (TypeError or ValueError naming the bad
    one) and returns ``grid_shape`` as a tuple of ints."""
    if not callable(level_source):
        raise TypeError("level_source must be callable as level_source(rng) -> Level")
    grid_shape = tuple(int(v) for v in grid_shape)
    if len(grid_shape) != 2 or min(grid_shape) < 3:
        raise ValueError(f"grid_shape must be (rows, cols) with both >= 3, got {grid_shape}")
    if int(max_boxes) < 1:
        raise ValueError(f"max_boxes must be >= 1, got {max_boxes}")
    if not 0 < pad_tolerance <= 0.5:
        raise ValueError(f"pad_tolerance must be in (0, 0.5] cells, got {pad_tolerance}")
    if time_limit <= 0:
        raise ValueError(f"time_limit must be positive seconds, got {time_limit}")
    if not isinstance(sleep, bool):
        raise TypeError(f"sleep must be True or False, got {sleep!r}")
    if (
        not isinstance(noslip_iterations, numbers.Integral)
        or isinstance(noslip_iterations, bool)
        or noslip_iterations < 0
    ):
        raise ValueError(f"noslip_iterations must be an integer >= 0, got {noslip_iterations!r}")
    return grid_shape


class Mujoban(ObservationsMixin, LooksMixin, LayoutMixin, PhysicsTask):
    """MuJoBan as a composer task.

    Observations and state accessors come from `ObservationsMixin`
    (`envs.mujoban.task_observations`), the description, textures and pad
    colours from `LooksMixin` (`envs.mujoban.task_looks`), level loading from
    `LayoutMixin` (`envs.mujoban.task_layout`); the rules (pads, reward,
    termination) and the composer hooks are here.

    Args:
      level_source: called with the environment's random generator at every
        reset; returns the next `Level`. See `envs.mujoban.sources`.
      grid_shape: arena capacity in cells; smaller levels are padded with walls
        (centred), larger ones raise `LevelError`.
      max_boxes: how many boxes (and pads) the arena holds.
      pegs: add pegs at every interior grid intersection (block diagonal box
        motion, and block the walker too, as in the original).
      top_camera: ``(height, width)`` of the top-down RGB camera, or None.
      egocentric_camera: ``(height, width)`` of the walker's camera, or None.
      randomize_appearance: draw the wall and floor textures every episode
        (labmaze ``style_01``, as the original); False keeps the first of each.
      control_timestep, physics_timestep, time_limit: seconds. The
        defaults are the paper's 0.05 s control step and the original's 1 ms
        physics step; ``physics_timestep=0.005`` is the cheaper deviation.
      pad_tolerance: how far (in cells, along both axes) a box centre may be
        from a pad centre to cover it. Default 0.1, the original's; 0.3 is
        the more lenient deviation.
      noslip_iterations: MuJoCo noslip solver iterations; default 5, the
        original's (dm_control composer's base arena). ``0`` is the cheaper
        deviation (about 2x faster on level 5, contacts may slip slightly).
      sleep: MuJoCo's sleeping of resting bodies (on by default, a deviation
        from the original, which has it off): boxes and the walker at rest
        stop being simulated until something touches them; 4-5x cheaper
        physics on Boxoban levels, the bodies' behaviour within 1% of the
        original's (`envs.mujoban.behaviour`).
      multisamples: samples per pixel of rendered frames (the original's 4;
        0 is cheaper, outlines move by up to a pixel).
      wall_slabs: size of the pool of render-only wall rectangles (levels
        needing more are drawn cell by cell).
      walker: a locomotion walker to use instead of the rolling ball (advanced;
        must expose ``create_root_joints`` and an egocentric camera).
      render_size: largest ``(height, width)`` of `Environment.render` frames,
        and their default size.
    """

    #: The abstract state the simulator's rounded cells give (the paper's
    #: agents observe cameras and proprioception only).
    privileged_observations = frozenset({"full_entity_layer", "pixel_layer"})
    state_observations = ("full_entity_layer",)
    #: The reward and the success rule in a sentence each (the module
    #: docstring has the details; the environment gallery's cards show these).
    reward_rule = (
        "+1 at the control step a box comes to cover a target pad, -1 when a box "
        "leaves one, 0 otherwise; +10 more at the step every pad is covered."
    )
    success_rule = (
        "Solved when every pad is covered by a box: the episode then terminates "
        "(discount 0). It also terminates if the walker dies (never for the "
        "rolling ball); at the time limit it is truncated (discount 1), unsolved."
    )

    def __init__(
        self,
        level_source: LevelSource,
        *,
        grid_shape=(10, 10),
        max_boxes=4,
        pegs=False,
        top_camera=(96, 96),
        egocentric_camera=(96, 96),
        randomize_appearance=True,
        control_timestep=0.05,
        physics_timestep=0.001,
        time_limit=45.0,
        pad_tolerance=0.1,
        cell_size=1.0,
        render_size=(256, 256),
        wall_slabs=32,
        walker=None,
        noslip_iterations=5,
        sleep=arena_lib.SLEEP,
        multisamples=arena_lib.MULTISAMPLES,
    ):
        grid_shape = _check_task_options(
            level_source, grid_shape, max_boxes, pad_tolerance, time_limit, sleep, noslip_iterations
        )
        self._level_source = level_source
        self._randomize_appearance = bool(randomize_appearance)
        self._pad_tolerance = float(pad_tolerance) * cell_size
        self.render_size = tuple(int(v) for v in render_size)

        sizes = [tuple(s) for s in (top_camera, egocentric_camera, render_size) if s]
        offscreen = (max(s[0] for s in sizes), max(s[1] for s in sizes))
        self._arena = arena_lib.MujobanArena(
            grid_shape=grid_shape,
            max_boxes=max_boxes,
            cell_size=cell_size,
            pegs=pegs,
            offscreen_size=offscreen,
            wall_slabs=wall_slabs,
            noslip_iterations=noslip_iterations,
            sleep=sleep,
            multisamples=multisamples,
        )
        self._walker = walker or jumping_ball.RollingBallWithHead(
            name="walker", add_ears=True, camera_height=0.25
        )
        self._add_walker_touch_sensor()
        self._walker.create_root_joints(self._arena.attach(self._walker))

        self._boxes: list[Box] = []
        self._box_joints: list[list] = []  # each box's x, y and z slide joints
        for i in range(max_boxes):
            self._add_box(i)

        self._cameras: dict[str, CameraConfig] = {}
        if top_camera:
            self._cameras["top_camera"] = CameraConfig("top_camera", *top_camera)
        if egocentric_camera:
            self._cameras["walker/egocentric_camera"] = CameraConfig(
                self._walker.egocentric_camera.full_identifier, *egocentric_camera
            )

        self.set_timesteps(control_timestep=control_timestep, physics_timestep=physics_timestep)
        self.time_limit_steps = int(round(time_limit / control_timestep))
        self.level: Level | None = None

    def _add_box(self, i: int) -> None:
        """Attaches box ``i``: three slide joints (x, y, z) without friction
        loss, damping or armature, resting on the floor at qpos z = 0, and a
        box-floor contact pair with `BOX_FLOOR_FRICTION`."""
        sliding, torsional, rolling = BOX_FLOOR_FRICTION
        box = Box(name=f"box_{i}")
        frame = self._arena.attach(box)
        frame.pos = (0, 0, box.half_height)  # resting on the floor at qpos z = 0
        joints = [
            frame.add(
                "joint",
                name=f"box_{i}_{axis}",
                type="slide",
                axis=vec,
                frictionloss=0.0,
                damping=0.0,
                armature=0.0,
            )
            for axis, vec in (("x", (1, 0, 0)), ("y", (0, 1, 0)), ("z", (0, 0, 1)))
        ]
        self._arena.mjcf_model.contact.add(
            "pair",
            name=f"box_{i}_floor",
            geom1=box.geom,
            geom2=self._arena.floor,
            condim=6,
            friction=(sliding, sliding, torsional, rolling, rolling),
        )
        self._boxes.append(box)
        self._box_joints.append(joints)

    # -- parts and sizes ----------------------------------------------------

    @property
    def root_entity(self):
        return self._arena

    @property
    def arena(self) -> arena_lib.MujobanArena:
        return self._arena

    @property
    def walker(self):
        return self._walker

    @property
    def boxes(self) -> list[Box]:
        return self._boxes

    @property
    def camera_configs(self) -> Mapping[str, CameraConfig]:
        return self._cameras

    @property
    def grid_shape(self) -> tuple[int, int]:
        return self._arena.grid_shape

    @property
    def cell_size(self) -> float:
        return self._arena.cell_size

    # -- composer hooks -----------------------------------------------------

    def after_compile(self, physics, random_state) -> None:
        bind = physics.bind
        arena = self._arena
        self._model = physics.model.ptr
        self._data = physics.data.ptr
        height, width = arena.grid_shape
        self._wall_ids = np.array([[bind(g).element_id for g in row] for row in arena.wall_cells])
        self._slab_ids = np.array([bind(g).element_id for g in arena.wall_slabs])
        self._pad_ids = np.array([bind(g).element_id for g in arena.pads])
        self._floor_mat = bind(arena.floor_material).element_id
        self._wall_mats = np.array(
            [bind(m).element_id for m in [arena.wall_cell_material, *arena.slab_materials]]
        )
        self._slab_mats = self._wall_mats[1:]
        self._floor_tex_ids = [bind(t).element_id for t in arena.floor_textures]
        self._wall_tex_ids = [bind(t).element_id for t in arena.wall_textures]
        self._box_geom_ids = np.array([bind(b.geom).element_id for b in self._boxes])
        box_qpos = np.array([[bind(j).qposadr for j in js] for js in self._box_joints])
        box_dof = np.array([[bind(j).dofadr for j in js] for js in self._box_joints])
        box_qpos = box_qpos.reshape(len(self._boxes), 3)
        box_dof = box_dof.reshape(len(self._boxes), 3)
        self._box_qpos, self._box_dof = box_qpos[:, :2], box_dof[:, :2]  # x, y
        self._box_z_qpos, self._box_all_dof = box_qpos[:, 2], box_dof

        self._bind_walker(bind)
        self._box_qpos_list = [tuple(map(int, row)) for row in self._box_qpos]
        self._active_box_qpos = []
        self._box_reference = []
        # Views of MjData's arrays (mj_resetData keeps the buffers), so the
        # per-step code skips the attribute lookups.
        d = self._data
        self._qpos, self._qvel, self._qfrc_actuator = d.qpos, d.qvel, d.qfrc_actuator
        self._xpos, self._xmat, self._sensordata, self._ctrl = d.xpos, d.xmat, d.sensordata, d.ctrl
        # Constants of world -> cell rounding, for the per-step estimate.
        self._rounding = (
            1.0 / self.cell_size,
            (width - 1) / 2,
            (height - 1) / 2,
            height - 1,
            width - 1,
        )
        self._static_layer = np.zeros((height, width, 4), bool)
        self._targets: list[tuple[int, int]] = []
        self._target_xy: list[tuple[float, float]] = []
        self._player_cell = (0, 0)
        self._box_cells: tuple[tuple[int, int], ...] = ()
        self._covered: tuple[bool, ...] = ()
        self._set_layers((), (0, 0))
        self._num_boxes = 0
        self._reward = 0.0
        self._solved = False
        self._fell = False

    def initialize_episode(self, physics, random_state):
        level = self._level_source(random_state)
        if not isinstance(level, Level):
            raise TypeError(f"level_source returned {type(level).__name__}, expected Level")
        self._set_level(level)
        if self._randomize_appearance:
            self._draw_appearance(random_state)
        m, d = self._model, self._data
        d.qpos[self._walker_joint_qpos] = 0.0
        px, py = self._arena.cell_centre(*self.level.player)
        d.qpos[self._walker_root_qpos[0]], d.qpos[self._walker_root_qpos[1]] = px, py
        d.qpos[self._steer_qpos] = random_state.uniform(-np.pi, np.pi)
        for i in range(len(self._boxes)):
            if i < self._num_boxes:
                r, c = self._initial_box_cells[i]
                d.qpos[self._box_qpos[i]] = self._arena.cell_centre(r, c)
                d.qpos[self._box_z_qpos[i]] = 0.0
                m.dof_damping[self._box_all_dof[i]] = 0.0
                m.geom_group[self._box_geom_ids[i]] = 0
            else:  # parked in the air far outside the arena, undrawn
                d.qpos[self._box_qpos[i]] = (1000.0 + 10 * i, 1000.0)
                d.qpos[self._box_z_qpos[i]] = 10.0
                m.dof_damping[self._box_all_dof[i]] = _PARKED_DAMPING
                m.geom_group[self._box_geom_ids[i]] = arena_lib.HIDDEN_GROUP
        self._box_reference = self._box_xy()
        self._covered = self._pads_covered(self._box_reference)
        self._paint_pads()
        self._set_layers(self._box_cells, self.level.player)
        self._reward = 0.0
        self._solved = False
        self._fell = False

    def on_seed(self, episode: int = 0) -> None:
        restart = getattr(self._level_source, "restart", None)
        if restart is not None:
            restart(episode)

    def before_step(self, physics, action, random_state):
        self._ctrl[self._act_ids] = action

    def after_step(self, physics, random_state):
        # Runs every control step, right after MuJoCo has filled the caches
        # with its own data: plain Python on a handful of floats, one read of
        # qpos, and arrays rebuilt only when the abstract state changes.
        q = self._qpos.tolist()
        entered = left = 0
        box_cells = self._box_cells
        inv, cx, cy, rmax, cmax = self._rounding
        # Resting boxes creep by tiny amounts under soft contacts; pads and box
        # cells are only re-evaluated once a box has moved 0.1 mm (a box that
        # creeps 0.1 mm in all is then re-evaluated: nothing is missed).
        moved = False
        for (ix, iy), (ox, oy) in zip(self._active_box_qpos, self._box_reference):
            if abs(q[ix] - ox) > 1e-4 or abs(q[iy] - oy) > 1e-4:
                moved = True
                break
        if moved:
            boxes = [(q[ix], q[iy]) for ix, iy in self._active_box_qpos]
            self._box_reference = boxes
            covered = self._pads_covered(boxes)
            previous = self._covered
            if covered != previous:
                entered = sum(now and not before for now, before in zip(covered, previous))
                left = sum(before and not now for now, before in zip(covered, previous))
                self._covered = covered
            if covered != previous or any(covered):  # the covering box may change
                self._paint_pads()
            # The paper's estimate: boxes first, then the walker unless it overlaps a box.
            box_cells = tuple(
                (min(max(round(cy - y * inv), 0), rmax), min(max(round(x * inv + cx), 0), cmax))
                for x, y in boxes
            )
        self._solved = all(self._covered)
        self._reward = float(entered - left) + (10.0 if self._solved else 0.0)

        rx, ry = self._walker_root_qpos[:2]
        hx, hy = q[rx], q[ry]  # the root slides move the head body
        player = (min(max(round(cy - hy * inv), 0), rmax), min(max(round(hx * inv + cx), 0), cmax))
        if player in box_cells:
            player = self._player_cell
        if box_cells != self._box_cells or player != self._player_cell:
            self._set_layers(box_cells, player)
        if self._aliveness is not None:
            self._fell = bool(self._aliveness(physics) < ALIVE_THRESHOLD)

    def get_reward(self, physics):
        return self._reward

    def should_terminate_episode(self, physics):
        return self._solved or self._fell

    def get_discount(self, physics):
        return 0.0 if (self._solved or self._fell) else 1.0

    def action_spec(self, physics):
        ranges = self._model.actuator_ctrlrange[self._act_ids]
        names = ",".join(a.name for a in self._walker.actuators)
        return specs.BoundedArray(
            (len(self._act_ids),), np.float64, ranges[:, 0], ranges[:, 1], name=names
        )

    # -- rules: state of the pads ------------------------------------------

    @property
    def solved(self) -> bool:
        return self._solved

    @property
    def succeeded(self) -> bool:
        """Every pad covered (the level solved)."""
        return self._solved

    @property
    def pad_tolerance(self) -> float:
        """Cells (along both axes) a box centre may be from a pad centre to cover it."""
        return self._pad_tolerance / self.cell_size

    def set_box_position(self, physics, index: int, xy) -> None:
        """Moves box `index` to world `xy` at rest (for tests and disturbances)."""
        if not 0 <= index < self._num_boxes:
            raise IndexError(f"box index {index} out of range for {self._num_boxes} boxes")
        self._data.qpos[self._box_qpos[index]] = xy
        self._data.qvel[self._box_all_dof[index]] = 0.0
        physics.forward()

    # -- internals ----------------------------------------------------------

    def _box_xy(self) -> list[tuple[float, float]]:
        qpos = self._qpos.tolist()
        return [(qpos[ix], qpos[iy]) for ix, iy in self._active_box_qpos]

    def _pads_covered(self, boxes) -> tuple[bool, ...]:
        tol = self._pad_tolerance
        return tuple(
            any(abs(tx - bx) <= tol and abs(ty - by) <= tol for bx, by in boxes)
            for tx, ty in self._target_xy
        )
