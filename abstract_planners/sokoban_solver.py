"""An exact Sokoban solver and the `SokobanSolverPlanner` built on it.

`solve` is complete and correct (every solution it returns is replayed
through the rules of `abstract_planners.sokoban` first, and it only reports
``"unsolvable"`` after exhausting a search space whose pruning never removes
every solution), but not optimal: it is tuned to find *a* solution fast.

Algorithm
=========

The board encoding, the lower bound ``h`` and the deadlock and PI-corral
pruning of children are described in `abstract_planners.sokoban_board`.

**Search space: pushes.** A search node is a box set plus the player's
*reachable region*: walking does not change the boxes, so states that differ
only in where the player stands inside the same region are the same node.
The region is a bitboard flood fill (``reach |= shifts(reach) & free`` until
it stops growing), and the node key is ``(boxes, lowest reachable cell)``.
The successors of a node are the pushes: box ``b`` in direction ``d`` when
the player can reach ``b - d`` and ``b + d`` is free. Walking moves are only
recovered at the end, by a breadth-first path search between pushes.

**Best-first order.** Nodes are expanded in weighted best-first order,
smallest ``g + 3 h`` first (``g`` the pushes so far, ``h`` a lower bound on
the pushes still needed; ties: smaller ``h``, then newest). The weight makes
the search greedy, so solutions are found fast but are not push-optimal.
A transposition table (the closed set) holds every expanded node with its
parent, from which the push sequence is read back; per box set it also keeps
the union of the expanded player regions, so a duplicate is recognised by one
bit test before it is queued or flood-filled again.

**Budget.** ``time_limit`` (seconds) and ``max_nodes`` (expansions) bound
the search; running out returns ``reason="budget"``. An exhausted open list
returns ``reason="unsolvable"``.
"""

from __future__ import annotations

import heapq
import time
from collections import deque
from dataclasses import dataclass

from abstract_planners.base import NoPlanError, Planner, Subgoal
from abstract_planners.sokoban import MOVES, SokobanState, replay
from abstract_planners.sokoban_board import (
    _INF,
    _Board,
    _Matching,
    _as_state,
    _bits,
    _board_for,
    _corral_pushes,
    _freeze_deadlock,
    _mask,
    dead_squares,
    frozen_deadlock,
    pi_corral_pushes,
)

__all__ = [
    "SokobanSolverPlanner",
    "SolveResult",
    "dead_squares",
    "frozen_deadlock",
    "pi_corral_pushes",
    "solve",
]

#: Expansions between two clock reads.
_CLOCK_EVERY = 128
#: Weight of the lower bound in the best-first priority ``g + WEIGHT * h``.
#: Measured on the shipped Boxoban files: 3 expands 8-18 % fewer nodes than
#: pure greedy (``h`` alone) and 25-50 % fewer than A* (weight 1), for
#: solutions about 5 % longer in pushes than A*'s.
_WEIGHT = 3


@dataclass(frozen=True)
class SolveResult:
    """The outcome of `solve`.

    Attributes:
      solved: whether a solution was found.
      moves: the solution's move letters, walking included (empty if not
        solved or if the state was already solved).
      pushes: how many of ``moves`` push a box.
      nodes: search nodes expanded.
      ms: wall time in milliseconds.
      reason: ``"solved"``, ``"unsolvable"`` (proved: the search space was
        exhausted) or ``"budget"`` (time or node budget ran out).
    """

    solved: bool
    moves: tuple = ()
    pushes: int = 0
    nodes: int = 0
    ms: float = 0.0
    reason: str = "solved"


# -- the search -----------------------------------------------------------------------


