"""Sokoban levels and the Boxoban text format.

A level is a rectangular grid written one row per line::

    #####
    #@$.#
    #####

with these characters:

====  =========================================================
``#``  wall
`` `` floor (a space)
``@``  player
``$``  box
``.``  target
``*``  box on a target
``+``  player on a target
====  =========================================================

``-`` and ``_`` are also read as floor (a common Sokoban convention for
files whose editors strip spaces); `Level.to_text` always writes a space.

Every row of a level must have the same length: nothing is padded, trimmed or
otherwise altered while parsing, so a level that looks wrong is an error
rather than a silently different level. Only a trailing ``\\r`` (Windows line
ends) is dropped from each line.

A multi-level file (the Boxoban layout) puts a header line starting with
``;`` before each level, for example::

    ; 0
    ##########
    ...
    ##########

    ; 1
    ...

Blank lines between levels are ignored. Coordinates are ``(row, col)`` with
row 0 the first line of the level's text and column 0 its first character.

This module holds the `Level` type, `LevelError` and reading and writing
level files; the character grammar (the characters above, row checks, the
splitting of a file into levels) is `envs.mujoban.levels_text`.
"""

from __future__ import annotations

import os
import pathlib
from dataclasses import dataclass, field
from typing import IO, Iterable

import numpy as np

from physics_planning.cli import UsageError

# The character grammar of level text; its names stay importable from here.
from envs.mujoban.levels_text import (
    _CANONICAL,  # noqa: F401
    _VALID_TEXT,  # noqa: F401
    BOX,  # noqa: F401
    BOX_ON_TARGET,
    FLOOR,
    FLOOR_ALIASES,  # noqa: F401
    PLAYER,
    PLAYER_ON_TARGET,
    TARGET,
    WALL,
    _blocks,
    _check_characters,
    _check_rectangular,
    _collect,
    _index_from_name,
    _split_rows,
)

__all__ = [
    "BOXOBAN_DIR",
    "Level",
    "LevelError",
    "Position",
    "parse_levels",
    "read_levels",
    "write_levels",
]

#: Directory of the Boxoban level files shipped with the package.
BOXOBAN_DIR = pathlib.Path(__file__).parent / "data" / "boxoban"

#: A grid cell as (row, col); row 0 is the top line of the level text.
Position = tuple[int, int]

#: Channel order of `Level.entity_layers` (the paper's ``full_entity_layer``).
ENTITY_CHANNELS = ("wall", "target", "player", "box")


class LevelError(UsageError):
    """A level (or level file) that cannot be used, with where the problem is
    (a `UsageError`, so a command reports it in one line; also a ValueError).

    Attributes:
      reason: what is wrong, without location.
      path: the file the level came from, if any.
      index: the level's index in a multi-level file: the ``N`` of its
        ``; N`` header when that is an integer, else its 0-based position.
      line: 1-based line number in the file (or text), if known.
      column: 1-based column number, if known.
    """

    def __init__(
        self,
        reason: str,
        *,
        path: str | os.PathLike | None = None,
        index: int | None = None,
        line: int | None = None,
        column: int | None = None,
    ) -> None:
        self.reason = reason
        self.path = None if path is None else os.fspath(path)
        self.index = index
        self.line = line
        self.column = column
        super().__init__(self._message())

    def _message(self) -> str:
        where = []
        if self.index is not None:
            where.append(f"level {self.index}")
        if self.line is not None:
            where.append(f"line {self.line}")
        if self.column is not None:
            where.append(f"column {self.column}")
        prefix = ", ".join(where)
        if self.path is not None:
            prefix = f"{self.path}: {prefix}" if prefix else self.path
        return f"{prefix}: {self.reason}" if prefix else self.reason

    def __str__(self) -> str:
        return self._message()

    def __reduce__(self):
        # Keyword-only arguments need help to survive pickling (multiprocessing).
        return (_rebuild_level_error, (self.reason, self.path, self.index, self.line, self.column))


def _rebuild_level_error(reason, path, index, line, column) -> LevelError:
    return LevelError(reason, path=path, index=index, line=line, column=column)


def _positions(cells: Iterable) -> frozenset[Position]:
    """``cells`` as a frozenset of (int, int) tuples."""
    return frozenset((int(r), int(c)) for r, c in cells)


