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

**Other games** (MuJoBoard, `envs.boards.games`): what a touch on a zone does
comes from the game's `GameRules` (a point, a column, or a move game's
piece-then-destination with a selection that times out after
``half_move_timeout``); the same hardest-press rule picks the zone. After
the agent's move the opponent plays until the agent must move again (a
checkers jump sequence is several moves; forced passes are played by the
referee), and with ``agent_player=1`` the opponent's first move is played
at reset.

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

import numpy as np
from dm_control.entities.manipulators import kinova
from dm_env import specs

from abstract_planners.base import Planner
from envs.boards import arena as arena_lib
from envs.boards.games import AGENT, BoardGame  # noqa: F401  (AGENT: re-export)

# The task's parts by concern; their public names stay importable from here.
from envs.boards.task_arm import (
    _REJECTION_SAMPLES,  # noqa: F401
    DOWN_QUAT,  # noqa: F401
    HOME_ARM_QPOS,  # noqa: F401
    TCP_HIGH,  # noqa: F401
    TCP_LOW,  # noqa: F401
    ArmPoseMixin,
    _quat_mul,  # noqa: F401
)
from envs.boards.task_observations import ObservationsMixin
from envs.boards.task_record import HALF_MOVE_TIMEOUT, PIECE_NOISE, GameRecordMixin
from envs.core import PhysicsTask
from envs.rendering import CameraConfig


def check_agent_player(agent_player) -> None:
    """Raises ValueError unless ``agent_player`` is 0, 1 or ``"random"``."""
    if isinstance(agent_player, bool) or agent_player not in (0, 1, "random"):
        raise ValueError(f"agent_player must be 0, 1 or 'random', got {agent_player!r}")


def _check_task_options(
    game, opponent, registering, time_limit, agent_player, half_move_timeout, piece_noise
):
    """Checks `BoardTask`'s options (ValueError or TypeError naming the bad
    one) and returns ``piece_noise``, the game's default where None."""
    if registering not in ("arm", "fingers", "fingertips"):
        raise ValueError(
            f"registering must be 'arm', 'fingers' or 'fingertips', got {registering!r}"
        )
    if time_limit <= 0:
        raise ValueError(f"time_limit must be positive seconds, got {time_limit}")
    check_agent_player(agent_player)
    if not half_move_timeout > 0:
        raise ValueError(f"half_move_timeout must be positive seconds, got {half_move_timeout!r}")
    if piece_noise is None:
        piece_noise = PIECE_NOISE.get(game.name, PIECE_NOISE["go"])
    if not 0 <= piece_noise <= 1:
        raise ValueError(f"piece_noise must be in [0, 1], got {piece_noise}")
    if not isinstance(opponent, Planner):
        raise TypeError(
            f"opponent must be an abstract_planners Planner, got {type(opponent).__name__}"
        )
    return piece_noise


