"""`ContinuationSearch`: the legal continuations of a game that best explain a frame.

The board games' camera estimator
(`hier_agents.estimators.camera_board.BoardCameraEstimator`) keeps the game
as OpenSpiel states; when a frame read (`hier_agents.estimators.board_view.
BoardView.read`) disagrees with its estimate, this search extends an
*anchor* (a state the frames confirmed) by legal moves, `BEAM` states per
move, at most `MAX_MOVES` moves ahead (or `DEEP_BEAM` and `DEEP_MOVES`
when asked), and ranks every continuation with the agent to move (or the
game over) by its `Score`. What the estimator knows beyond the frame (its
current estimate, the touch that played the agent's last move, the moves
the game refused, the selected piece) comes in as `Clues`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, NamedTuple

import numpy as np

from envs.boards.games import BoardGame
from hier_agents.estimators.board_view import UNSEEN

__all__ = [
    "BEAM",
    "Clues",
    "ContinuationSearch",
    "DEEP_BEAM",
    "DEEP_MOVES",
    "MAX_MOVES",
    "Score",
    "confirmed",
]

#: States kept per move, and moves looked ahead of an anchor.
BEAM = 8
MAX_MOVES = 8
#: The deeper search's (when no anchor's usual search explains a frame).
DEEP_BEAM = 16
DEEP_MOVES = 16
#: Searches remembered (by their inputs) before the memory is cleared.
CACHE_SIZE = 256


class Score(NamedTuple):
    """How well a continuation explains a frame; lower is better (compared
    field by field, in this order)."""

    #: Finished or not, unlike the episode (a game that ended with it).
    unfinished: bool
    #: Cells read surely and contradicted, and refused moves it allows.
    wrong: int
    #: Distance between the visible cells' colour shares and its pieces.
    soft: float
    #: 1 when it rewrites moves of the current estimate.
    rewrite: int
    #: 1 when it does not play the agent's registered move (`Clues.played`) at its ply.
    miss: int
    #: Cells changed since the anchor and not read surely.
    blind: int
    #: After an opponent's pass, empty cells not read surely (a reply could lie there).
    replies: int


def confirmed(score: Score) -> bool:
    """Whether a score explains the frame: not unfinished at the game's end,
    no cell read surely contradicted, every changed cell read surely, and
    after an opponent's pass every empty cell read surely."""
    return not score.unfinished and score.wrong == 0 and score.blind == 0 and score.replies == 0


@dataclass(frozen=True)
class Clues:
    """What the estimator knows beyond the frame.

    Attributes:
      belief: the current estimate (an OpenSpiel state, settled).
      played: the agent's last registered move, (ply, action): the action
        the touch under the hand before the last arm reset played, acting
        on the estimate of then, whose length is the ply; or None.
      refused: actions the game refused since the last arm reset.
      selected: the selected piece's point (move games), -1 for none.
    """

    belief: Any
    played: tuple[int, int] | None = None
    refused: frozenset[int] = frozenset()
    selected: int = -1

    def key(self) -> tuple:
        """The clues as a hashable key (the belief by its history)."""
        return (
            tuple(self.belief.history()),
            self.played,
            tuple(sorted(self.refused)),
            self.selected,
        )


