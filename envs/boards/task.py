"""Board games played by touching a board with a 9-DoF Jaco arm (MuJoXO, MuJoGo).

By default this is the original task (Mirza et al. 2020, DeepMind's
``physics_planning_games.board_games``). The agent controls dm_control's
Kinova Jaco arm (6 joints) and three-finger hand (3 joints) with velocity
actuators: the action is 9 joint-velocity targets. The arena is
`envs.boards.arena` (the original world frame: board at the origin, arm base
at (0, 0.4, 0)).

**Registration.** Every physics substep the original reads the board's touch
sensors (threshold 1e-3 N) and, until a move has registered in the current
control step, takes the most strongly pressed square as the touched point
(Go: the pass sensor first, if it is pressed harder than every square and
above the threshold). MuJoGo additionally requires a finger geom (any hand
geom named ``finger*``: knuckles and tips) to be in contact with that
square's geom (or the pass geom). A legal move is played; an illegal one
changes nothing; in Go the agent cannot pass twice in a row (the second pass
is ignored). The agent's piece appears where the square was touched (its
first contact), the opponent (an `abstract_planners` planner) replies at
once, its piece landing at the sensor's centre plus uniform jitter (tic-tac-
toe: up to the sensor's half-size; Go: a quarter of it).

Our runner steps all substeps in one ``mj_step`` call, so the sensors keep
every substep's reading in MuJoCo's sensor history (``nsample`` = substeps
per control step): touch sensors for the pressures, ``contact`` sensors
(data ``found``) between each square and each finger's subtree for the
finger rule, and ``contact`` sensors (``found pos``) for where a square was
touched. `after_step` finds, vectorised over the recorded substeps, the
first substep in which a legal move registers, exactly as the per-substep
loop would. The one difference: the opponent's reply and the arm reset
happen after the control step's last substep instead of right after the
registering substep.

**Arm reset.** At episode start and after every registered move (unless
``arm_reset=False``) the arm is put, as by dm_control's
``ToolCenterPointInitializer``, with its tool centre point (the hand's grip
site) at a uniform random position in the box (-0.1..0.1, -0.1..0.1,
0.2..0.4) pointing down with a uniform random yaw in (-pi, pi), by IK (mink);
poses whose arm collides with itself or the board are rejected (10 tries).
The fingers and the joint velocities are left as they are.

Rewards are given at the end of the game: 1 for a win, 0 for a loss, the
game's draw reward for a draw (MuJoXO 0.5). The episode terminates (discount
0) when the game ends. At the time limit MuJoXO truncates (discount 1); in
MuJoGo a game still running is a loss (reward 0, discount 0).
"""

from __future__ import annotations

import math
import re

import mink
import mujoco
import numpy as np
from dm_control.entities.manipulators import kinova
from dm_env import specs

from abstract_planners.base import Planner
from envs.boards import arena as arena_lib
from envs.boards.games import AGENT, BoardGame
from envs.core import PhysicsTask
from envs.rendering import CameraConfig

#: A known-good arm posture with the hand above the board pointing down; the
#: IK for random poses starts from it and is regularised towards it.
HOME_ARM_QPOS = np.array([4.38, 3.89, 2.13, 5.79, 1.64, 3.89])
#: Orientation of a Jaco site pointing straight down (w, x, y, z), as
#: dm_control's ``manipulators.base.DOWN_QUATERNION``.
DOWN_QUAT = np.array([0.0, 0.70710678118, 0.70710678118, 0.0])
#: The original's box of tool-centre-point positions for the arm reset.
TCP_LOW = np.array([-0.1, -0.1, 0.2])
TCP_HIGH = np.array([0.1, 0.1, 0.4])
#: Piece jitter as a fraction of the sensor's half-size (the original's).
PIECE_NOISE = {"tic_tac_toe": 1.0, "go": 0.25}
_REJECTION_SAMPLES = 10


def _quat_mul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