class BoardTask(GameRecordMixin, ArmPoseMixin, ObservationsMixin, PhysicsTask):
    """A two-player board game against a planner, played with a Jaco arm.

    Touch registration and the game record come from `GameRecordMixin`
    (`envs.boards.task_record`), the arm reset and IK from `ArmPoseMixin`
    (`envs.boards.task_arm`), the description, observations and positions
    from `ObservationsMixin` (`envs.boards.task_observations`); the composer
    hooks, rewards and termination are here.

    Args:
      game: the `BoardGame` (tic-tac-toe, Go or another registered game).
      opponent: planner for the other player (gets OpenSpiel states).
      agent_player: the agent's OpenSpiel player: 0 (moves first, the
        paper's), 1, or ``"random"`` (drawn per episode). When the opponent
        moves first, its move is on the board in the first observation.
      half_move_timeout: move games: seconds after which a selected piece
        whose move was not completed is deselected; a press held on it
        selects it again only after it is released.
      registering: which geoms register a move: ``"arm"`` (any contact on the
        board; MuJoXO), ``"fingers"`` (a finger geom, knuckle or tip, must
        touch the square; MuJoGo) or ``"fingertips"`` (only the tips).
      arm_reset: reset the arm to a random pose after every registered move.
      front_camera: ``(height, width)`` of the RGB camera facing the arm, or None.
      front_camera_2: ``(height, width)`` of the original code's second view
        (``front_camera_2``: higher and steeper, the whole 7x7 Go board in
        view), or None (the default: the paper's agents see one camera).
      time_limit: seconds; `timeout_is_loss` makes the last step terminal.
      piece_noise: the opponent's pieces land uniformly within this fraction
        of the touch sensor's half-size around the point (None: the
        original's, 1 for tic-tac-toe, 0.25 for Go).
      allow_double_pass: let the agent pass twice in a row (the original
        ignores a second consecutive pass).
      control_timestep, physics_timestep: seconds.
      render_size: largest frame `Environment.render` will be asked for, and
        its default size.
      multisamples: samples per pixel of rendered frames (the original's 4).
      shadows: the light casts shadows, as the original's does.
    """

    #: The referee's record of the game (the paper's agents observe cameras
    #: and proprioception only); move games add ``selected_point``.
    privileged_observations = frozenset({"board_state", "move_history"})
    state_observations = ("board_state",)

    def __init__(
        self,
        game: BoardGame,
        opponent: Planner,
        *,
        registering="arm",
        arm_reset=True,
        front_camera=(84, 84),
        front_camera_2=None,
        time_limit=30.0,
        timeout_is_loss=False,
        piece_noise=None,
        allow_double_pass=False,
        control_timestep=0.05,
        physics_timestep=0.002,
        render_size=(256, 256),
        multisamples=0,
        shadows=False,
        agent_player=AGENT,
        half_move_timeout=HALF_MOVE_TIMEOUT,
    ):
        piece_noise = _check_task_options(
            game, opponent, registering, time_limit, agent_player, half_move_timeout, piece_noise
        )
        self.game = game
        self.opponent = opponent
        self._spiel_game = game.load()
        self._registering = registering
        self._arm_reset = bool(arm_reset)
        self._timeout_is_loss = bool(timeout_is_loss)
        self._piece_noise = float(piece_noise)
        self._allow_double_pass = bool(allow_double_pass)
        render_height, render_width = render_size
        self.render_size = (int(render_height), int(render_width))
        sizes = [tuple(s) for s in (front_camera, front_camera_2, render_size) if s]
        offscreen = (max(s[0] for s in sizes), max(s[1] for s in sizes))
        self.agent_player = agent_player
        if game.rules.input == "move":
            self.privileged_observations = self.privileged_observations | {"selected_point"}
        self._agent = AGENT if agent_player == "random" else int(agent_player)
        self._arena = arena_lib.BoardArena(
            game=game,
            offscreen_size=offscreen,
            physics_timestep=physics_timestep,
            multisamples=multisamples,
            shadows=shadows,
        )
        self._multisamples = int(multisamples)
        self._arm = kinova.JacoArm(name="arm")
        self._hand = kinova.JacoHand(name="hand")  # tool centre point: the grip site
        self._arm.attach(self._hand)
        self._arena.attach_arm(self._arm)
        self._cameras = {}
        if front_camera:
            self._cameras["front_camera"] = CameraConfig("front_camera", *front_camera)
        if front_camera_2:
            self._cameras["front_camera_2"] = CameraConfig("front_camera_2", *front_camera_2)
        self.set_timesteps(control_timestep=control_timestep, physics_timestep=physics_timestep)
        self._add_sensors(self.physics_steps_per_control_step)
        self.time_limit_steps = int(round(time_limit / control_timestep))
        self.half_move_timeout = float(half_move_timeout)
        self._half_move_steps = max(1, int(round(half_move_timeout / control_timestep)))
        self.state = None  # the OpenSpiel state of the current game
        self._resigned = False
        self.main_camera = "front_camera"
        self._ik = None
        self._tcp_ik = None
        self._description = None
        self._model = None

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
        self._selection_id = (
            bind(arena.selection).element_id if arena.selection is not None else None
        )
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
        return specs.BoundedArray(
            (len(self._act_ids),), np.float64, ranges[:, 0], ranges[:, 1], name=names
        )

    def truncated_discount(self) -> float:
        return 0.0 if self._timeout_is_loss else 1.0

    def close(self) -> None:
        self.opponent.close()

    # -- episode -----------------------------------------------------------

    def initialize_episode(self, physics, random_state) -> None:
        self.opponent.reset(seed=int(random_state.integers(2**31)))
        if self.agent_player == "random":
            self._agent = int(random_state.integers(2))
        self.state = self._spiel_game.new_initial_state()
        self._players = np.full(self.game.num_points, -1, np.int8)
        self._kings = np.zeros(self.game.num_points, bool)
        self._moves: list[int] = []
        self._history = np.full(self._max_moves, -1, np.int32)
        m = self._model
        m.geom_group[self._piece_ids] = arena_lib.HIDDEN_GROUP
        m.geom_size[self._piece_ids, 1] = self._arena.piece_half_height
        self._show_pieces()  # the initial pieces (othello, move games)
        self._reward = 0.0
        self._game_over = False
        self._resigned = False
        self._last_agent_move_passed = False
        self._effects_key = self._effects = None
        self._steps = 0
        self._stale = -1
        self._set_selected(-1)
        self.moves_registered = 0
        self.ik_failures = 0
        self._others_turn(random_state)  # the opponent's first move, if it has it
        self._place_arm(random_state)

    def before_step(self, physics, action, random_state):
        self._ctrl[self._act_ids] = action

    def after_step(self, physics, random_state):
        self._reward = 0.0
        self._steps += 1
        if self._game_over:
            return
        if self._selected >= 0 and self._steps - self._selected_at >= self._half_move_steps:
            # The half move timed out; its piece is selected again only by a
            # new press (after its sensor has been released).
            self._stale = self._selected
            self._set_selected(-1)
        h = self._data.history
        order = (int(h[self._cursor_adr]) + 1 + self._arange) % self._nsample
        pressure = h[self._touch_idx[:, order]]  # (zones, substeps), oldest first
        if self._stale >= 0 and not pressure[self._stale].min() > arena_lib.TOUCH_THRESHOLD:
            self._stale = -1
        if not pressure.max() > arena_lib.TOUCH_THRESHOLD:
            return
        registered = self.registered_touch(pressure, order)
        if registered is None:
            return
        if registered[0] == "select":
            self._set_selected(registered[1])
        else:
            self._play_agent_move(registered[1], registered[2], random_state)

    # -- rewards and termination --------------------------------------------

    def get_reward(self, physics):
        return self._reward

    def should_terminate_episode(self, physics):
        return self._game_over

    def get_discount(self, physics):
        return 0.0 if self._game_over else 1.0

    @property
    def agent(self) -> int:
        """The agent's OpenSpiel player in the current episode."""
        return self._agent

    @property
    def succeeded(self) -> bool:
        """The agent won the game (an opponent's resignation included)."""
        return self.outcome == "win"

    @property
    def reward_rule(self) -> str:
        """The reward rule in a sentence (the environment gallery's cards show it)."""
        return (
            f"0 until the game ends; then 1 for a win (an opponent's resignation included), "
            f"{self.game.draw_reward:g} for a draw, 0 for a loss."
        )

    @property
    def success_rule(self) -> str:
        """The success rule and how the episode ends, in a sentence."""
        timeout = (
            "a game still running is a loss (reward 0, discount 0)"
            if self._timeout_is_loss
            else "a game still running is truncated (discount 1), not a win"
        )
        return (
            f"A win. The episode terminates (discount 0) when the game ends; at the time "
            f"limit {timeout}."
        )
