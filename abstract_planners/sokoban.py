"""Sokoban as an abstract game: `SokobanState` and its rules.

A state is the whole board: ``walls``, ``targets`` and ``boxes`` (frozensets
of ``(row, col)`` cells), the ``player``'s cell and the grid size. Row 0 is
the top row, so the move letters are

====  ==============================
``U``  up, towards row 0
``D``  down, towards the last row
``L``  left, towards column 0
``R``  right, towards the last column
====  ==============================

Rules: the player steps onto an adjacent cell that is neither a wall nor
outside the grid. Stepping onto a box pushes it one cell further in the same
direction, which is only allowed when that cell is inside the grid, not a
wall and not another box (so exactly one box moves; boxes are never pulled).
The level is solved when every box is on a target.

States are immutable and compare (and hash) by content, so they can be used
as dictionary keys. Successor states share the ``walls`` and ``targets``
frozensets of their parent, so `apply` only builds the new box set (and only
when a box moves).

This module does not import ``envs``: `SokobanState.from_level` duck-types
any object with ``walls``, ``targets``, ``boxes``, ``player``, ``height`` and
``width`` attributes (an ``envs.mujoban.levels.Level``), and
`SokobanState.from_text` reads the Boxoban characters itself.
"""

from __future__ import annotations

from typing import Iterable

__all__ = [
    "DIRECTIONS",
    "MOVES",
    "SokobanState",
    "replay",
]

Position = tuple[int, int]

#: Move letters in a fixed order, and their (row, col) steps.
MOVES: tuple[str, ...] = ("U", "D", "L", "R")
DIRECTIONS: dict[str, Position] = {"U": (-1, 0), "D": (1, 0), "L": (0, -1), "R": (0, 1)}
_STEPS = tuple(DIRECTIONS[m] for m in MOVES)

_WALL, _FLOOR, _PLAYER, _BOX, _TARGET, _BOX_ON_TARGET, _PLAYER_ON_TARGET = "# @$.*+"
_FLOOR_ALIASES = "-_"


def _cells(cells: Iterable) -> frozenset[Position]:
    return frozenset((int(r), int(c)) for r, c in cells)


def _assign(state, walls, targets, boxes, player, height, width) -> None:
    """Sets the fields of a (frozen, slotted) `SokobanState` (on the solver's
    hot path: one call per field, no loop)."""
    _set = object.__setattr__
    _set(state, "walls", walls)
    _set(state, "targets", targets)
    _set(state, "boxes", boxes)
    _set(state, "player", player)
    _set(state, "height", height)
    _set(state, "width", width)
    _set(state, "_hash", None)