def solve(
    state,
    *,
    time_limit: float | None = 10.0,
    max_nodes: int | None = None,
) -> SolveResult:
    """Solve a Sokoban state (see the module docstring for the algorithm).

    Args:
      state: a `SokobanState` or a level-like object (see
        `SokobanState.from_level`).
      time_limit: seconds before giving up with ``reason="budget"`` (None: no
        limit).
      max_nodes: expansions before giving up with ``reason="budget"`` (None:
        no limit).

    Returns:
      A `SolveResult`; when solved, ``replay(state, result.moves)`` is solved.

    Raises:
      ValueError: for a non-positive ``time_limit`` or ``max_nodes``.
    """
    if time_limit is not None and not time_limit > 0:
        raise ValueError(f"time_limit must be positive seconds or None, got {time_limit!r}")
    if max_nodes is not None and max_nodes < 1:
        raise ValueError(f"max_nodes must be a positive integer or None, got {max_nodes!r}")
    t0 = time.perf_counter()
    deadline = None if time_limit is None else t0 + time_limit
    state = _as_state(state)
    board = _board_for(state)

    def result(solved, reason, moves=(), pushes=0, nodes=0):
        ms = (time.perf_counter() - t0) * 1000.0
        return SolveResult(
            solved=solved, moves=tuple(moves), pushes=pushes, nodes=nodes, ms=ms, reason=reason
        )

    if state.is_solved():
        return result(True, "solved")
    boxes0 = _mask(board.index(r, c) for r, c in state.boxes)
    if boxes0 & board.dead or any(_freeze_deadlock(board, b, boxes0) for b in _bits(boxes0)):
        return result(False, "unsolvable")
    heuristic = _Matching(board)
    h0 = heuristic(boxes0)
    if h0 >= _INF:
        return result(False, "unsolvable")

    steps = board.steps
    wall, dead, goal = board.wall, board.dead, board.target_mask
    shift = board.key_shift
    reach_of = board.reach
    push = heapq.heappush
    pop = heapq.heappop
    # Open list entries: (priority, h, -counter, g, boxes, player cell, parent key,
    # pushed box, direction); ties go to the smaller bound, then the newest.
    counter = 0
    heap = [(_WEIGHT * h0, h0, 0, 0, boxes0, board.index(*state.player), -1, -1, -1)]
    # closed: node key -> (parent key, pushed box, direction), for read-back.
    # covered: box set -> union of the expanded player regions with it, so a
    # duplicate (same boxes, player in an expanded region) is recognised by a
    # bit test, without a flood fill.
    closed: dict[int, tuple[int, int, int]] = {}
    covered: dict[int, int] = {}
    nodes = 0
    while heap:
        _f, _h, _c, g, boxes, player, parent, pushed, direction = pop(heap)
        regions = covered.get(boxes, 0)
        if (regions >> player) & 1:
            continue
        reach = reach_of(player, boxes)
        covered[boxes] = regions | reach
        key = (boxes << shift) | ((reach & -reach).bit_length() - 1)
        closed[key] = (parent, pushed, direction)
        nodes += 1
        if max_nodes is not None and nodes > max_nodes:
            return result(False, "budget", nodes=nodes - 1)
        if deadline is not None and nodes % _CLOCK_EVERY == 0 and time.perf_counter() > deadline:
            return result(False, "budget", nodes=nodes)

        candidates = _corral_pushes(board, boxes, reach)
        if candidates is None:
            blocked = wall | dead | boxes
            candidates = [
                (b, d)
                for b in _bits(boxes)
                for d, s in enumerate(steps)
                if (reach >> (b - s)) & 1 and not (blocked >> (b + s)) & 1
            ]
        g1 = g + 1
        for b, d in candidates:
            to = b + steps[d]
            new_boxes = boxes ^ (1 << b) ^ (1 << to)
            if new_boxes == goal:
                pushes = _read_pushes(closed, key) + [(b, d)]
                moves = _walk_and_push(board, state, pushes)
                final = replay(state, moves)
                if not final.is_solved():  # pragma: no cover - a solver bug
                    raise AssertionError("solver produced a non-solution: " + "".join(moves))
                return result(True, "solved", moves, len(pushes), nodes)
            if (covered.get(new_boxes, 0) >> b) & 1:
                continue
            if _freeze_deadlock(board, to, new_boxes):
                continue
            h = heuristic(new_boxes)
            if h >= _INF:
                continue
            counter -= 1
            push(heap, (g1 + _WEIGHT * h, h, counter, g1, new_boxes, b, key, b, d))
    return result(False, "unsolvable", nodes=nodes)


def _read_pushes(closed: dict, key: int) -> list[tuple[int, int]]:
    """The (box cell, direction) pushes leading to the node ``key``."""
    pushes = []
    parent, pushed, direction = closed[key]
    while parent != -1:
        pushes.append((pushed, direction))
        parent, pushed, direction = closed[parent]
    pushes.reverse()
    return pushes


def _walk_and_push(board: _Board, state: SokobanState, pushes) -> list[str]:
    """Move letters for ``pushes``: a shortest walk to each push, then the push."""
    moves: list[str] = []
    boxes = _mask(board.index(r, c) for r, c in state.boxes)
    player = board.index(*state.player)
    steps = board.steps
    for b, d in pushes:
        moves.extend(_walk(board, player, b - steps[d], boxes))
        moves.append(MOVES[d])
        boxes ^= (1 << b) ^ (1 << (b + steps[d]))
        player = b
    return moves


