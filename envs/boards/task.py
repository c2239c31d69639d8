"""Board games played by touching a board with a 9-DoF Jaco arm (MuJoXO, MuJoGo).

The agent controls dm_control's Kinova Jaco arm (6 joints) and three-finger
hand (3 joints) with velocity actuators: the action is 9 joint-velocity
targets. Touching a point's invisible pad with a registering geom (any arm or
hand geom in MuJoXO, only the three fingertips in MuJoGo) plays that point if
it is legal; a piece of the agent's colour appears where the touch was. The
opponent (an `abstract_planners` planner, mixed with random moves) replies in
the same control step; its piece lands at the chosen point with uniform noise
inside the pad. After every move, and at episode start, the arm is put in a
random pose above the board (IK with mink; ``arm_reset=False`` disables the
reset after moves).

Touches are read from MuJoCo's contacts once per control step (the contacts of
the step's last substep) and register on their rising edge: a pad must stop
being touched before it can register again, so a finger resting on a pass pad
passes once. Touching an occupied or illegal point (Go suicide, ko) changes
nothing.

Rewards are given at the end of the game: 1 for a win, 0 for a loss, the
game's draw reward for a draw (MuJoXO 0.5). The episode terminates (discount
0) when the game ends. At the time limit MuJoXO truncates (discount 1); in
MuJoGo a game still running is a loss (reward 0, discount 0).
"""

from __future__ import annotations

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
HOME_ARM_QPOS = np.array([1.24, 3.89, 2.13, 5.79, 1.64, 3.89])
#: Orientation of the pinch site pointing straight down (w, x, y, z).
DOWN_QUAT = np.array([0.0, 0.70710678118, 0.70710678118, 0.0])


