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
The search keeps `BEAM` states per move and looks at most `MAX_MOVES`
moves ahead; when no anchor's does explain the frame (the game ran on
while the changed cells stayed hidden), one search from the last anchor
keeps `DEEP_BEAM` states and looks `DEEP_MOVES` ahead. A frame that the
current estimate already explains costs no search. When an episode ends with the game (a terminal
timestep, discount 0), a finished game is preferred: the winning piece may
still be under the hand.

Frame schedule: a frame is read every `FRAME_EVERY` steps, and at once when
the arm's joints jump (the arm reset after a registered move), while the
estimate is not confirmed, and at the episode's last step; in between the
last estimate is returned with the new joints.

The arm reset tells more: a move was registered, by the touch under the
pinch site just before the jump (the arm's own model at the previous
joints), acting on the current estimate. The next search then ranks
continuations in which the agent's move after that estimate is the move
that touch plays (`envs.boards.games.BoardGame.zone_effects`) above the
others, after what the cells show and the moves already estimated: the
agent's own piece is often still hidden by the arm, and the estimate may
run unconfirmed ahead of the last anchor (a move under the hand).

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

from typing import Any

import numpy as np

from envs.boards.games import BoardGame
from hier_agents.estimators.base import Estimator
from hier_agents.estimators.board import scalar
from hier_agents.estimators.board_colours import BoardColours
from hier_agents.estimators.board_view import EMPTY_CELL, SELECTED, UNSEEN, BoardView
from hier_agents.estimators.presses import TouchZones
from skills.scene import ArmScene

__all__ = ["BoardCameraEstimator", "CAMERA", "FRAME_SHAPE"]

#: The camera read and its frame size (height, width).
CAMERA = "front_camera_2"
FRAME_SHAPE = (128, 128)
#: Frame schedule: a frame is read every `FRAME_EVERY` steps, and at once
#: when a joint moved more than `ARM_JUMP` (rad) in a step (the arm reset
#: that follows a registered move), while the estimate is unconfirmed, and
#: at an episode's last step.
FRAME_EVERY = 3
ARM_JUMP = 0.3
#: Search: states kept per move, moves looked ahead of an anchor, and
#: anchors tried back from the last.
BEAM = 8
MAX_MOVES = 8
BACKTRACK = 3
#: When no anchor's search explains a frame (every cell read surely): one
#: more search from the last anchor, keeping `DEEP_BEAM` states per move
#: and looking `DEEP_MOVES` moves ahead.
DEEP_BEAM = 16
DEEP_MOVES = 16


def _confirmed(score) -> bool:
    """Whether a `BoardCameraEstimator._search` score explains the frame: not
    unfinished at the game's end, no cell read surely contradicted, every
    changed cell read surely, and after an opponent's pass every empty cell
    read surely (a reply could lie there)."""
    return not score[0] and score[1] == 0 and score[5] == 0 and score[6] == 0