@dataclass(frozen=True)
class Level:
    """An immutable Sokoban level; equal (and hashing equal) by content.

    Attributes:
      walls, targets, boxes: sets of (row, col) cells.
      player: the player's (row, col) cell.
      height, width: grid size in cells.
      name: the level's name (its ``; N`` header in a file); not compared.
      path: the file the level was read from, if any; not compared. Used only
        to say where a level came from in errors.

    Raises:
      LevelError: if a position is outside the grid, a box, target or the
        player is on a wall, the player is on a box, or the numbers of boxes
        and targets differ or are zero.
    """

    walls: frozenset[Position]
    targets: frozenset[Position]
    boxes: frozenset[Position]
    player: Position
    height: int
    width: int
    name: str | None = field(default=None, compare=False)
    path: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        # Normalise containers so that equality and hashing are by content.
        object.__setattr__(self, "walls", _positions(self.walls))
        object.__setattr__(self, "targets", _positions(self.targets))
        object.__setattr__(self, "boxes", _positions(self.boxes))
        object.__setattr__(self, "player", (int(self.player[0]), int(self.player[1])))
        object.__setattr__(self, "height", int(self.height))
        object.__setattr__(self, "width", int(self.width))
        self._validate()

    # -- validation ----------------------------------------------------------

    def _error(self, reason: str) -> LevelError:
        index = _index_from_name(self.name)
        if index is None and self.name is not None:
            reason = f"level {self.name!r}: {reason}"
        return LevelError(reason, path=self.path, index=index)

    def _validate(self) -> None:
        if self.height < 1 or self.width < 1:
            raise self._error(f"level must be at least 1x1, got {self.height}x{self.width}")
        groups = (
            ("wall", self.walls),
            ("target", self.targets),
            ("box", self.boxes),
            ("player", (self.player,)),
        )
        for kind, cells in groups:
            for r, c in sorted(cells):
                if not (0 <= r < self.height and 0 <= c < self.width):
                    raise self._error(
                        f"{kind} at {(r, c)} is outside the {self.height}x{self.width} grid"
                    )
        for kind, cells in groups[1:]:
            on_wall = sorted(set(cells) & self.walls)
            if on_wall:
                raise self._error(f"{kind} at {on_wall[0]} is on a wall")
        if self.player in self.boxes:
            raise self._error(f"player at {self.player} is on a box")
        if not self.boxes:
            raise self._error("level has no box")
        if len(self.boxes) != len(self.targets):
            raise self._error(f"level has {len(self.boxes)} boxes but {len(self.targets)} targets")

    # -- text ----------------------------------------------------------------

    @classmethod
    def from_text(
        cls,
        text: str,
        *,
        path: str | os.PathLike | None = None,
        index: int | None = None,
        first_line: int = 1,
        name: str | None = None,
    ) -> Level:
        """Parse one level written one row per line (see the module docstring).

        Args:
          text: the level's rows; a trailing newline is fine.
          path: the file the text came from (for error messages).
          index: the level's index in that file (for error messages).
          first_line: file line number of the text's first line, so that
            errors point at the right line of a multi-level file.
          name: the level's name.

        Raises:
          LevelError: unknown character, rows of different lengths, no or two
            players, different numbers of boxes and targets, no box.
        """
        path = None if path is None else os.fspath(path)
        rows = _split_rows(text)

        def error(reason: str, line: int | None = None, column: int | None = None):
            return LevelError(reason, path=path, index=index, line=line, column=column)

        if not rows:
            raise error("empty level: no rows", first_line)
        _check_characters(rows, first_line, error)
        _check_rectangular(rows, first_line, error)
        walls, targets, boxes, players = _collect(rows)
        if not players:
            raise error("no player ('@' or '+')", first_line)
        if len(players) > 1:
            (r, c) = players[1]
            raise error(
                f"more than one player (the first is at line "
                f"{first_line + players[0][0]}, column {players[0][1] + 1})",
                first_line + r,
                c + 1,
            )
        if not boxes:
            raise error("level has no box", first_line)
        if len(boxes) != len(targets):
            raise error(f"level has {len(boxes)} boxes but {len(targets)} targets", first_line)
        return cls(
            walls=frozenset(walls),
            targets=frozenset(targets),
            boxes=frozenset(boxes),
            player=players[0],
            height=len(rows),
            width=len(rows[0]),
            name=name,
            path=path,
        )

    def to_text(self) -> str:
        """The level's rows joined by newlines (no trailing newline).

        ``Level.from_text(level.to_text()) == level`` for every level.
        """
        return "\n".join("".join(row) for row in self.grid())

    def grid(self) -> np.ndarray:
        """The level as an (height, width) array of single characters."""
        grid = np.full((self.height, self.width), FLOOR, dtype="<U1")
        for cells, char in ((self.walls, WALL), (self.targets, TARGET), (self.boxes, BOX)):
            for r, c in cells:
                grid[r, c] = char
        for r, c in self.boxes & self.targets:
            grid[r, c] = BOX_ON_TARGET
        r, c = self.player
        grid[r, c] = PLAYER_ON_TARGET if self.player in self.targets else PLAYER
        return grid

    def entity_layers(self) -> np.ndarray:
        """(height, width, 4) bool layers, channels [wall, target, player, box].

        This is the paper's ``full_entity_layer`` observation.
        """
        layers = np.zeros((self.height, self.width, len(ENTITY_CHANNELS)), dtype=bool)
        for channel, cells in enumerate((self.walls, self.targets, {self.player}, self.boxes)):
            for r, c in cells:
                layers[r, c, channel] = True
        return layers

    def padded(self, height: int, width: int) -> Level:
        """This level surrounded by walls to exactly ``height`` x ``width``.

        The original is placed at offset ((height - h) // 2, (width - w) // 2).

        Raises:
          LevelError: if the level is larger than (height, width).
        """
        if self.height > height or self.width > width:
            raise self._error(
                f"level is {self.height}x{self.width}, larger than the arena's {height}x{width}"
            )
        dr, dc = (height - self.height) // 2, (width - self.width) // 2
        shift = lambda cells: frozenset((r + dr, c + dc) for r, c in cells)  # noqa: E731
        inside = {(r, c) for r in range(dr, dr + self.height) for c in range(dc, dc + self.width)}
        border = {(r, c) for r in range(height) for c in range(width)} - inside
        return Level(
            walls=shift(self.walls) | border,
            targets=shift(self.targets),
            boxes=shift(self.boxes),
            player=(self.player[0] + dr, self.player[1] + dc),
            height=height,
            width=width,
            name=self.name,
            path=self.path,
        )

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width)."""
        return (self.height, self.width)

    def is_solved(self) -> bool:
        """Whether every box is on a target."""
        return self.boxes == self.targets


# -- files ---------------------------------------------------------------------


def parse_levels(text: str, path: str | os.PathLike | None = None) -> list[Level]:
    """All levels of a multi-level text (Boxoban layout, see module docstring).

    Each level's name is the text of its ``;`` header, stripped (``"0"`` for
    ``; 0``), or None without a header. Errors give the level's index (the
    header's number when it is an integer, else its 0-based position) and file
    line numbers.

    Raises:
      LevelError: for the first malformed level.
    """
    path = None if path is None else os.fspath(path)
    levels = []
    for position, (name, start, rows) in enumerate(_blocks(text)):
        index = _index_from_name(name)
        levels.append(
            Level.from_text(
                "\n".join(rows),
                path=path,
                index=position if index is None else index,
                first_line=start,
                name=name,
            )
        )
    return levels


def read_levels(path: str | os.PathLike) -> list[Level]:
    """All levels of a file (see `parse_levels`).

    Raises:
      OSError: if the file cannot be read.
      LevelError: for the first malformed level.
    """
    with open(path, encoding="utf-8-sig") as file:
        text = file.read()
    return parse_levels(text, path=path)


def _writable_rows(level: Level) -> str:
    """``level.to_text()``, with floor-only rows written as ``-`` (floor alias).

    A row of spaces alone would read back as a blank line between levels.
    """
    rows = level.to_text().split("\n")
    return "\n".join("-" * len(row) if not row.strip() else row for row in rows)


def write_levels(levels: Iterable[Level], path_or_textio: str | os.PathLike | IO[str]) -> None:
    """Write levels in the Boxoban layout: ``; {name or i}``, rows, blank line.

    `read_levels` of the result gives back equal levels with the same names
    (a level without a name gets its position ``i`` as name). A row that is
    all floor is written with ``-`` (a floor alias) so it is not mistaken for
    a blank line.

    Raises:
      ValueError: for a name that would not read back the same (one with a
        line break or surrounding whitespace).
    """
    chunks = []
    for i, level in enumerate(levels):
        name = str(i) if level.name is None else level.name
        if "\n" in name or "\r" in name or name != name.strip():
            raise ValueError(
                f"level {i}: name {name!r} cannot be written as a '; name' "
                f"header (line break or surrounding whitespace)"
            )
        chunks.append(f"; {name}\n{_writable_rows(level)}\n\n")
    text = "".join(chunks)
    if hasattr(path_or_textio, "write"):
        path_or_textio.write(text)
        return
    with open(path_or_textio, "w", encoding="utf-8", newline="\n") as file:
        file.write(text)
