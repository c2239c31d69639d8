"""`BoardCameraEstimator` (``camera``): a board game seen through a camera.

Observation-only: it reads the RGB frames of the board's high front view
(``front_camera_2``, the whole board in view), the arm's joint observations
(``arm/joints_pos``, ``arm/joints_vel``) and ``agent_player``, and the public
description: each point's world position, the camera's pose and
intrinsics, the arm's own kinematic model; the game's rules
(`envs.boards.games.GameRules`: its pieces' colours) come from the game the
description names, the selection disc's colour from the arena's look
(`envs.boards.arena.SELECTION_RGBA`). It never reads ``board_state``, ``move_history`` or
``selected_point``.

How it reads a frame: `hier_agents.estimators.board_view.BoardView` (cells
projected from the described camera, the arm hidden with its own model,
pieces against the empty board, the selection disc).
`hier_agents.estimators.board_colours.BoardColours` learns the empty
board's colour per patch sample (from the first frame, and from cells a
confirmed state says are empty) and, under a light that casts shadows (the
original's looks), the share of light the arm's shadow leaves.

How it keeps the game (`estimate`): the OpenSpiel state of the last
*anchor* (a state every visible cell confirmed, with no hidden cell
deciding it) is extended by the legal continuations: the player to move,
then the other, until the agent is to move again (a forced pass played as
the referee plays it, a checkers jump sequence as several moves). Each
continuation is scored, and the best becomes the estimate: fewest cells
read surely that it contradicts, then the smallest distance between the
visible cells' colour shares and its pieces (an unsure cell still counts
a little), then keeping the moves already estimated (two orders of the
same moves can give one board; the skill and the planner read the
record), then fewest changed cells not read surely, then fewest moves.
It becomes the anchor when it contradicts no cell read surely and every
cell it changed (and, after the opponent's pass, every empty cell, where a
reply could lie) was read surely, in this frame or in a later one before
the next registered move (the board stands still in between: the opponent
replies at once and the arm resets). When the last anchor's continuations
contradict a cell read surely (a move taken for a pass, or for another
under the arm), the `BACKTRACK` anchors before it are tried; later anchors
are dropped only when an earlier one's continuation explains the frame.
When the last anchor's continuations contradict a cell read surely, those
of the current estimate (extending that anchor, unconfirmed) are searched
too: the beam ranks half-played continuations by what they already
explain and can drop the true one.
The search (`hier_agents.estimators.board_search.ContinuationSearch`)
keeps `BEAM` states per move and looks at most `MAX_MOVES` moves ahead;
when no anchor's does explain the frame (the game ran on while the changed
cells stayed hidden), one search from the last anchor keeps `DEEP_BEAM`
states and looks `DEEP_MOVES` ahead. A frame that the current estimate
already explains costs no search. When an episode ends with the game (a terminal
timestep, discount 0), a finished game is preferred: the winning piece may
still be under the hand.

Frame schedule: a frame is read at once when the arm jumps (the arm reset
after a registered move: a joint moves more than `ARM_JUMP` or the pinch
site more than `PINCH_JUMP` in a step), while the estimate is not
confirmed, when a press shows a refused move, and at the episode's last
step; and every `FRAME_EVERY` steps while the hand is low over the board
(its pinch site within `TOUCH_HEIGHT` of a zone's top, in this step or the
last: only a touch registers a move, and the opponent replies at once; a
move registered with no arm reset is read within `FRAME_EVERY` steps). A
confirmed estimate of a game whose every touch plays a move is read only
then (``still=True``, the default): the board stands still until a touch
registers. In a game that selects a piece first, a selection times out
with no touch, so its frames are read every `FRAME_EVERY` steps wherever
the hand is (every game's, with ``still=False``). In between the last
estimate is returned with the new joints.

The arm reset tells more: a move was registered, by the touch under the
pinch site just before the jump (the arm's own model at the previous
joints), acting on the current estimate. Until an anchor reaches that
move's ply, the searches rank continuations that play the move that touch
plays (`envs.boards.games.BoardGame.zone_effects`) at that ply above the
others, after what the cells show and the moves already estimated: the
agent's own piece is often still hidden by the arm, and the estimate may
run unconfirmed ahead of the last anchor (a move under the hand). Without
it, a later search could take the agent's hidden move for a pass when the
hand hides it again (a pass changes fewer hidden cells).

Presses tell too: the hand standing blocked on one zone with no arm reset
(`hier_agents.estimators.presses`) means the game refused that move (its
point is taken, under the hand where the camera cannot see it), unless the
point is known empty since the last arm reset (read surely empty, or empty
in a confirmed estimate with the agent to move, as at the game's start when
the agent moves first): the board stands still in between, so the press
failed to register. Until the next reset, a
continuation in which that move is legal counts as contradicting a cell
read surely, so an opponent's reply hidden by the hand is not kept for a
pass. A pass is confirmed only once every empty cell, where a reply could
lie, was read surely.

Its camera (``env_overrides``): ``front_camera_2`` at `FRAME_SHAPE`, the
other camera off, rendered only when read (``lazy_cameras=True``).
"""