class BoardCameraEstimator(Estimator):
    """The game from the camera: `BoardView` reads each frame, legal
    continuations of the last confirmed state explain it. See the module
    docstring."""

    name = "camera"
    # Per episode, set by `reset`: the arm posture of the last estimate (None
    # before the first), the zone a touch hit before the arm jumped back, the
    # cells read surely since the estimate was made.
    _qpos: np.ndarray | None
    _touched: int | None
    _vouched: np.ndarray | None
    #: Its camera (see the module docstring).
    env_overrides = {"front_camera": None, CAMERA: FRAME_SHAPE, "lazy_cameras": True}

    def __init__(self, frame_every: int = FRAME_EVERY) -> None:
        if not isinstance(frame_every, int) or isinstance(frame_every, bool) or frame_every < 1:
            raise ValueError(f"frame_every must be an integer >= 1, got {frame_every!r}")
        self.frame_every = frame_every
        self._views: dict[tuple[BoardGame, object, object], BoardView] = {}
        self._view: BoardView | None = None
        self.searches = 0

    def reset(self, description, timestep) -> None:
        game = BoardGame.from_description(description)
        camera = getattr(description, CAMERA, None)
        key = (game, camera, getattr(description, "shadow_light", None))
        if key not in self._views:
            self._views[key] = BoardView(description, game, camera)
        view = self._view = self._views[key]
        self._game, self._spiel = game, game.load()
        self._agent = scalar(timestep.observation, "agent_player", 0)
        initial = self._spiel.new_initial_state()
        self._settle(initial)
        self._anchors = [initial]
        self._belief = initial.clone()
        self._selected = -1
        # `_search`'s results: (state, score) by the search's inputs.
        self._cache: dict[tuple[object, ...], tuple[Any, tuple[Any, ...]]] = {}
        self._since, self._qpos = self.frame_every, None  # the first estimate reads
        self._touched = None
        self._vouched = None
        # The touch zones and the hand over them; the moves refused since
        # the last arm reset, and the cells known empty since then (`_refuse`).
        self._zones = TouchZones(description, view.half, view.silhouette.pinch)
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
        """Plays the passes the referee plays (`BoardGame.forced_pass`)."""
        forced = self._game.forced_pass(state)
        while forced is not None:
            state.apply_action(forced)
            forced = self._game.forced_pass(state)

    def _settled(self, state) -> bool:
        """A state the agent can be shown: the agent to move, or the end."""
        return state.is_terminal() or state.current_player() == self._agent

    def estimate(self, timestep) -> ArmScene:
        if self._view is None:
            raise RuntimeError("BoardCameraEstimator.estimate called before reset")
        obs = timestep.observation
        qpos = np.array(obs["arm/joints_pos"], float)
        self._since += 1
        jumped = self._qpos is not None and np.abs(qpos - self._qpos).max() > ARM_JUMP
        if jumped:
            # The arm is reset only after a registered move: the touch that
            # played it was under the hand before the jump.
            self._touched = self._zones.touched(self._qpos)
        self._qpos = qpos
        refused = self._refuse(qpos, jumped)
        if (
            self._since < self.frame_every
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
            or self._touched is not None
            or refused
        ):
            self._belief = self._explain(cells, np.where(hidden[:, None], np.nan, fractions), over)
            self._touched = None
            self._vouched = seen & (game.players(self._belief) == cells)
        elif self._belief.history() != self._anchor.history():
            # The board stands still between two registered moves (the arm
            # resets at each, and the opponent replies at once): cells read
            # surely in any frame since the estimate was made vouch for it.
            self._vouched = seen if self._vouched is None else self._vouched | seen
            changed = game.players(self._anchor) != players
            if not np.any(changed & ~self._vouched) and not self._unseen_replies(
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

    def _refuse(self, qpos, jumped: bool) -> bool:
        """Follows presses (`TouchZones.blocked`); True when the press at
        ``qpos`` has just shown the game refused a move the estimate allows
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
        zone = self._zones.blocked(qpos)
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
                (score[0] or score[1])
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
            if any(not s[0] and s[1] == 0 for s, _, _ in tried):
                break
        else:
            # Nothing near explains the frame: the game ran further ahead
            # while cells were hidden. A deeper, wider search from the last anchor.
            state, score = self._search(self._anchor, cells, fractions, over, DEEP_MOVES, DEEP_BEAM)
            tried.append((score, 0, state))
        score, back, state = min(tried, key=lambda t: (t[0], t[1]))
        if _confirmed(score):
            self._confirm(state)
        return state

    def _confirm(self, state) -> None:
        """``state`` becomes the last anchor; anchors that are not earlier
        states of its game (an earlier estimate it rewrote) are dropped."""
        history = state.history()
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

    def _search(
        self,
        anchor,
        cells,
        fractions,
        over: bool = False,
        max_moves: int = MAX_MOVES,
        beam: int = BEAM,
        start=None,
    ):
        """(state, score): the best-explaining continuation of ``anchor`` and
        its score (see the module docstring).
        ``fractions`` (n, 2): each visible cell's share of each piece colour
        (NaN under the arm); with ``over`` (the episode ended with the game)
        only a finished game is accepted, if one is found. ``start``: a
        settled continuation of ``anchor`` (the current estimate) to search
        from instead; the score still counts what changed since ``anchor``."""
        start = anchor if start is None else start
        key = (
            tuple(anchor.history()),
            tuple(start.history()),
            tuple(self._belief.history()),  # the score's reference (`_scorer`)
            max_moves,
            beam,
            cells.tobytes(),
            self._touched,
            tuple(sorted(self._refused)),
            self._selected,
            np.round(np.nan_to_num(fractions, nan=-1.0) * 20).astype(np.int8).tobytes(),
            over,
        )
        if key in self._cache:
            state, score = self._cache[key]
            return state.clone(), score
        self.searches += 1
        score = self._scorer(anchor, cells, fractions, over)
        start = start.clone()
        best = (score(start), 0, start) if self._settled(start) else None
        frontier = [start]
        for depth in range(1, max_moves + 1):
            children = self._expand(frontier, score)
            if not children:
                break
            for s, child in children:
                if self._settled(child) and (best is None or (s, depth) < (best[0], best[1])):
                    best = (s, depth, child)
            if best is not None and _confirmed(best[0]) and not best[0][4]:
                break
            frontier = self._beam(children, beam)
        if best is None:  # nothing settled within reach: keep the estimate, unconfirmed
            result = (self._belief.clone(), (True, len(cells), 0.0, 0, 1, len(cells), 0))
        else:
            result = (best[2], best[0])
        if len(self._cache) > 256:
            self._cache.clear()
        self._cache[key] = (result[0].clone(), result[1])
        return result

    def _scorer(self, anchor, cells, fractions, over: bool):
        """The score `_search` ranks a continuation ``state`` of ``anchor`` by,
        lower is better:
        (finished or not unlike the episode, cells read surely and
        contradicted (and moves the game refused, `_refuse`, that the state
        allows), how far the visible cells' colour shares are from the
        state's pieces, rewriting moves of the current estimate (two orders
        of the same moves can give one board), not continuing the current
        estimate with the move the touch before an arm reset played (the
        agent acted on that estimate: an unconfirmed part of it may lie
        between ``anchor`` and that move), cells changed
        since ``anchor`` not read surely, after an opponent's pass since
        ``anchor`` the empty cells not read surely (`_unseen_replies`): only
        a tie-break, it holds back the pass's confirmation, not the pass)."""
        game = self._game
        visible = ~np.isnan(fractions[:, 0])
        seen = cells != UNSEEN
        base = game.players(anchor)
        shares = fractions[visible]
        # The action the touch before an arm reset played, and its place in
        # the game: the agent touched it acting on the current estimate.
        believed = list(self._belief.history())
        played, ply = None, len(believed)
        if self._touched is not None and self._belief.current_player() == self._agent:
            zone = min(self._touched, game.num_zones - 1)
            action = game.zone_effects(self._belief, self._selected)[0][zone]
            played = int(action) if action >= 0 else None
        refused = tuple(self._refused)
        by_point = game.rules.input == "point"

        def score(state):
            players = game.players(state)
            wrong = int(np.count_nonzero(players[seen] != cells[seen]))
            if refused:  # the game runs, and refused them: as cells read surely
                if state.is_terminal() or state.current_player() != self._agent:
                    wrong += len(refused)
                else:
                    legal = set(state.legal_actions())
                    wrong += sum(action in legal for action in refused)
                    if by_point:  # no piece of the agent's is put down without an arm reset
                        own = (players == self._agent) & (base != self._agent)
                        wrong += sum(bool(own[a]) for a in refused if a < len(own))
            pieces = np.stack([players[visible] == 0, players[visible] == 1], axis=1)
            soft = round(float(np.abs(shares - pieces).sum()), 3)
            history = state.history()
            miss = played is not None and (len(history) <= ply or history[ply] != played)
            blind = int(np.count_nonzero((players != base) & ~seen))
            replies = self._unseen_replies(anchor, state, players, seen)
            common = min(len(history), len(believed))
            rewrite = history[:common] != believed[:common]
            return (
                over != state.is_terminal(),  # the game ends when the episode does
                wrong,
                soft,
                int(rewrite),
                int(miss),
                blind,
                replies,
            )

        return score

    def _unseen_replies(self, anchor, state, players, seen) -> int:
        """After an opponent's pass since ``anchor`` in ``state`` (games with
        a pass area: Go), the empty cells of ``state`` (``players``) not in
        ``seen``: a reply could lie there, so the pass is not yet told from
        a move; else 0."""
        pass_action = self._game.pass_action
        tail = state.history()[len(anchor.history()) :]
        if pass_action is None or pass_action not in tail:
            return 0
        replay = anchor.clone()
        for action in tail:
            if action == pass_action and replay.current_player() != self._agent:
                return int(np.count_nonzero((players < 0) & ~seen))
            replay.apply_action(action)
        return 0

    def _expand(self, frontier, score) -> list:
        """Every legal move's child of the unfinished states of ``frontier``,
        settled, as (score, child) pairs, best score first (stable)."""
        children = []
        for state in frontier:
            if state.is_terminal():
                continue
            for action in state.legal_actions():
                child = state.child(action)
                self._settle(child)
                children.append((score(child), child))
        children.sort(key=lambda item: item[0])
        return children

    def _beam(self, children, beam: int) -> list:
        """The next frontier: the first ``beam`` unfinished ``children`` (best
        first), one per board and player to move."""
        game = self._game
        frontier, boards = [], set()
        for _, child in children:
            board = (game.players(child).tobytes(), child.current_player())
            if board in boards or child.is_terminal():
                continue
            boards.add(board)
            frontier.append(child)
            if len(frontier) >= beam:
                break
        return frontier