class SokobanState:
    """An immutable Sokoban board; equal (and hashing equal) by content.

    Attributes:
      walls, targets, boxes: frozensets of (row, col) cells.
      player: the player's (row, col) cell.
      height, width: grid size; cells outside it behave like walls.

    Raises:
      ValueError: a cell outside the grid, a box, target or the player on a
        wall, the player on a box, or different numbers of boxes and targets.
    """

    __slots__ = ("walls", "targets", "boxes", "player", "height", "width", "_hash")
    walls: frozenset[Position]
    targets: frozenset[Position]
    boxes: frozenset[Position]
    player: Position
    height: int
    width: int
    _hash: int | None

    def __init__(
        self,
        walls: Iterable[Position],
        targets: Iterable[Position],
        boxes: Iterable[Position],
        player: Position,
        height: int,
        width: int,
    ) -> None:
        walls, targets, boxes = _cells(walls), _cells(targets), _cells(boxes)
        player = (int(player[0]), int(player[1]))
        height, width = int(height), int(width)
        _validate(walls, targets, boxes, player, height, width)
        _assign(self, walls, targets, boxes, player, height, width)

    @classmethod
    def _make(cls, walls, targets, boxes, player, height, width) -> "SokobanState":
        """A state from already-validated parts (the fast path of `apply`)."""
        state = object.__new__(cls)
        _assign(state, walls, targets, boxes, player, height, width)
        return state

    # -- construction ----------------------------------------------------------

    @classmethod
    def from_level(cls, level) -> "SokobanState":
        """The state of a level-like object (e.g. ``envs.mujoban.levels.Level``).

        Any object with ``walls``, ``targets``, ``boxes``, ``player``,
        ``height`` and ``width`` attributes works.
        """
        if isinstance(level, SokobanState):
            return level
        try:
            parts = (
                level.walls,
                level.targets,
                level.boxes,
                level.player,
                level.height,
                level.width,
            )
        except AttributeError as error:
            raise TypeError(
                f"from_level needs an object with walls, targets, boxes, "
                f"player, height and width attributes, got "
                f"{type(level).__name__}: {error}"
            ) from None
        return cls(*parts)

    @classmethod
    def from_text(cls, text: str) -> "SokobanState":
        """Parse one board written one row per line in the Boxoban characters.

        ``#`` wall, `` `` floor (``-`` and ``_`` also read as floor), ``@``
        player, ``$`` box, ``.`` target, ``*`` box on target, ``+`` player on
        target. Rows shorter than the longest are padded with floor on the
        right. Trailing blank lines are ignored.

        Raises:
          ValueError: unknown character, not exactly one player, or the
            problems listed in the class docstring.
        """
        rows = [line[:-1] if line.endswith("\r") else line for line in text.split("\n")]
        while rows and not rows[-1].strip():
            rows.pop()
        if not rows:
            raise ValueError("empty board: no rows")
        walls, targets, boxes, players = [], [], [], []
        for r, row in enumerate(rows):
            for c, ch in enumerate(row):
                if ch == _WALL:
                    walls.append((r, c))
                elif ch in (_TARGET, _BOX_ON_TARGET, _PLAYER_ON_TARGET):
                    targets.append((r, c))
                elif ch not in (_FLOOR, _PLAYER, _BOX) and ch not in _FLOOR_ALIASES:
                    raise ValueError(
                        f"unknown character {ch!r} at row {r}, column {c} "
                        f"(valid: '#', ' ', '@', '$', '.', '*', '+')"
                    )
                if ch in (_BOX, _BOX_ON_TARGET):
                    boxes.append((r, c))
                if ch in (_PLAYER, _PLAYER_ON_TARGET):
                    players.append((r, c))
        if len(players) != 1:
            raise ValueError(f"a board needs exactly one player ('@' or '+'), found {len(players)}")
        return cls(walls, targets, boxes, players[0], len(rows), max(map(len, rows)))

    def to_text(self) -> str:
        """The board's rows joined by newlines (no trailing newline).

        ``SokobanState.from_text(state.to_text()) == state``.
        """
        grid = [[_FLOOR] * self.width for _ in range(self.height)]
        for r, c in self.walls:
            grid[r][c] = _WALL
        for r, c in self.targets:
            grid[r][c] = _TARGET
        for r, c in self.boxes:
            grid[r][c] = _BOX_ON_TARGET if (r, c) in self.targets else _BOX
        r, c = self.player
        grid[r][c] = _PLAYER_ON_TARGET if self.player in self.targets else _PLAYER
        return "\n".join("".join(row) for row in grid)

    # -- rules -------------------------------------------------------------------

    def _blocked(self, cell: Position) -> bool:
        """Whether ``cell`` is a wall or outside the grid."""
        r, c = cell
        return cell in self.walls or r < 0 or c < 0 or r >= self.height or c >= self.width

    def _outcome(self, move: str):
        """(new player cell, pushed box cell or None, box destination) or None if illegal."""
        step = DIRECTIONS.get(move)
        if step is None:
            raise ValueError(f"unknown move {move!r}: moves are 'U', 'D', 'L', 'R'")
        dr, dc = step
        r, c = self.player
        ahead = (r + dr, c + dc)
        if self._blocked(ahead):
            return None
        if ahead not in self.boxes:
            return ahead, None, None
        beyond = (r + 2 * dr, c + 2 * dc)
        if self._blocked(beyond) or beyond in self.boxes:
            return None
        return ahead, ahead, beyond

    def is_legal(self, move: str) -> bool:
        """Whether ``move`` ('U', 'D', 'L' or 'R') can be made.

        Raises:
          ValueError: for a string that is not a move letter.
        """
        return self._outcome(move) is not None

    def is_push(self, move: str) -> bool:
        """Whether ``move`` is legal and pushes a box."""
        outcome = self._outcome(move)
        return outcome is not None and outcome[1] is not None

    def legal_moves(self) -> list[str]:
        """The legal move letters, in the order U, D, L, R."""
        return [m for m in MOVES if self._outcome(m) is not None]

    def apply(self, move: str) -> "SokobanState":
        """The state after ``move``; this state is unchanged.

        Raises:
          ValueError: if ``move`` is not a move letter or is illegal here
            (into a wall or off the grid, or pushing a box into a wall,
            another box or off the grid).
        """
        outcome = self._outcome(move)
        if outcome is None:
            raise ValueError(
                f"illegal move {move!r} from player at {self.player}: {self._why_illegal(move)}"
            )
        player, pushed, beyond = outcome
        boxes = self.boxes
        if pushed is not None:
            boxes = (boxes - {pushed}) | {beyond}
        return SokobanState._make(self.walls, self.targets, boxes, player, self.height, self.width)

    def _why_illegal(self, move: str) -> str:
        dr, dc = DIRECTIONS[move]
        r, c = self.player
        ahead = (r + dr, c + dc)
        if self._blocked(ahead):
            return f"{ahead} is a wall" if ahead in self.walls else f"{ahead} is off the grid"
        beyond = (r + 2 * dr, c + 2 * dc)
        if beyond in self.boxes:
            return f"the box at {ahead} is blocked by the box at {beyond}"
        where = "a wall" if beyond in self.walls else "off the grid"
        return f"the box at {ahead} would be pushed into {beyond}, {where}"

    def is_solved(self) -> bool:
        """Whether every box is on a target."""
        return self.boxes == self.targets

    def with_player(self, player: Position) -> "SokobanState":
        """This board with the player moved to ``player`` (validated)."""
        return SokobanState(self.walls, self.targets, self.boxes, player, self.height, self.width)

    # -- value semantics -----------------------------------------------------------

    def __eq__(self, other) -> bool:
        if self is other:
            return True
        if not isinstance(other, SokobanState):
            return NotImplemented
        return (
            self.player == other.player
            and self.boxes == other.boxes
            and self.height == other.height
            and self.width == other.width
            and (self.targets is other.targets or self.targets == other.targets)
            and (self.walls is other.walls or self.walls == other.walls)
        )

    def __hash__(self) -> int:
        h = self._hash
        if h is None:
            # Walls and targets are shared by every state of a game, so they
            # are left out of the hash (equality still compares them).
            h = hash((self.player, self.boxes, self.height, self.width))
            object.__setattr__(self, "_hash", h)
        return h

    def __setattr__(self, name, value):
        raise AttributeError(f"SokobanState is immutable (cannot set {name!r})")

    def __delattr__(self, name):
        raise AttributeError(f"SokobanState is immutable (cannot delete {name!r})")

    def __reduce__(self):
        return (
            SokobanState,
            (self.walls, self.targets, self.boxes, self.player, self.height, self.width),
        )

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self

    def __repr__(self) -> str:
        return f"SokobanState.from_text({self.to_text()!r})"

    def __str__(self) -> str:
        return self.to_text()


def _validate(walls, targets, boxes, player, height, width) -> None:
    if height < 1 or width < 1:
        raise ValueError(f"board must be at least 1x1, got {height}x{width}")
    groups = (("wall", walls), ("target", targets), ("box", boxes), ("player", (player,)))
    for kind, cells in groups:
        for r, c in sorted(cells):
            if not (0 <= r < height and 0 <= c < width):
                raise ValueError(f"{kind} at {(r, c)} is outside the {height}x{width} grid")
    for kind, cells in groups[1:]:
        on_wall = sorted(set(cells) & walls)
        if on_wall:
            raise ValueError(f"{kind} at {on_wall[0]} is on a wall")
    if player in boxes:
        raise ValueError(f"player at {player} is on a box")
    if len(boxes) != len(targets):
        raise ValueError(f"board has {len(boxes)} boxes but {len(targets)} targets")


def replay(state: SokobanState, moves: Iterable[str]) -> SokobanState:
    """The state after making ``moves`` (letters, a string like ``"UURD"`` works) in turn.

    Raises:
      ValueError: at the first illegal move, naming its index.
    """
    for i, move in enumerate(moves):
        try:
            state = state.apply(move)
        except ValueError as error:
            raise ValueError(f"move {i}: {error}") from None
    return state
