"""The compiled Sokoban board, its deadlock checks and the matching lower bound.

These are the per-level and per-position pieces the searches of
`abstract_planners.sokoban_solver` and `abstract_planners.sokoban_time_solver`
are built on. None of the pruning below ever removes every solution.

**Board encoding.** The grid is padded with one ring of walls and cells are
numbered ``(row + 1) * (width + 2) + (col + 1)``; a set of cells is a Python
int used as a bitboard (bit ``i`` set = cell ``i`` in the set). A step in
direction U/D/L/R adds ``-W, +W, -1, +1`` (``W`` the padded width), and the
padding makes these shifts never wrap onto floor.

**Lower bound.** `_Matching` gives ``h``, a lower bound on the pushes still
needed from a box set: a minimum-cost perfect matching of boxes to targets
(`scipy.optimize.linear_sum_assignment`), where the cost of a box on cell
``c`` for target ``t`` is the number of pushes to bring a lone box from
``c`` to ``t`` (computed once per level by reverse pulls from each target).
One push moves one box, so ``h`` is cached per box set. A box set with no
perfect matching (two boxes that can only reach the same target) is a
deadlock.

**Deadlock pruning.** A position reached by a push is a deadlock when

* the pushed box lands on a *dead square*: a cell from which a lone box can
  never reach any target (the cells no reverse pull from a target reaches);
* the pushed box becomes part of a *freeze deadlock*: it cannot move along
  either axis because each axis is blocked by a wall, by dead squares on both
  sides, or by a box that is itself frozen (checked recursively, treating the
  boxes already on the path as walls), and some box in that frozen group is
  not on a target (see `frozen_deadlock`);
* the matching bound finds no perfect matching.

**PI-corral pruning.** When the player cannot reach some box-free floor
cells, each connected area ``C`` of them is a *corral*, fenced in by walls and the boxes
next to it (its barrier ``B``). Before any ``B`` box moves, no other box can
enter ``C`` and the player cannot enter it either. If ``C`` is unfinished (a
``B`` box off target or an empty target inside ``C``), every solution must
push a ``B`` box at some point. When moreover every push of a ``B`` box that
could become possible before then (the player stands on a non-corral, non-
barrier cell, the box moves onto a non-wall, non-barrier cell) pushes the
box *into* ``C`` and is already possible now (its player cell is reachable),
the first ``B`` push of any solution can be made first: it only frees a cell
outside ``C`` and fills one inside ``C``, which the earlier pushes never use.
So only the pushes of that corral's barrier boxes need to be generated. Of all
such corrals, the one with the fewest pushes is used; one with no safe push
is a deadlock. See `pi_corral_pushes`.
"""

from __future__ import annotations

from collections import OrderedDict, deque

import numpy as np
from scipy.optimize import linear_sum_assignment

from abstract_planners.sokoban import MOVES, SokobanState

__all__ = [
    "dead_squares",
    "frozen_deadlock",
    "pi_corral_pushes",
]

#: Cost standing for "this box can never reach this target".
_INF = 1 << 20
#: How many compiled boards `_board_for` keeps (a planner re-solving one level
#: reuses the dead squares and distance tables).
_BOARD_CACHE_SIZE = 16


# -- the compiled board ----------------------------------------------------------------