from __future__ import annotations

import numpy as np

from envs.boards.games import BoardGame
from hier_agents.estimators.base import Estimator
from hier_agents.estimators.board import scalar
from hier_agents.estimators.board_colours import BoardColours
from hier_agents.estimators.board_search import (
    BEAM,
    DEEP_BEAM,
    DEEP_MOVES,
    MAX_MOVES,
    Clues,
    ContinuationSearch,
    confirmed,
)
from hier_agents.estimators.board_view import EMPTY_CELL, SELECTED, UNSEEN, BoardView
from hier_agents.estimators.presses import TouchZones
from skills.scene import ArmScene

__all__ = [
    "BoardCameraEstimator",
    "CAMERA",
    "FRAME_SHAPE",
    "BEAM",
    "MAX_MOVES",
    "DEEP_BEAM",
    "DEEP_MOVES",
]

#: The camera read and its frame size (height, width).
CAMERA = "front_camera_2"
FRAME_SHAPE = (128, 128)
#: Frame schedule (see the module docstring): a frame is read at once when
#: a joint moved more than `ARM_JUMP` (rad) or the pinch site more than
#: `PINCH_JUMP` (m) in a step (the arm reset that follows a registered
#: move), while the estimate is unconfirmed, after a refused press and at
#: an episode's last step; every `FRAME_EVERY` steps while the pinch site is
#: within `TOUCH_HEIGHT` (m) of a zone's top (in this step or the last); and
#: every `FRAME_EVERY` steps in a game that selects a piece first (in every
#: game with ``still=False``). Measured on MuJoXO, MuJoGo and connect four
#: (5 to 9 games): touches registered with the pinch site at most 0.032 m
#: above the zone's top; the pinch site moved at most 0.028 m in a step of
#: play and at least 0.19 m at an arm reset.
FRAME_EVERY = 3
ARM_JUMP = 0.3
PINCH_JUMP = 0.08
TOUCH_HEIGHT = 0.07
#: Anchors tried back from the last when its continuations contradict a
#: cell read surely (the search: `hier_agents.estimators.board_search`).
BACKTRACK = 3