class ContinuationSearch:
    """Searches the legal continuations of one game for an agent.

    Args:
      game: the episode's `envs.boards.games.BoardGame`.
      agent: the agent's player (0 or 1).

    Attributes:
      searches: searches run (not answered from memory).
    """

    def __init__(self, game: BoardGame, agent: int) -> None:
        self.game, self.agent = game, int(agent)
        self.searches = 0
        self._cache: dict[tuple[object, ...], tuple[Any, Score]] = {}

    def settle(self, state) -> None:
        """Plays the passes the referee plays (`BoardGame.forced_pass`)."""
        forced = self.game.forced_pass(state)
        while forced is not None:
            state.apply_action(forced)
            forced = self.game.forced_pass(state)

    def settled(self, state) -> bool:
        """A state the agent can be shown: the agent to move, or the end."""
        return state.is_terminal() or state.current_player() == self.agent

    def search(
        self,
        anchor,
        cells: np.ndarray,
        fractions: np.ndarray,
        clues: Clues,
        over: bool = False,
        max_moves: int = MAX_MOVES,
        beam: int = BEAM,
        start=None,
    ) -> tuple[Any, Score]:
        """(state, score): the best-explaining settled continuation of
        ``anchor`` and its `Score`; the fewest moves among equal scores.

        Args:
          anchor: the state searched from (an OpenSpiel state, settled).
          cells: (n,) each cell as read: a player, empty, or unseen.
          fractions: (n, 2) each visible cell's share of each piece colour
            (NaN under the arm).
          clues: what else is known (`Clues`).
          over: the episode ended with the game: only a finished game is
            accepted, if one is found.
          max_moves, beam: moves looked ahead, states kept per move.
          start: a settled continuation of ``anchor`` (the current estimate)
            to search from instead; the score still counts what changed
            since ``anchor``.

        Returns the current estimate, unconfirmed, when no settled state is
        within reach. The answer is a fresh state (the caller may play on it).
        """
        start = anchor if start is None else start
        key = (
            tuple(anchor.history()),
            tuple(start.history()),
            clues.key(),
            max_moves,
            beam,
            cells.tobytes(),
            np.round(np.nan_to_num(fractions, nan=-1.0) * 20).astype(np.int8).tobytes(),
            over,
        )
        if key in self._cache:
            state, score = self._cache[key]
            return state.clone(), score
        self.searches += 1
        scorer = self._scorer(anchor, cells, fractions, clues, over)
        start = start.clone()
        best = (scorer(start), 0, start) if self.settled(start) else None
        frontier = [start]
        for depth in range(1, max_moves + 1):
            children = self._expand(frontier, scorer)
            if not children:
                break
            for s, child in children:
                if self.settled(child) and (best is None or (s, depth) < (best[0], best[1])):
                    best = (s, depth, child)
            if best is not None and confirmed(best[0]) and not best[0].miss:
                break
            frontier = self._beam(children, beam)
        if best is None:  # nothing settled within reach: keep the estimate, unconfirmed
            n = len(cells)
            result = (clues.belief.clone(), Score(True, n, 0.0, 0, 1, n, 0))
        else:
            result = (best[2], best[0])
        if len(self._cache) > CACHE_SIZE:
            self._cache.clear()
        self._cache[key] = (result[0].clone(), result[1])
        return result

    def unseen_replies(self, anchor, state, players: np.ndarray, seen: np.ndarray) -> int:
        """After an opponent's pass since ``anchor`` in ``state`` (games with
        a pass area: Go), the empty cells of ``state`` (``players``) not in
        ``seen``: a reply could lie there, so the pass is not yet told from
        a move; else 0."""
        pass_action = self.game.pass_action
        tail = state.history()[len(anchor.history()) :]
        if pass_action is None or pass_action not in tail:
            return 0
        replay = anchor.clone()
        for action in tail:
            if action == pass_action and replay.current_player() != self.agent:
                return int(np.count_nonzero((players < 0) & ~seen))
            replay.apply_action(action)
        return 0

    def _scorer(self, anchor, cells, fractions, clues: Clues, over: bool) -> Callable[[Any], Score]:
        """The `Score` of a continuation ``state`` of ``anchor`` (the
        fields' order is the ranking's). The registered move (`Clues.played`)
        is looked for at its ply (an unconfirmed part of the estimate may lie
        between ``anchor`` and that move). A refused move the state allows
        counts as a cell read surely and contradicted; in point games so does
        a piece of the agent's put down on a refused point (none is without
        an arm reset)."""
        game, agent, belief = self.game, self.agent, clues.belief
        visible = ~np.isnan(fractions[:, 0])
        seen = cells != UNSEEN
        unseen, cells_seen = ~seen, cells[seen]
        base = game.players(anchor)
        shares = fractions[visible]
        # |share - piece| per visible point and channel, for each owner a
        # point can have (-1, 0, 1 -> rows 0, 1, 2): `soft` gathers its rows.
        costs = np.abs(shares[None] - np.array([[0, 0], [1, 0], [0, 1]], bool)[:, None])
        columns = np.arange(len(shares))
        believed = list(belief.history())
        ply, played = clues.played if clues.played is not None else (0, None)
        refused = tuple(clues.refused)
        by_point = game.rules.input == "point"

        def score(state) -> Score:
            players = game.players(state)
            wrong = int(np.count_nonzero(players[seen] != cells_seen))
            if refused:  # the game runs, and refused them: as cells read surely
                if state.is_terminal() or state.current_player() != agent:
                    wrong += len(refused)
                else:
                    legal = set(state.legal_actions())
                    wrong += sum(action in legal for action in refused)
                    if by_point:
                        own = (players == agent) & (base != agent)
                        wrong += sum(bool(own[a]) for a in refused if a < len(own))
            history = state.history()
            common = min(len(history), len(believed))
            return Score(
                unfinished=over != state.is_terminal(),
                wrong=wrong,
                soft=round(float(costs[players[visible] + 1, columns].sum()), 3),
                rewrite=int(history[:common] != believed[:common]),
                miss=int(played is not None and (len(history) <= ply or history[ply] != played)),
                blind=int(np.count_nonzero((players != base) & unseen)),
                replies=self.unseen_replies(anchor, state, players, seen),
            )

        return score

    def _expand(self, frontier, score) -> list:
        """Every legal move's child of the unfinished states of ``frontier``,
        settled, as (score, child) pairs, best score first (stable)."""
        children = []
        for state in frontier:
            if state.is_terminal():
                continue
            for action in state.legal_actions():
                child = state.child(action)
                self.settle(child)
                children.append((score(child), child))
        children.sort(key=lambda item: item[0])
        return children

    def _beam(self, children, beam: int) -> list:
        """The next frontier: the first ``beam`` unfinished ``children`` (best
        first), one per board and player to move."""
        game = self.game
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