class _Board:
    """Static, per-level data: masks, steps, dead squares, distance tables."""

    def __init__(self, walls, targets, height: int, width: int) -> None:
        self.height, self.width = height, width
        W = self.W = width + 2
        n = self.n = W * (height + 2)
        self.steps = (-W, W, -1, 1)  # U, D, L, R
        wall = (1 << n) - 1
        for r in range(height):
            for c in range(width):
                if (r, c) not in walls:
                    wall &= ~(1 << self.index(r, c))
        self.wall = wall
        self.floor = ((1 << n) - 1) & ~wall
        self.targets = tuple(sorted(self.index(r, c) for r, c in targets))
        self.target_mask = _mask(self.targets)
        self.dist = tuple(self._pull_distances(t) for t in self.targets)
        live = 0
        for table in self.dist:
            for cell, d in enumerate(table):
                if d < _INF:
                    live |= 1 << cell
        self.dead = self.floor & ~live
        # Key = boxes << key_shift | lowest reachable cell.
        self.key_shift = n.bit_length()

    def index(self, r: int, c: int) -> int:
        return (r + 1) * self.W + (c + 1)

    def cell(self, i: int) -> tuple[int, int]:
        return (i // self.W - 1, i % self.W - 1)

    def _pull_distances(self, target: int) -> list[int]:
        """Pushes for a lone box to reach ``target`` from each cell (``_INF`` if never).

        Breadth-first over reverse pulls: a box on ``x`` came from ``x + s``
        if the player could stand behind it on ``x + 2s``.
        """
        dist = [_INF] * self.n
        dist[target] = 0
        queue = deque([target])
        floor = self.floor
        while queue:
            x = queue.popleft()
            nd = dist[x] + 1
            for s in self.steps:
                y = x + s
                if (floor >> y) & 1 and (floor >> (y + s)) & 1 and dist[y] == _INF:
                    dist[y] = nd
                    queue.append(y)
        return dist

    def reach(self, player: int, boxes: int) -> int:
        """Bitboard of the cells the player can walk to (boxes block)."""
        free = self.floor & ~boxes
        W = self.W
        r = 1 << player
        while True:
            grown = (r | (r << 1) | (r >> 1) | (r << W) | (r >> W)) & free
            if grown == r:
                return r
            r = grown

    def fill(self, seed: int, inside: int) -> int:
        """Flood fill of bitboard ``seed`` within bitboard ``inside``."""
        W = self.W
        r = seed
        while True:
            grown = (r | (r << 1) | (r >> 1) | (r << W) | (r >> W)) & inside
            if grown == r:
                return r
            r = grown


_BOARDS: "OrderedDict[tuple, _Board]" = OrderedDict()


def _board_for(state: SokobanState) -> _Board:
    key = (state.walls, state.targets, state.height, state.width)
    board = _BOARDS.get(key)
    if board is None:
        board = _Board(state.walls, state.targets, state.height, state.width)
        _BOARDS[key] = board
        if len(_BOARDS) > _BOARD_CACHE_SIZE:
            _BOARDS.popitem(last=False)
    else:
        _BOARDS.move_to_end(key)
    return board


def _mask(cells) -> int:
    m = 0
    for i in cells:
        m |= 1 << i
    return m


def _bits(m: int) -> list[int]:
    """Indices of the set bits of ``m``, lowest first."""
    out = []
    while m:
        low = m & -m
        out.append(low.bit_length() - 1)
        m ^= low
    return out


# -- deadlock checks ---------------------------------------------------------------------


def _is_frozen(board: _Board, pos: int, boxes: int, as_wall: int, group: list) -> bool:
    """Whether the box on ``pos`` can never move again (see `frozen_deadlock`).

    ``as_wall``: boxes already on the recursion path, treated as walls.
    Boxes found frozen are appended to ``group`` (entries of a failed branch
    are removed again).
    """
    mark = len(group)
    as_wall |= 1 << pos
    blocking = board.wall | as_wall
    dead = board.dead
    for s in (1, board.W):
        a, b = pos - s, pos + s
        if (blocking >> a) & 1 or (blocking >> b) & 1:
            continue
        if (dead >> a) & 1 and (dead >> b) & 1:
            continue
        if (boxes >> a) & 1 and _is_frozen(board, a, boxes, as_wall, group):
            continue
        if (boxes >> b) & 1 and _is_frozen(board, b, boxes, as_wall, group):
            continue
        del group[mark:]
        return False
    group.append(pos)
    return True


def _freeze_deadlock(board: _Board, pos: int, boxes: int) -> bool:
    """Bitboard version of `frozen_deadlock` for the box on cell index ``pos``."""
    # Fast exit: one free axis (no wall or box on either side, not both dead).
    W = board.W
    occupied = board.wall | boxes
    dead = board.dead
    for s in (1, W):
        a, b = pos - s, pos + s
        if not (
            (occupied >> a) & 1 or (occupied >> b) & 1 or ((dead >> a) & 1 and (dead >> b) & 1)
        ):
            return False
    group: list[int] = []
    if not _is_frozen(board, pos, boxes, 0, group):
        return False
    targets = board.target_mask
    return any(not (targets >> p) & 1 for p in group)


def _as_state(state) -> SokobanState:
    return state if isinstance(state, SokobanState) else SokobanState.from_level(state)


def dead_squares(state) -> frozenset[tuple[int, int]]:
    """The floor cells from which a lone box can never be pushed onto any target.

    Computed by reverse play: pulling a box from every target (the player
    needs the two cells behind the box) reaches exactly the live cells; any
    other non-wall cell of the grid is dead. Boxes and the player are ignored.
    """
    state = _as_state(state)
    board = _board_for(state)
    return frozenset(board.cell(i) for i in _bits(board.dead))


def frozen_deadlock(state, cell: tuple[int, int]) -> bool:
    """Whether the box on ``cell`` is part of a freeze deadlock in ``state``.

    A box is *frozen* when it can never move again: on each axis (horizontal
    and vertical) it is blocked by a wall on either side, by dead squares on
    both sides, or by a neighbouring box that is itself frozen (checked
    recursively, with the boxes already being checked counted as walls). A
    frozen group with a box off target can never be solved.

    Raises:
      ValueError: if there is no box on ``cell``.
    """
    state = _as_state(state)
    cell = (int(cell[0]), int(cell[1]))
    if cell not in state.boxes:
        raise ValueError(f"no box on {cell}")
    board = _board_for(state)
    boxes = _mask(board.index(r, c) for r, c in state.boxes)
    return _freeze_deadlock(board, board.index(*cell), boxes)


def _corral_pushes(board: _Board, boxes: int, reach: int):
    """The safe push set of the best PI-corral, or None (see module docstring).

    Returns a list of (box cell, direction) pushes (possibly empty: then the
    position is a deadlock), or None if no corral qualifies.
    """
    unreached = board.floor & ~boxes & ~reach
    if not unreached:
        return None
    W = board.W
    wall = board.wall
    steps = board.steps
    targets = board.target_mask
    dead = board.dead
    best = None
    while unreached:
        corral = board.fill(unreached & -unreached, unreached)
        unreached &= ~corral
        barrier = ((corral << 1) | (corral >> 1) | (corral << W) | (corral >> W)) & boxes
        if not (barrier & ~targets) and not (corral & targets):
            continue  # finished corral: nothing forces a barrier push
        closed = wall | barrier
        never_from = closed | corral
        pushes = []
        ok = True
        for b in _bits(barrier):
            for d, s in enumerate(steps):
                frm, to = b - s, b + s
                if (never_from >> frm) & 1 or (closed >> to) & 1:
                    continue  # impossible until a barrier box moves
                if not (corral >> to) & 1 or not (reach >> frm) & 1:
                    ok = False  # not an I-corral or not a P-corral
                    break
                if not (dead >> to) & 1:
                    pushes.append((b, d))
            if not ok:
                break
        if ok and (best is None or len(pushes) < len(best)):
            best = pushes
            if not pushes:
                break
    return best


def pi_corral_pushes(state) -> list[tuple[tuple[int, int], str]] | None:
    """The pushes PI-corral pruning keeps in ``state``, or None without a PI-corral.

    Returns (box cell, move letter) pairs; an empty list means a PI-corral
    that no push can ever enter, i.e. a deadlock. See the module docstring.
    """
    state = _as_state(state)
    board = _board_for(state)
    boxes = _mask(board.index(r, c) for r, c in state.boxes)
    reach = board.reach(board.index(*state.player), boxes)
    pushes = _corral_pushes(board, boxes, reach)
    if pushes is None:
        return None
    return [(board.cell(b), MOVES[d]) for b, d in pushes]


# -- the heuristic --------------------------------------------------------------------


class _Matching:
    """Cached minimum-cost box-to-target matching bound."""

    def __init__(self, board: _Board) -> None:
        self.dist = board.dist
        self.cache: dict[int, int] = {}

    def __call__(self, boxes: int) -> int:
        h = self.cache.get(boxes)
        if h is None:
            cells = _bits(boxes)
            cost = [[table[c] for c in cells] for table in self.dist]
            if len(cells) == 1:
                h = cost[0][0]
            else:
                matrix = np.array(cost)
                rows, cols = linear_sum_assignment(matrix)
                h = int(matrix[rows, cols].sum())
            if h >= _INF:
                h = _INF
            self.cache[boxes] = h
        return h