class BoardCameraEstimator(Estimator):
    """The game from the camera: `BoardView` reads each frame, legal
    continuations of the last confirmed state explain it. See the module
    docstring."""

    name = "camera"
    # Per episode, set by `reset`: the arm posture of the last estimate (None
    # before the first), the agent's last registered move (`Clues.played`)
    # until an anchor holds its ply, the cells read surely since the estimate
    # was made, the hand low over the board at the last estimate.
    _qpos: np.ndarray | None
    _played: tuple[int, int] | None
    _vouched: np.ndarray | None
    _low: bool
    _pinch: np.ndarray | None
    #: Its camera (see the module docstring).
    env_overrides = {"front_camera": None, CAMERA: FRAME_SHAPE, "lazy_cameras": True}

    def __init__(self, frame_every: int = FRAME_EVERY, still: bool = True) -> None:
        """``frame_every``: an integer >= 1, the steps between frames read
        while nothing else calls for one; ``still``: whether a confirmed
        estimate of a game whose every touch plays a move is kept without
        frames until the board can change (the module docstring's frame
        schedule). Raises ValueError on a bad ``frame_every``, TypeError on a
        ``still`` that is not a bool."""
        if not isinstance(frame_every, int) or isinstance(frame_every, bool) or frame_every < 1:
            raise ValueError(f"frame_every must be an integer >= 1, got {frame_every!r}")
        if not isinstance(still, bool):
            raise TypeError(f"still must be True or False, got {still!r}")
        self.frame_every = frame_every
        self.still = still
        self._views: dict[tuple[BoardGame, object, object], BoardView] = {}
        self._view: BoardView | None = None

    def reset(self, description, timestep) -> None:
        game = BoardGame.from_description(description)
        camera = getattr(description, CAMERA, None)
        key = (game, camera, getattr(description, "shadow_light", None))
        if key not in self._views:
            self._views[key] = BoardView(description, game, camera)
        view = self._view = self._views[key]
        self._game, self._spiel = game, game.load()
        # Frames between registered moves only where a touch can select a piece.
        self._every = self.frame_every if game.rules.input == "move" or not self.still else None
        self._agent = scalar(timestep.observation, "agent_player", 0)
        self._searcher = ContinuationSearch(game, self._agent)
        initial = self._spiel.new_initial_state()
        self._settle(initial)
        self._anchors = [initial]
        self._belief = initial.clone()
        self._selected = -1
        self._since, self._qpos = 0, None  # the first estimate reads
        self._played = None
        self._vouched = None
        self._low = False  # the hand low over the board at the last estimate
        self._pinch = None  # the pinch site's position then
        # The touch zones and the hand over them; the moves refused since
        # the last arm reset, and the cells known empty since then (`_refuse`).
        self._zones = TouchZones(description, view.half)
        self._refused: set[int] = set()
        self._empty_since_reset = np.zeros(len(description.point_positions), bool)
        self._known_empty(initial)
        # The empty board's colours and the arm shadow's share of light, from
        # the first frame on (nothing can stand out when the agent moves
        # first: no move was played).
        obs = timestep.observation
        qpos = obs["arm/joints_pos"]
        self._colours = BoardColours(
            view,
            game,
            self._anchor,
            view.samples(obs[CAMERA]),
            view.clear(qpos),
            check=not self._settled(self._anchor),
        )
        self._colours.learn_shade(obs[CAMERA], qpos, self._colours.filled(), self._anchor)

    def read(self, timestep):
        """(cells, hidden) of ``timestep``'s frame as `estimate` reads it
        (`BoardView.read` with the learnt background), without changing the
        estimate."""
        if self._view is None:
            raise RuntimeError("BoardCameraEstimator.read called before reset")
        obs = timestep.observation
        cells, hidden, _, _ = self._view.read(
            obs[CAMERA], obs["arm/joints_pos"], self._colours.filled(), self._colours.shade
        )
        return cells, hidden

    def _settle(self, state) -> None:
        """Plays the passes the referee plays (`ContinuationSearch.settle`)."""
        self._searcher.settle(state)

    def _settled(self, state) -> bool:
        """A state the agent can be shown (`ContinuationSearch.settled`)."""
        return self._searcher.settled(state)

    def _search(self, anchor, cells, fractions, over: bool, **options):
        """`ContinuationSearch.search` from ``anchor`` with this estimator's
        clues (its estimate, the agent's registered move, the refused moves,
        the selected piece)."""
        clues = Clues(self._belief, self._played, frozenset(self._refused), self._selected)
        return self._searcher.search(anchor, cells, fractions, clues, over, **options)

    def estimate(self, timestep) -> ArmScene:
        if self._view is None:
            raise RuntimeError("BoardCameraEstimator.estimate called before reset")
        obs = timestep.observation
        qpos = np.array(obs["arm/joints_pos"], float)
        self._since += 1
        first = self._qpos is None
        pinch = self._view.silhouette.pinch(qpos)
        jumped = not first and (
            np.abs(qpos - self._qpos).max() > ARM_JUMP
            or float(np.linalg.norm(pinch - self._pinch)) > PINCH_JUMP
        )
        if jumped:
            # The arm is reset only after a registered move: the touch that
            # played it was under the hand before the jump.
            self._register(self._zones.under(self._pinch))
        self._qpos, self._pinch = qpos, pinch
        refused = self._refuse(pinch, jumped)
        low, self._low = self._low, self._zones.within(pinch, TOUCH_HEIGHT)
        every = self.frame_every if low or self._low else self._every
        if (
            not first
            and (every is None or self._since < every)
            and not jumped
            and not refused
            and not timestep.last()
            and self._belief.history() == self._anchor.history()
            and self._settled(self._belief)
        ):
            return self._scene(qpos, obs)  # between frames: as last read
        self._since = 0
        colours = self._colours
        background = colours.filled()
        cells, hidden, selection, fractions = self._view.read(
            obs[CAMERA], qpos, background, colours.shade
        )
        seen = cells != UNSEEN
        self._empty_since_reset |= cells == EMPTY_CELL
        game = self._game
        players = game.players(self._belief)
        # The episode ended with the game (not at the time limit): the game is over.
        over = timestep.last() and float(timestep.discount or 0.0) == 0.0
        if (
            np.any(players[seen] != cells[seen])
            or not self._settled(self._belief)
            or (over and not self._belief.is_terminal())
            or jumped
            or refused
        ):
            self._belief = self._explain(cells, np.where(hidden[:, None], np.nan, fractions), over)
            self._vouched = seen & (game.players(self._belief) == cells)
        elif self._belief.history() != self._anchor.history():
            # The board stands still between two registered moves (the arm
            # resets at each, and the opponent replies at once): cells read
            # surely in any frame since the estimate was made vouch for it.
            self._vouched = seen if self._vouched is None else self._vouched | seen
            changed = game.players(self._anchor) != players
            if not np.any(changed & ~self._vouched) and not self._searcher.unseen_replies(
                self._anchor, self._belief, players, self._vouched
            ):
                self._confirm(self._belief)
        if self._belief.history() == self._anchor.history():
            if not colours.complete:
                colours.learn(
                    self._anchor,
                    self._view.samples(obs[CAMERA]),
                    self._view.clear(qpos, cells == EMPTY_CELL),
                )
            colours.learn_shade(obs[CAMERA], qpos, background, self._anchor)
        self._selected = self._selection(selection, hidden)
        return self._scene(qpos, obs)

    def _register(self, zone: int | None) -> None:
        """The agent's move registered by a touch on ``zone`` (None: no
        zone under the hand) acting on the current estimate, with the agent
        to move in it: its ply and action become ``_played`` (the search
        looks for it there until an anchor holds that ply: `_confirm`);
        else None."""
        self._played = None
        belief = self._belief
        if zone is None or belief.is_terminal() or belief.current_player() != self._agent:
            return
        game = self._game
        action = int(game.zone_effects(belief, self._selected)[0][min(zone, game.num_zones - 1)])
        if action >= 0:
            self._played = (len(belief.history()), action)

    def _refuse(self, pinch, jumped: bool) -> bool:
        """Follows presses (`TouchZones.blocked`); True when the press with
        the pinch site at ``pinch`` has just shown the game refused a move the estimate allows
        (the move joins ``_refused`` until the next arm reset: ``jumped``):
        not on a point known empty since that reset (`_known_empty`, or read
        surely empty). Only games whose
        every touch plays a move (not a piece's selection)."""
        if jumped:
            self._zones.reset()
            self._refused = set()
            self._empty_since_reset[:] = False
            return False
        game, belief = self._game, self._belief
        if game.rules.input == "move":
            return False
        zone = self._zones.blocked(pinch)
        if zone is None or belief.is_terminal() or belief.current_player() != self._agent:
            return False
        if zone < len(self._empty_since_reset) and self._empty_since_reset[zone]:
            # The board stands still between registered moves: a point known
            # empty since the last one (read surely empty, or empty in a
            # confirmed estimate with the agent to move) is empty still (and
            # its column not full); the press failed to register, the game
            # refused nothing.
            return False
        action = int(game.zone_effects(belief, self._selected)[0][min(zone, game.num_zones - 1)])
        if action < 0 or action == game.pass_action or action not in belief.legal_actions():
            return False
        self._refused.add(action)
        return True

    def _scene(self, qpos, obs) -> ArmScene:
        state = self._belief.clone()
        return ArmScene(
            state=state,
            moves=tuple(int(a) for a in state.history()),
            qpos=qpos,
            qvel=np.array(obs["arm/joints_vel"], float),
            selected=self._selected,
            agent=self._agent,
        )

    def _selection(self, selection, hidden) -> int:
        if self._game.rules.input != "move":
            return -1
        best = int(np.argmax(selection))
        if selection[best] >= SELECTED:
            return best
        if self._selected >= 0 and hidden[self._selected]:
            return self._selected  # under the arm: as last seen
        return -1

    @property
    def _anchor(self):
        return self._anchors[-1]

    def _explain(self, cells, fractions, over: bool):
        """The state that best explains a frame: the best continuation of the
        last anchor, or, when that contradicts a cell read surely, of one of
        the `BACKTRACK` anchors before it (a move first taken for a pass, or
        for another under the arm); later anchors are then dropped. A
        confirmed state becomes the last anchor."""
        tried = []
        believed = self._belief.history()
        for back in range(min(BACKTRACK, len(self._anchors))):
            anchor = self._anchors[-1 - back]
            state, score = self._search(anchor, cells, fractions, over)
            tried.append((score, back, state))
            before = anchor.history()
            if (
                (score.unfinished or score.wrong)
                and back == 0
                and len(believed) > len(before)
                and believed[: len(before)] == before
            ):
                # The beam ranks half-played continuations by the cells they
                # already explain, and can drop the true one when its next
                # moves flip cells it contradicts: from the current estimate
                # that continuation is moves shorter. Only when the last
                # anchor's search contradicts a cell read surely (always, it
                # kept MuJoGo's unconfirmed mistakes).
                state, score = self._search(anchor, cells, fractions, over, start=self._belief)
                tried.append((score, back, state))
            if any(not s.unfinished and s.wrong == 0 for s, _, _ in tried):
                break
        else:
            # Nothing near explains the frame: the game ran further ahead
            # while cells were hidden. A deeper, wider search from the last anchor.
            state, score = self._search(
                self._anchor, cells, fractions, over, max_moves=DEEP_MOVES, beam=DEEP_BEAM
            )
            tried.append((score, 0, state))
        score, back, state = min(tried, key=lambda t: (t[0], t[1]))
        if confirmed(score):
            self._confirm(state)
        return state

    def _confirm(self, state) -> None:
        """``state`` becomes the last anchor; anchors that are not earlier
        states of its game (an earlier estimate it rewrote) are dropped."""
        history = state.history()
        if self._played is not None and len(history) > self._played[0]:
            self._played = None  # the anchor holds the registered move's ply
        while len(self._anchors) > 1:
            before = self._anchor.history()
            if history[: len(before)] == before:
                break
            self._anchors.pop()
        self._anchors.append(state.clone())
        self._known_empty(state)

    def _known_empty(self, state) -> None:
        """A confirmed ``state`` with the agent to move stands until the
        agent's next registered move (an arm reset, which clears
        ``_empty_since_reset``): its empty cells are known empty until then."""
        if not state.is_terminal() and self._settled(state):
            self._empty_since_reset |= self._game.players(state) == EMPTY_CELL
