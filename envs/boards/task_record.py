"""The game record of the board task (`envs.boards.task.BoardTask`): the
touch and contact sensors, which move a control step's touches register,
playing it and the opponent's reply (the OpenSpiel state, the pieces on the
board), and the game's accessors.

`GameRecordMixin` is one of `BoardTask`'s bases; it reads the attributes
`BoardTask.after_compile` sets (sensor history indices, ``_model``,
``_data``, piece geom ids, point positions) and keeps the game's state
(``state``, ``_moves``, ``_history``, ``_owners``, ``_planes``,
``_game_over``, ``_reward``, ``_resigned``, ``moves_registered``).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any, Callable

import mujoco
import numpy as np

from envs.boards import arena as arena_lib

if TYPE_CHECKING:
    from abstract_planners.base import Planner
    from envs.boards.games import BoardGame

#: Piece jitter as a fraction of the sensor's half-size (the original's;
#: other games take Go's).
PIECE_NOISE = {"tic_tac_toe": 1.0, "go": 0.25}
#: Move games: seconds before a selected piece whose move was not completed
#: is deselected (`envs.boards.task.BoardTask`'s ``half_move_timeout``).
HALF_MOVE_TIMEOUT = 10.0


class GameRecordMixin:
    """Touch registration, moves and the game record of `BoardTask`."""

    # Set by `BoardTask` (its parts, settings and compiled-model indices).
    game: BoardGame
    opponent: Planner
    _arena: arena_lib.BoardArena
    _hand: Any
    _registering: str
    _arm_reset: bool
    _piece_noise: float
    _agent: int
    _model: mujoco.MjModel
    _data: mujoco.MjData
    _arange: np.ndarray
    _pos_idx: np.ndarray
    _finger_idx: np.ndarray | None
    _num_squares: int
    _has_pass: bool
    _piece_ids: np.ndarray
    _selection_id: int | None
    _point_xy: np.ndarray
    _steps: int
    _stale: int
    # Kept here (see the module docstring).
    state: Any  # the OpenSpiel state (pyspiel has no type stubs)
    moves_registered: int
    _moves: list[int]
    _history: np.ndarray
    _players: np.ndarray
    _kings: np.ndarray
    _game_over: bool
    # The arm reset, `envs.boards.task_arm.ArmPoseMixin._place_arm` (an annotation only, so
    # that the method is still found on ArmPoseMixin).
    _place_arm: Callable[[np.random.Generator], None]

    def _add_sensors(self, nsample: int) -> None:
        """Touch and contact sensors that keep every substep's reading."""
        sensor = self._arena.mjcf_model.sensor
        arena = self._arena
        self._touch_sensors, self._pos_sensors, self._finger_sensors = [], [], []
        zones = list(zip(arena.squares, arena.sensor_sites))
        if arena.pass_geom is not None:
            zones.append((arena.pass_geom, arena.pass_site))
        # One sensor per finger: a knuckle body's subtree holds its tip too.
        pattern = re.compile(
            r"b_finger_\d+$" if self._registering == "fingers" else r"b_finger_tip_\d+$"
        )
        finger_bodies = [
            b for b in self._hand.mjcf_model.find_all("body") if b.name and pattern.match(b.name)
        ]
        for k, (geom, site) in enumerate(zones):
            self._touch_sensors.append(
                sensor.add("touch", name=f"touch_{k}", site=site, nsample=nsample)
            )
            self._pos_sensors.append(
                sensor.add(
                    "contact", name=f"contact_{k}", geom1=geom, data="found pos", nsample=nsample
                )
            )
            if self._registering != "arm":
                self._finger_sensors.append(
                    [
                        sensor.add(
                            "contact",
                            name=f"finger_{k}_{j}",
                            geom1=geom,
                            subtree2=body,
                            data="found",
                            nsample=nsample,
                        )
                        for j, body in enumerate(finger_bodies)
                    ]
                )

    def registered_touch(self, pressure: np.ndarray, order: np.ndarray):
        """The first substep's touch that does something: ``("move", action,
        piece (x, y) or None)``, ``("select", point)`` (move games), or None.

        ``pressure`` holds the zones' (points, then pass) touch readings per
        substep, oldest first; ``order`` maps those substeps to history slots.
        What a touch on a zone does comes from the game
        (`envs.boards.games.BoardGame.zone_effects`).
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
        act, select = self._zone_effects()
        does = (act >= 0) | select
        if self._stale >= 0:
            does = does.copy()
            does[self._stale] = False
        keep = np.flatnonzero(does[zones])
        if not keep.size:
            return None
        step, zone = int(steps[keep[0]]), int(zones[keep[0]])
        if act[zone] < 0:
            return "select", zone
        piece_xy = None
        if zone < n2 and self.game.rules.input == "point":
            found, x, y, _ = self._data.history[self._pos_idx[zone, order[step]]]
            piece_xy = (float(x), float(y)) if found > 0 else tuple(self._point_xy[zone])
        return "move", int(act[zone]), piece_xy

    def _zone_effects(self):
        """`BoardGame.zone_effects` of the current decision (cached), with
        the agent's second consecutive pass removed unless allowed."""
        key = (len(self._moves), self._selected)
        if self._effects_key != key:
            act, select = self.game.zone_effects(self.state, self._selected)
            if self._has_pass and self._last_agent_move_passed and not self._allow_double_pass:
                act[self._num_squares] = -1
            self._effects_key, self._effects = key, (act, select)
        return self._effects

    def _set_selected(self, point: int) -> None:
        """Selects ``point``'s piece for the half move in progress (-1: none)
        and shows or hides the selection disc."""
        self._selected = int(point)
        self._selected_at = self._steps
        if self._selection_id is None:
            return
        m = self._model
        if point < 0:
            m.geom_group[self._selection_id] = arena_lib.HIDDEN_GROUP
            return
        x, y = self._point_xy[point]
        m.geom_pos[self._selection_id] = (x, y, arena_lib.BOARD_TOP + 0.001)
        m.geom_group[self._selection_id] = 0

    def _play_agent_move(self, action: int, piece_xy, rng) -> None:
        self._set_selected(-1)
        self._apply(action, piece_xy=piece_xy)
        self._last_agent_move_passed = action == self.game.pass_action
        self.moves_registered += 1
        self._others_turn(rng)
        if self._game_over:
            return
        if self.state.is_terminal():
            self._game_over = True
            self._reward = self.game.final_reward(self.state, self._agent)
        elif self._arm_reset:
            self._place_arm(rng)

    def _others_turn(self, rng) -> None:
        """Plays until the agent must move or the game ends: the opponent's
        moves (a checkers jump sequence is several) and the passes the
        referee plays (`BoardGame.forced_pass`), the agent's included. An
        opponent's resignation ends the game as the agent's win."""
        while not self.state.is_terminal():
            forced = self.game.forced_pass(self.state)
            if forced is not None:
                self._apply(forced, piece_xy=None)
                continue
            if self.state.current_player() == self._agent:
                return
            subgoal = self.opponent.plan(self.state)
            if subgoal.info.get("resigned"):
                # The opponent (GNU Go) resigned: the game ends as the agent's
                # win (OpenSpiel's go has no resign action, so nothing is played).
                self._resigned = True
                self._game_over = True
                self._reward = 1.0
                return
            self._apply(int(subgoal.action), piece_xy=None, rng=rng)

    def _apply(self, action: int, *, piece_xy, rng=None) -> None:
        """Plays ``action`` for the player to move and updates the pieces
        (`_show_pieces`)."""
        self.state.apply_action(action)
        self._history[len(self._moves)] = action
        self._moves.append(action)
        self._show_pieces(action=action, piece_xy=piece_xy, rng=rng)

    def _show_pieces(self, *, action=None, piece_xy=None, rng=None) -> None:
        """Makes the piece geoms show ``self.state``: a new piece lands at
        its point (with the piece noise when ``rng`` is given: the
        opponent's), at ``piece_xy`` for the point ``action`` when given; a
        piece that changes colour or is promoted stays where it is; a
        removed one is hidden. At reset (all pieces hidden, ``_players``
        all -1) it draws the game's initial pieces at their points."""
        players = self.game.players(self.state)
        kings = self.game.kings(self.state)
        changed = np.flatnonzero((players != self._players) | (kings != self._kings))
        m = self._model
        arena = self._arena
        half = arena.pad_half
        for point in changed:
            geom = self._piece_ids[point]
            player = players[point]
            if player < 0:  # captured or moved away
                m.geom_group[geom] = arena_lib.HIDDEN_GROUP
                continue
            height = arena.piece_half_height * (arena_lib.KING_HEIGHT if kings[point] else 1.0)
            m.geom_size[geom, 1] = height
            if self._players[point] < 0:  # a new piece
                if piece_xy is not None and point == action:
                    x, y = piece_xy
                else:
                    px, py = self._point_xy[point]
                    noise = (
                        rng.uniform(-1, 1, 2) * self._piece_noise * half
                        if rng is not None
                        else (0.0, 0.0)
                    )
                    x, y = px + noise[0], py + noise[1]
            else:
                x, y = m.geom_pos[geom, :2]
            m.geom_pos[geom] = (x, y, arena_lib.BOARD_TOP + height - arena.piece_half_height)
            m.geom_rgba[geom] = arena.colours[player]
            m.geom_group[geom] = 0
        self._players, self._kings = players, kings
        self._planes = self.game.board_planes(self.state, self._agent)

    # -- the game, for agents and tests -------------------------------------

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
        if probe.is_terminal() or probe.current_player() != self._agent:
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
        value = self.state.returns()[self._agent]
        return "win" if value > 0 else ("draw" if value == 0 else "loss")