class BoardTask(PhysicsTask):
    """A two-player board game against a planner, played with a Jaco arm.

    Args:
      game: the `BoardGame` (tic-tac-toe or Go of some size).
      opponent: planner for the second player (gets OpenSpiel states).
      registering: which geoms register a move: ``"arm"`` (any contact on the
        board; MuJoXO), ``"fingers"`` (a finger geom, knuckle or tip, must
        touch the square; MuJoGo) or ``"fingertips"`` (only the tips).
      arm_reset: reset the arm to a random pose after every registered move.
      front_camera: ``(height, width)`` of the RGB camera facing the arm, or None.
      time_limit: seconds; `timeout_is_loss` makes the last step terminal.
      piece_noise: the opponent's pieces land uniformly within this fraction
        of the touch sensor's half-size around the point (None: the
        original's, 1 for tic-tac-toe, 0.25 for Go).
      allow_double_pass: let the agent pass twice in a row (the original
        ignores a second consecutive pass).
      control_timestep, physics_timestep: seconds.
      render_size: largest frame `Environment.render` will be asked for.
    """

    def __init__(self, game: BoardGame, opponent: Planner, *, registering="arm",
                 arm_reset=True, front_camera=(84, 84), time_limit=30.0,
                 timeout_is_loss=False, piece_noise=None, allow_double_pass=False,
                 control_timestep=0.05, physics_timestep=0.002, render_size=(256, 256)):
        if registering not in ("arm", "fingers", "fingertips"):
            raise ValueError(f"registering must be 'arm', 'fingers' or 'fingertips', "
                             f"got {registering!r}")
        if time_limit <= 0:
            raise ValueError(f"time_limit must be positive seconds, got {time_limit}")
        if piece_noise is None:
            piece_noise = PIECE_NOISE[game.name]
        if not 0 <= piece_noise <= 1:
            raise ValueError(f"piece_noise must be in [0, 1], got {piece_noise}")
        if not isinstance(opponent, Planner):
            raise TypeError(f"opponent must be an abstract_planners Planner, got "
                            f"{type(opponent).__name__}")
        self.game = game
        self.opponent = opponent
        self._spiel_game = game.load()
        self._registering = registering
        self._arm_reset = bool(arm_reset)
        self._timeout_is_loss = bool(timeout_is_loss)
        self._piece_noise = float(piece_noise)
        self._allow_double_pass = bool(allow_double_pass)
        sizes = [tuple(s) for s in (front_camera, render_size) if s]
        offscreen = (max(s[0] for s in sizes), max(s[1] for s in sizes))
        self._arena = arena_lib.BoardArena(kind=game.name, size=game.size,
                                           offscreen_size=offscreen,
                                           physics_timestep=physics_timestep)
        self._arm = kinova.JacoArm(name="arm")
        self._hand = kinova.JacoHand(name="hand")  # tool centre point: the grip site
        self._arm.attach(self._hand)
        self._arena.attach_arm(self._arm)
        self._cameras = {}
        if front_camera:
            self._cameras["front_camera"] = CameraConfig("front_camera", *front_camera)
        self.set_timesteps(control_timestep=control_timestep, physics_timestep=physics_timestep)
        self._add_sensors(self.physics_steps_per_control_step)
        self.time_limit_steps = int(round(time_limit / control_timestep))
        self.state = None  # the OpenSpiel state of the current game
        self._resigned = False
        self.main_camera = "front_camera"
        self._ik = None
        self._tcp_ik = None
        self._description = None
        self._model = None

    def _add_sensors(self, nsample: int) -> None:
        """Touch and contact sensors that keep every substep's reading."""
        sensor = self._arena.mjcf_model.sensor
        arena = self._arena
        self._touch_sensors, self._pos_sensors, self._finger_sensors = [], [], []
        zones = list(zip(arena.squares, arena.sensor_sites))
        if arena.pass_geom is not None:
            zones.append((arena.pass_geom, arena.pass_site))
        # One sensor per finger: a knuckle body's subtree holds its tip too.
        pattern = re.compile(r"b_finger_\d+$" if self._registering == "fingers"
                             else r"b_finger_tip_\d+$")
        finger_bodies = [b for b in self._hand.mjcf_model.find_all("body")
                         if b.name and pattern.match(b.name)]
        for k, (geom, site) in enumerate(zones):
            self._touch_sensors.append(sensor.add("touch", name=f"touch_{k}", site=site,
                                                  nsample=nsample))
            self._pos_sensors.append(sensor.add("contact", name=f"contact_{k}", geom1=geom,
                                                data="found pos", nsample=nsample))
            if self._registering != "arm":
                self._finger_sensors.append([
                    sensor.add("contact", name=f"finger_{k}_{j}", geom1=geom, subtree2=body,
                               data="found", nsample=nsample)
                    for j, body in enumerate(finger_bodies)])

    def description(self):
        """The public `envs.description.BoardDescription` of this task (built
        once: the arm's own model is compiled from a fresh arm and hand)."""
        if self._description is None:
            self._description = self._describe()
        return self._description

    def _describe(self):
        from dm_control import mjcf

        from envs.description import ArmDescription, BoardDescription, CameraDescription
        arena = self._arena
        # The arm's own model: a fresh arm and hand mounted as in the arena.
        root = mjcf.RootElement(model="jaco")
        arm, hand = kinova.JacoArm(name="arm"), kinova.JacoHand(name="hand")
        arm.attach(hand)
        frame = root.attach(arm.mjcf_model)
        frame.pos = arena_lib.ARM_OFFSET
        xml = root.to_xml_string()
        assets = root.get_assets()
        joints = list(arm.joints) + list(hand.joints)
        spec = self._model.actuator_ctrlrange[self._act_ids]
        arm_desc = ArmDescription(
            xml=xml, assets=assets, joint_names=tuple(j.full_identifier for j in joints),
            pinch_site=hand.pinch_site.full_identifier,
            tool_center_point=hand.tool_center_point.full_identifier,
            base_position=tuple(float(v) for v in arena_lib.ARM_OFFSET),
            action_minimum=tuple(float(v) for v in spec[:, 0]),
            action_maximum=tuple(float(v) for v in spec[:, 1]))
        n = self.game.size
        cx, cy = arena.centre
        zones = {}
        if arena.pass_geom is not None:
            size = tuple(float(v) for v in arena.pass_geom.size)
            # The pass sensor covers the board's footprint and beyond; the
            # part outside the board on each side is what a robot can touch.
            for side, sign in (("left", -1.0), ("right", 1.0)):
                # (the pass geom is centred at z = 0: its top is at its half-height)
                zones[side] = {"centre": (cx + sign * 0.5 * (arena.half_board + size[0]), cy,
                                          size[2]),
                               "half": (0.5 * (size[0] - arena.half_board), size[1])}
        cam = arena.front_camera
        front = CameraDescription(
            "front_camera", tuple(float(v) for v in cam.pos),
            tuple(float(v) for v in cam.xyaxes), float(cam.fovy or 45.0),
            (self._cameras["front_camera"].height, self._cameras["front_camera"].width)
            if "front_camera" in self._cameras else None)
        return BoardDescription(
            game=self.game.name, board_size=n, komi=float(self.game.komi),
            num_points=self.game.num_points, pass_action=self.game.pass_action,
            point_positions=tuple(tuple(float(v) for v in self.point_position(a))
                                  for a in range(self.game.num_points)),
            pad_half=float(arena.pad_half), pass_zones=zones,
            board_centre=(float(cx), float(cy)), board_half=float(arena.half_board),
            registering=self._registering, control_timestep=float(self.control_timestep),
            time_limit_steps=int(self.time_limit_steps), arm=arm_desc, front_camera=front)

    # -- composer / PhysicsTask plumbing ------------------------------------

    @property
    def root_entity(self):
        return self._arena

    @property
    def arena(self) -> arena_lib.BoardArena:
        return self._arena

    @property
    def camera_configs(self):
        return self._cameras

    @property
    def arm(self):
        return self._arm

    @property
    def hand(self):
        return self._hand

    def after_compile(self, physics, random_state):
        bind = physics.bind
        m = physics.model.ptr
        self._model, self._data = m, physics.data.ptr
        arena = self._arena
        n = self.physics_steps_per_control_step
        self._nsample = n

        def history(sensors):
            """Index (len(sensors), nsample, dim) of the values in data.history."""
            ids = np.array([bind(s).element_id for s in sensors])
            dims = m.sensor_dim[ids]
            if not (np.all(m.sensor_history[ids, 0] == n) and np.all(dims == dims[0])):
                raise RuntimeError("sensor histories do not match the substeps")
            start = m.sensor_historyadr[ids] + 2 + n
            return start[:, None, None] + np.arange(n * dims[0]).reshape(n, dims[0])[None]

        self._touch_idx = history(self._touch_sensors)[:, :, 0]  # (zones, n)
        self._pos_idx = history(self._pos_sensors)  # (zones, n, 4)
        if self._finger_sensors:
            flat = [s for group in self._finger_sensors for s in group]
            idx = history(flat)[:, :, 0]
            self._finger_idx = idx.reshape(len(self._finger_sensors), -1, n)  # (zones, f, n)
        else:
            self._finger_idx = None
        first = bind(self._touch_sensors[0]).element_id
        self._cursor_adr = int(m.sensor_historyadr[first]) + 1
        self._time_adr = int(m.sensor_historyadr[first]) + 2
        self._arange = np.arange(n)
        self._num_squares = self.game.num_points
        self._has_pass = arena.pass_geom is not None
        self._piece_ids = np.array([bind(p).element_id for p in arena.pieces])
        self._point_xy = arena.point_xy
        joints = list(self._arm.joints) + list(self._hand.joints)
        self._joint_qpos = np.array([bind(j).qposadr for j in joints]).ravel()
        self._joint_dof = np.array([bind(j).dofadr for j in joints]).ravel()
        self._finger_range = np.array([bind(j).range for j in self._hand.joints])
        arm_joints = [bind(j) for j in self._arm.joints]
        self._arm_wrap = np.array([not j.limited for j in arm_joints])
        actuators = list(self._arm.actuators) + list(self._hand.actuators)
        self._act_ids = np.array([bind(a).element_id for a in actuators])
        self._pinch_site = bind(self._hand.pinch_site).element_id
        self._pinch_name = self._hand.pinch_site.full_identifier
        self._tcp_name = self._hand.tool_center_point.full_identifier
        self._qpos, self._qvel = self._data.qpos, self._data.qvel
        self._ctrl = self._data.ctrl
        self._qfrc_actuator = self._data.qfrc_actuator
        self._max_moves = self._spiel_game.max_game_length()
        # Robot geoms, for the arm reset's collision check.
        self._is_arm = np.zeros(m.ngeom, bool)
        self._is_hand = np.zeros(m.ngeom, bool)
        for entity, mask in ((self._arm, self._is_arm), (self._hand, self._is_hand)):
            for geom in entity.mjcf_model.find_all("geom"):
                mask[bind(geom).element_id] = True
        self._is_arm &= ~self._is_hand

    def action_spec(self, physics):
        ranges = self._model.actuator_ctrlrange[self._act_ids]
        names = ",".join(a.name for a in list(self._arm.actuators) + list(self._hand.actuators))
        return specs.BoundedArray((len(self._act_ids),), np.float64, ranges[:, 0], ranges[:, 1],
                                  name=names)

    def truncated_discount(self) -> float:
        return 0.0 if self._timeout_is_loss else 1.0

    def close(self) -> None:
        self.opponent.close()

    # -- episode -----------------------------------------------------------

    def initialize_episode(self, physics, random_state):
        self.opponent.reset(seed=int(random_state.integers(2**31)))
        self.state = self._spiel_game.new_initial_state()
        self._owners = np.full(self.game.num_points, -1, np.int8)
        self._moves: list[int] = []
        self._history = np.full(self._max_moves, -1, np.int32)
        self._planes = self.game.board_planes(self.state)
        m = self._model
        m.geom_group[self._piece_ids] = arena_lib.HIDDEN_GROUP
        self._reward = 0.0
        self._game_over = False
        self._resigned = False
        self._last_agent_move_passed = False
        self.moves_registered = 0
        self.ik_failures = 0
        self._place_arm(random_state)

    def before_step(self, physics, action, random_state):
        self._ctrl[self._act_ids] = action

    def after_step(self, physics, random_state):
        self._reward = 0.0
        if self._game_over:
            return
        h = self._data.history
        order = (int(h[self._cursor_adr]) + 1 + self._arange) % self._nsample
        pressure = h[self._touch_idx[:, order]]  # (zones, substeps), oldest first
        if not pressure.max() > arena_lib.TOUCH_THRESHOLD:
            return
        registered = self.registered_move(pressure, order)
        if registered is not None:
            self._play_agent_move(*registered, random_state)

    def registered_move(self, pressure: np.ndarray, order: np.ndarray):
        """The first substep's move that registers: (action, piece (x, y) or None), or None.

        ``pressure`` holds the zones' (squares, then pass) touch readings per
        substep, oldest first; ``order`` maps those substeps to history slots.
        """
        n2, threshold = self._num_squares, arena_lib.TOUCH_THRESHOLD
        squares = pressure[:n2]
        best = squares.argmax(axis=0)
        best_value = squares[best, self._arange]
        candidate = np.where(best_value > threshold, best, -1)
        if self._has_pass:
            passing = pressure[n2]
            candidate = np.where((passing > best_value) & (passing > threshold), n2, candidate)
        steps = np.flatnonzero(candidate >= 0)
        if not steps.size:
            return None
        zones = candidate[steps]
        if self._finger_idx is not None:
            # A finger geom in contact with that square's geom in that substep.
            fingers = self._data.history[self._finger_idx[zones, :, order[steps]]]
            keep = fingers.max(axis=1) > 0
            steps, zones = steps[keep], zones[keep]
        if not steps.size:
            return None
        legal = np.zeros(n2 + 1, bool)
        legal[self.state.legal_actions()] = True
        if self._has_pass and self._last_agent_move_passed and not self._allow_double_pass:
            legal[n2] = False
        keep = np.flatnonzero(legal[zones])
        if not keep.size:
            return None
        step, zone = int(steps[keep[0]]), int(zones[keep[0]])
        action = self.game.pass_action if zone == n2 else zone
        piece_xy = None
        if zone < n2:
            found, x, y, _ = self._data.history[self._pos_idx[zone, order[step]]]
            piece_xy = (float(x), float(y)) if found > 0 else tuple(self._point_xy[zone])
        return action, piece_xy

    def _play_agent_move(self, action: int, piece_xy, rng) -> None:
        self._apply(action, piece_xy=piece_xy)
        self._last_agent_move_passed = action == self.game.pass_action
        self.moves_registered += 1
        if not self.state.is_terminal():
            subgoal = self.opponent.plan(self.state)
            if subgoal.info.get("resigned"):
                # The opponent (GNU Go) resigned: the game ends as the agent's
                # win (OpenSpiel's go has no resign action, so nothing is played).
                self._resigned = True
                self._game_over = True
                self._reward = 1.0
                return
            self._apply(int(subgoal.action), piece_xy=None, rng=rng)
        if self.state.is_terminal():
            self._game_over = True
            self._reward = self.game.final_reward(self.state)
        elif self._arm_reset:
            self._place_arm(rng)

    def _apply(self, action: int, *, piece_xy, rng=None) -> None:
        """Plays ``action`` for the player to move and updates the pieces."""
        player = self.state.current_player()
        self.state.apply_action(action)
        self._history[len(self._moves)] = action
        self._moves.append(action)
        owners = self.game.owners(self.state)
        changed = np.flatnonzero(owners != self._owners)
        m = self._model
        colours = arena_lib.COLOURS[self.game.name]
        half = self._arena.pad_half
        for point in changed:
            geom = self._piece_ids[point]
            owner = owners[point]
            if owner < 0:  # captured
                m.geom_group[geom] = arena_lib.HIDDEN_GROUP
                continue
            px, py = self._point_xy[point]
            if point == action and player == AGENT and piece_xy is not None:
                x, y = piece_xy
            else:
                noise = (rng.uniform(-1, 1, 2) * self._piece_noise * half
                         if rng is not None else (0.0, 0.0))
                x, y = px + noise[0], py + noise[1]
            m.geom_pos[geom] = (x, y, arena_lib.BOARD_TOP)
            m.geom_rgba[geom] = colours[owner]
            m.geom_group[geom] = 0
        self._owners = owners
        self._planes = self.game.board_planes(self.state)

    # -- the arm's random pose ----------------------------------------------

    def _place_arm(self, rng) -> None:
        """The original's arm reset: the grip site at a random point of the
        TCP box, pointing down with a random yaw; fingers and velocities kept."""
        d, m = self._data, self._model
        arm_qpos = self._joint_qpos[:6]
        before = d.qpos[arm_qpos].copy()
        for _ in range(_REJECTION_SAMPLES):
            target = rng.uniform(TCP_LOW, TCP_HIGH)
            yaw = rng.uniform(-math.pi, math.pi)
            quat = _quat_mul([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)], DOWN_QUAT)
            arm_q = self._solve_tcp(target, quat)
            if arm_q is None:
                continue
            d.qpos[arm_qpos] = arm_q
            mujoco.mj_forward(m, d)
            if not self._arm_collides():
                return
        self.ik_failures += 1
        d.qpos[arm_qpos] = before
        mujoco.mj_forward(m, d)

    def _arm_collides(self) -> bool:
        """Contacts of the arm with itself, the hand or the board (not hand-hand)."""
        ncon = self._data.ncon
        if not ncon:
            return False
        contact = self._data.contact
        g = contact.geom[:ncon]
        touching = contact.dist[:ncon] <= 0
        arm, hand = self._is_arm[g], self._is_hand[g]
        robot = arm | hand
        relevant = ((arm[:, 0] & robot[:, 1]) | (robot[:, 0] & arm[:, 1])
                    | (robot[:, 0] != robot[:, 1]))
        return bool(np.any(relevant & touching))

    def _ik_problem(self, site: str, *, orientation_cost: float, fingers=None):
        """A mink problem for ``site``: (configuration, frame task, posture task
        regularising towards the home posture, that home posture)."""
        config = mink.Configuration(self._model)
        frame = mink.FrameTask(site, "site", position_cost=1.0, orientation_cost=orientation_cost)
        posture = mink.PostureTask(self._model, cost=1e-3)
        home = config.q.copy()
        home[self._joint_qpos[:6]] = HOME_ARM_QPOS
        if fingers is not None:
            home[self._joint_qpos[6:]] = fingers
        posture.set_target(home)
        return config, frame, posture, home

    def _solve_tcp(self, target, quat) -> np.ndarray | None:
        """Arm joints putting the grip site at ``target`` with orientation ``quat``."""
        if self._tcp_ik is None:
            self._tcp_ik = self._ik_problem(self._tcp_name, orientation_cost=1.0)
        config, frame, posture, home = self._tcp_ik
        frame.set_target(mink.SE3.from_rotation_and_translation(mink.SO3(np.asarray(quat)),
                                                                 np.asarray(target, float)))
        q = home.copy()
        q[self._joint_qpos[6:]] = self._data.qpos[self._joint_qpos[6:]]
        config.update(q)
        for _ in range(200):
            velocity = mink.solve_ik(config, [frame, posture], 0.05, "daqp", damping=1e-3)
            config.integrate_inplace(velocity, 0.05)
            error = frame.compute_error(config)
            if np.linalg.norm(error[:3]) < 1e-3 and np.linalg.norm(error[3:]) < 1e-2:
                break
        else:
            return None
        arm_q = config.q[self._joint_qpos[:6]].copy()
        # Continuous joints in [0, 2 pi), as dm_control's IK canonicalises them.
        arm_q[self._arm_wrap] = np.mod(arm_q[self._arm_wrap], 2 * np.pi)
        return arm_q

    def solve_ik(self, target) -> np.ndarray | None:
        """Arm joint angles (6) putting the pinch site at ``target`` pointing down.

        Starts from a home posture above the board (then, failing that, from
        the current posture) and is regularised towards it; None if it does
        not converge to 2 mm. (For tests and scripts.)
        """
        target = np.asarray(target, dtype=np.float64)
        if self._ik is None:
            problem = self._ik_problem(self._pinch_name, orientation_cost=0.05,
                                       fingers=self._finger_range[:, 0])
            self._ik = (*problem, [mink.ConfigurationLimit(self._model)])
        config, frame, posture, home, limits = self._ik
        frame.set_target(mink.SE3.from_rotation_and_translation(mink.SO3(DOWN_QUAT), target))
        current = home.copy()
        current[self._joint_qpos[:6]] = self._data.qpos[self._joint_qpos[:6]]
        for start in (home, current):
            config.update(start)
            for _ in range(150):
                velocity = mink.solve_ik(config, [frame, posture], 0.05, "daqp", damping=1e-3,
                                         limits=limits)
                config.integrate_inplace(velocity, 0.05)
                if np.linalg.norm(frame.compute_error(config)[:3]) < 2e-3:
                    return config.q[self._joint_qpos[:6]].copy()
        return None

    # -- rewards and termination --------------------------------------------

    def get_reward(self, physics):
        return self._reward

    def should_terminate_episode(self, physics):
        return self._game_over

    def get_discount(self, physics):
        return 0.0 if self._game_over else 1.0

    # -- observations -------------------------------------------------------

    def observation_spec(self):
        n, dof = self.game.size, len(self._joint_qpos)
        return {
            "arm/joints_pos": specs.Array((dof,), np.float64, "arm/joints_pos"),
            "arm/joints_vel": specs.Array((dof,), np.float64, "arm/joints_vel"),
            "arm/joints_torque": specs.Array((dof,), np.float64, "arm/joints_torque"),
            "arm/pinch_site_pos": specs.Array((3,), np.float64, "arm/pinch_site_pos"),
            "arm/pinch_site_rmat": specs.Array((9,), np.float64, "arm/pinch_site_rmat"),
            "board_state": specs.Array((n, n, 3), bool, "board_state"),
            "move_history": specs.BoundedArray((self._max_moves,), np.int32, -1,
                                               self._spiel_game.num_distinct_actions() - 1,
                                               "move_history"),
        }

    def observe(self, physics):
        d = self._data
        return {
            "arm/joints_pos": self._qpos[self._joint_qpos],
            "arm/joints_vel": self._qvel[self._joint_dof],
            "arm/joints_torque": self._qfrc_actuator[self._joint_dof],
            "arm/pinch_site_pos": d.site_xpos[self._pinch_site].copy(),
            "arm/pinch_site_rmat": d.site_xmat[self._pinch_site].copy(),
            "board_state": self._planes.copy(),
            "move_history": self._history.copy(),
        }

    # -- accessors for agents and tests -------------------------------------

    def play_moves(self, actions) -> None:
        """Sets up a position: plays ``actions`` for both sides in turn, no replies.

        For tests, demonstrations and curricula; call after ``reset()``. The
        pieces appear at their points (opponent noise applies to none). The
        agent must be the player to move afterwards.

        Raises:
          ValueError: an illegal action, a finished game, or a position where
            the opponent would be to move.
        """
        actions = [int(a) for a in actions]
        probe = self.state.clone()
        for a in actions:
            if probe.is_terminal() or a not in probe.legal_actions():
                raise ValueError(f"action {a} is illegal after {list(probe.history())}")
            probe.apply_action(a)
        if probe.is_terminal() or probe.current_player() != AGENT:
            raise ValueError(f"after {actions} the agent must be to move in a running game")
        for a in actions:
            self._apply(a, piece_xy=None)
        mujoco.mj_forward(self._model, self._data)

    @property
    def moves(self) -> tuple[int, ...]:
        """Actions played so far in this game, both players, in order."""
        return tuple(self._moves)

    @property
    def game_over(self) -> bool:
        return self._game_over

    @property
    def resigned(self) -> bool:
        """Whether the opponent resigned this game (it ended as the agent's win)."""
        return self._resigned

    @property
    def outcome(self) -> str | None:
        """``"win"``, ``"draw"`` or ``"loss"`` for the agent once the game is
        over (an opponent's resignation is a win), else None."""
        if self._resigned:
            return "win"
        if self.state is None or not self.state.is_terminal():
            return None
        value = self.state.returns()[AGENT]
        return "win" if value > 0 else ("draw" if value == 0 else "loss")

    def point_position(self, action: int) -> np.ndarray:
        """World (x, y, z) of board point ``action`` on the board's top."""
        x, y = self._arena.point_position(action)
        return np.array([x, y, arena_lib.BOARD_TOP])

    def pass_position(self, side: str = "left") -> np.ndarray:
        """World (x, y, z) of a point of a pass area (Go only), on the pass geom's
        top 5 cm beside the board's ``side`` edge, level with the rows nearest
        the arm (the easiest part of the area to reach)."""
        arena = self._arena
        if arena.pass_geom is None:
            raise ValueError("this game has no pass areas")
        cx, cy = arena.centre
        sign = -1.0 if side == "left" else 1.0
        return np.array([cx + sign * (arena.half_board + 0.05), cy + 0.75 * arena.half_board,
                         0.5 * arena_lib.SQUARE_HALF_HEIGHT])

    def pinch_site_position(self) -> np.ndarray:
        return self._data.site_xpos[self._pinch_site].copy()