class BoardTask(PhysicsTask):
    """A two-player board game against a planner, played with a Jaco arm.

    Args:
      game: the `BoardGame` (tic-tac-toe or Go of some size).
      opponent: planner for the second player (gets OpenSpiel states).
      registering: ``"arm"`` (any arm or hand geom registers a move) or
        ``"fingertips"``.
      arm_reset: put the arm in a random pose above the board after every move.
      front_camera: ``(height, width)`` of the RGB camera facing the arm, or None.
      time_limit: seconds; `timeout_is_loss` makes the last step terminal.
      piece_noise: the opponent's pieces land uniformly within this fraction
        of the pad's half-width around the point.
      control_timestep, physics_timestep: seconds.
      render_size: largest frame `Environment.render` will be asked for.
    """

    def __init__(self, game: BoardGame, opponent: Planner, *, registering="arm",
                 arm_reset=True, front_camera=(84, 84), time_limit=30.0,
                 timeout_is_loss=False, piece_noise=0.6, control_timestep=0.05,
                 physics_timestep=0.005, render_size=(256, 256)):
        if registering not in ("arm", "fingertips"):
            raise ValueError(f"registering must be 'arm' or 'fingertips', got {registering!r}")
        if time_limit <= 0:
            raise ValueError(f"time_limit must be positive seconds, got {time_limit}")
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
        sizes = [tuple(s) for s in (front_camera, render_size) if s]
        offscreen = (max(s[0] for s in sizes), max(s[1] for s in sizes))
        self._arena = arena_lib.BoardArena(kind=game.name, size=game.size,
                                           offscreen_size=offscreen)
        self._arm = kinova.JacoArm(name="arm")
        self._hand = kinova.JacoHand(name="hand", use_pinch_site_as_tcp=True)
        self._arm.attach(self._hand)
        self._arena.attach(self._arm)
        self._cameras = {}
        if front_camera:
            self._cameras["front_camera"] = CameraConfig("front_camera", *front_camera)
        self.set_timesteps(control_timestep=control_timestep, physics_timestep=physics_timestep)
        self.time_limit_steps = int(round(time_limit / control_timestep))
        self.state = None  # the OpenSpiel state of the current game
        self.main_camera = "front_camera"
        self._ik = None

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
        n_points = self.game.num_points
        # Geom id -> board action of its pad (-1: not a pad).
        self._pad_action = np.full(m.ngeom, -1, np.int64)
        for a, pad in enumerate(arena.pads):
            self._pad_action[bind(pad).element_id] = a
        for pad in arena.pass_pads:
            self._pad_action[bind(pad).element_id] = self.game.pass_action
        self._registers = np.zeros(m.ngeom, bool)
        if self._registering == "arm":
            for entity in (self._arm, self._hand):
                for geom in entity.mjcf_model.find_all("geom"):
                    self._registers[bind(geom).element_id] = True
        else:
            for geom in self._hand.mjcf_model.find_all("geom"):
                if geom.name and geom.name.startswith("finger_tip"):
                    self._registers[bind(geom).element_id] = True
        self._piece_ids = np.array([bind(p).element_id for p in arena.pieces])
        self._point_xy = arena.point_xy
        joints = list(self._arm.joints) + list(self._hand.joints)
        self._joint_qpos = np.array([bind(j).qposadr for j in joints]).ravel()
        self._joint_dof = np.array([bind(j).dofadr for j in joints]).ravel()
        self._finger_range = np.array([bind(j).range for j in self._hand.joints])
        actuators = list(self._arm.actuators) + list(self._hand.actuators)
        self._act_ids = np.array([bind(a).element_id for a in actuators])
        self._pinch_site = bind(self._hand.pinch_site).element_id
        self._pinch_name = self._hand.pinch_site.full_identifier
        self._qpos, self._qvel = self._data.qpos, self._data.qvel
        self._ctrl = self._data.ctrl
        self._qfrc_actuator = self._data.qfrc_actuator
        self._max_moves = self._spiel_game.max_game_length()

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
        self._touched: frozenset = frozenset()
        self._reward = 0.0
        self._game_over = False
        self.moves_registered = 0
        self.ik_failures = 0
        self._place_arm(random_state, forward=False)

    def before_step(self, physics, action, random_state):
        self._ctrl[self._act_ids] = action

    def after_step(self, physics, random_state):
        self._reward = 0.0
        touched = self._touched_pads()
        if not touched and not self._touched:
            return
        new = [a for a in touched if a not in self._touched]
        self._touched = frozenset(touched)
        if self._game_over:
            return
        for action in new:
            if action in self.state.legal_actions():
                self._play_agent_move(action, touched[action], random_state)
                break

    def _touched_pads(self) -> dict[int, tuple[float, float]]:
        """Pads in contact with a registering geom: action -> contact (x, y)."""
        ncon = self._data.ncon
        if not ncon:
            return {}
        contact = self._data.contact
        geom = contact.geom
        pad_action, registers = self._pad_action, self._registers
        found: dict[int, tuple[float, float]] = {}
        for i in range(ncon):
            g1, g2 = int(geom[i, 0]), int(geom[i, 1])
            if registers[g2] and pad_action[g1] >= 0:
                action = int(pad_action[g1])
            elif registers[g1] and pad_action[g2] >= 0:
                action = int(pad_action[g2])
            else:
                continue
            if action not in found:
                pos = contact.pos[i]
                found[action] = (float(pos[0]), float(pos[1]))
        return found

    def _play_agent_move(self, action: int, touch_xy, rng) -> None:
        self._apply(action, piece_xy=touch_xy)
        self.moves_registered += 1
        if not self.state.is_terminal():
            subgoal = self.opponent.plan(self.state)
            self._apply(int(subgoal.action), piece_xy=None, rng=rng)
        if self.state.is_terminal():
            self._game_over = True
            self._reward = self.game.final_reward(self.state)
        elif self._arm_reset:
            self._place_arm(rng, forward=True)
            self._touched = frozenset()

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
                x = min(max(piece_xy[0], px - half), px + half)
                y = min(max(piece_xy[1], py - half), py + half)
            else:
                noise = (rng.uniform(-1, 1, 2) * self._piece_noise * half
                         if rng is not None else (0.0, 0.0))
                x, y = px + noise[0], py + noise[1]
            m.geom_pos[geom] = (x, y, arena_lib.BOARD_TOP + self._arena.piece_half_height)
            m.geom_rgba[geom] = colours[owner]
            m.geom_group[geom] = 0
        self._owners = owners
        self._planes = self.game.board_planes(self.state)

    # -- the arm's random pose ----------------------------------------------

    def _place_arm(self, rng, *, forward: bool) -> None:
        """Puts the arm at rest in a random pose with the hand above the board."""
        d = self._data
        half = self._arena.half_board
        cx, cy = arena_lib.BOARD_CENTRE
        target = np.array([cx + rng.uniform(-0.8, 0.8) * half,
                           cy + rng.uniform(-0.8, 0.8) * half,
                           arena_lib.BOARD_TOP + rng.uniform(0.12, 0.3)])
        arm_q = self.solve_ik(target)
        if arm_q is None:
            self.ik_failures += 1
            arm_q = HOME_ARM_QPOS
        fingers = self._finger_range[:, 0] + rng.uniform(0, 1, 3) * np.ptp(self._finger_range, 1)
        d.qpos[self._joint_qpos] = np.concatenate([arm_q, fingers])
        d.qvel[self._joint_dof] = 0.0
        d.ctrl[self._act_ids] = 0.0
        if forward:
            mujoco.mj_forward(self._model, d)

    def solve_ik(self, target) -> np.ndarray | None:
        """Arm joint angles (6) putting the pinch site at ``target`` pointing down.

        Starts from, and is regularised towards, a home posture above the
        board; None if it does not converge to 2 mm.
        """
        target = np.asarray(target, dtype=np.float64)
        if self._ik is None:
            config = mink.Configuration(self._model)
            frame = mink.FrameTask(self._pinch_name, "site", position_cost=1.0,
                                   orientation_cost=0.3)
            posture = mink.PostureTask(self._model, cost=1e-3)
            home = config.q.copy()
            home[self._joint_qpos[:6]] = HOME_ARM_QPOS
            home[self._joint_qpos[6:]] = self._finger_range[:, 0]
            posture.set_target(home)
            self._ik = (config, frame, posture, home)
        config, frame, posture, home = self._ik
        frame.set_target(mink.SE3.from_rotation_and_translation(mink.SO3(DOWN_QUAT), target))
        config.update(home)
        for _ in range(100):
            velocity = mink.solve_ik(config, [frame, posture], 0.05, "daqp", damping=1e-3)
            config.integrate_inplace(velocity, 0.05)
            if np.linalg.norm(frame.compute_error(config)[:3]) < 2e-3:
                break
        else:
            return None
        return config.q[self._joint_qpos[:6]].copy()

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

    def point_position(self, action: int) -> np.ndarray:
        """World (x, y, z) of the top of board point ``action``'s pad."""
        x, y = self._arena.point_position(action)
        return np.array([x, y, arena_lib.BOARD_TOP + 2 * arena_lib.PAD_HALF_HEIGHT])

    def pass_position(self, side: str = "left") -> np.ndarray:
        """World (x, y, z) of the centre of a pass pad (Go only)."""
        if not self._arena.pass_pads:
            raise ValueError("this game has no pass pads")
        pad = self._arena.pass_pads[0 if side == "left" else 1]
        x, y, _ = pad.pos
        return np.array([x, y, arena_lib.BOARD_TOP + 2 * arena_lib.PAD_HALF_HEIGHT])

    def pinch_site_position(self) -> np.ndarray:
        return self._data.site_xpos[self._pinch_site].copy()