def _walk(board: _Board, start: int, goal: int, boxes: int) -> list[str]:
    """Shortest walk (letters) from cell ``start`` to ``goal`` around the boxes."""
    if start == goal:
        return []
    free = board.floor & ~boxes
    parent: dict[int, tuple[int, int] | None] = {start: None}
    queue = deque([start])
    while queue:
        x = queue.popleft()
        for d, s in enumerate(board.steps):
            y = x + s
            if y in parent or not (free >> y) & 1:
                continue
            parent[y] = (x, d)
            if y == goal:
                letters = []
                while (step := parent[y]) is not None:
                    y, d = step
                    letters.append(MOVES[d])
                letters.reverse()
                return letters
            queue.append(y)
    raise AssertionError(f"solver bug: no walk from {board.cell(start)} to {board.cell(goal)}")


# -- the planner ----------------------------------------------------------------------


class SokobanSolverPlanner(Planner):
    """Plans with `solve` and follows the solution while the world does.

    ``plan(state)`` solves ``state`` (unless it lies on the cached solution)
    and returns the first move as a `Subgoal`: ``action`` the move letter,
    ``state`` the state after it, ``plan`` the remaining moves, ``info``
    with ``nodes`` (expanded by this call; 0 when the cached plan was used),
    ``ms`` (this call's time), ``pushes`` (pushes left in the plan from the
    planned-from state) and ``cached``.

    ``next_push(state)`` is the same at push granularity: ``action`` is the
    tuple of moves up to and including the next push (the walk to the box,
    then the push), ``state`` the state after that push.

    Raises (both methods):
      ValueError: for an already solved state.
      NoPlanError: reason ``"unsolvable"`` (proved) or ``"budget"``.
    """

    name = "sokoban-solver"

    def __init__(self, time_limit: float | None = 10.0, max_nodes: int | None = None) -> None:
        if time_limit is not None and not time_limit > 0:
            raise ValueError(f"time_limit must be positive seconds or None, got {time_limit!r}")
        if max_nodes is not None and max_nodes < 1:
            raise ValueError(f"max_nodes must be a positive integer or None, got {max_nodes!r}")
        self.time_limit = time_limit
        self.max_nodes = max_nodes
        self._index: dict[SokobanState, int] = {}
        self._states: list[SokobanState] = []
        self._moves: tuple[str, ...] = ()
        self._is_push: tuple[bool, ...] = ()

    def __repr__(self) -> str:
        return f"SokobanSolverPlanner(time_limit={self.time_limit!r})"

    def reset(self, seed: int | None = None) -> None:
        """Forgets the cached solution (the solver is deterministic: ``seed`` is unused)."""
        self._index, self._states, self._moves, self._is_push = {}, [], (), ()

    def search(self, state) -> SolveResult:
        """The search behind the plans, from ``state`` (a `SolveResult`;
        subclasses may search otherwise)."""
        return solve(state, time_limit=self.time_limit, max_nodes=self.max_nodes)

    def _locate(self, state) -> tuple[SokobanState, int, dict]:
        """(state, its index in the cached solution, search info), solving if needed."""
        t0 = time.perf_counter()
        state = _as_state(state)
        if state.is_solved():
            raise ValueError("the state is already solved: there is nothing to plan")
        i = self._index.get(state)
        if i is not None:
            return state, i, {"nodes": 0, "ms": (time.perf_counter() - t0) * 1000.0, "cached": True}
        found = self.search(state)
        if not found.solved:
            self.reset()
            if found.reason == "unsolvable":
                message = "no solution: the Sokoban state is unsolvable (deadlocked)"
            else:
                message = (
                    f"no solution found within the budget (time_limit="
                    f"{self.time_limit}s, max_nodes={self.max_nodes}, "
                    f"{found.nodes} nodes expanded)"
                )
            raise NoPlanError(message, reason=found.reason)
        states = [state]
        pushes = []
        for move in found.moves:
            pushes.append(states[-1].is_push(move))
            states.append(states[-1].apply(move))
        self._states, self._moves, self._is_push = states, found.moves, tuple(pushes)
        self._index = {}
        for k, s in enumerate(states[:-1]):
            self._index.setdefault(s, k)
        return (
            state,
            0,
            {"nodes": found.nodes, "ms": (time.perf_counter() - t0) * 1000.0, "cached": False},
        )

    def plan(self, state) -> Subgoal:
        """The next move from ``state`` (see the class docstring)."""
        state, i, info = self._locate(state)
        info["pushes"] = sum(self._is_push[i:])
        return Subgoal(
            action=self._moves[i], state=self._states[i + 1], plan=self._moves[i + 1 :], info=info
        )

    def next_push(self, state) -> Subgoal:
        """The walk to the next box and its push from ``state`` (see the class docstring)."""
        state, i, info = self._locate(state)
        info["pushes"] = sum(self._is_push[i:])
        j = i
        while not self._is_push[j]:
            j += 1
        return Subgoal(
            action=self._moves[i : j + 1],
            state=self._states[j + 1],
            plan=self._moves[j + 1 :],
            info=info,
        )
