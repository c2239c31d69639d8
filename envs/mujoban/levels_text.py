"""The character grammar of Sokoban level text (see `envs.mujoban.levels`).

The level characters (`WALL`, `FLOOR`, `PLAYER`, `BOX`, `TARGET`,
`BOX_ON_TARGET`, `PLAYER_ON_TARGET`, the floor aliases) and the helpers that
read text without knowing the `Level` type: splitting rows, checking
characters and rectangularity, collecting the cells of each kind, and
splitting a multi-level file into its ``;``-headed blocks. Errors are raised
through the ``error(reason, line, column)`` callback the caller passes.
`envs.mujoban.levels` re-exports every name.
"""

from __future__ import annotations

from collections import Counter
from typing import Iterator

WALL, FLOOR, PLAYER, BOX, TARGET, BOX_ON_TARGET, PLAYER_ON_TARGET = "# @$.*+"
#: Characters that are read as plain floor besides the space.
FLOOR_ALIASES = ("-", "_")
_CANONICAL = (WALL, FLOOR, PLAYER, BOX, TARGET, BOX_ON_TARGET, PLAYER_ON_TARGET)
_VALID_TEXT = ", ".join(repr(ch) for ch in _CANONICAL)


def _split_rows(text: str) -> list[str]:
    """Lines of ``text`` without line ends; trailing empty lines dropped."""
    rows = [line[:-1] if line.endswith("\r") else line for line in text.split("\n")]
    while rows and rows[-1] == "":
        rows.pop()
    return rows


def _check_characters(rows: list[str], first_line: int, error) -> None:
    allowed = set(_CANONICAL) | set(FLOOR_ALIASES)
    for r, row in enumerate(rows):
        for c, char in enumerate(row):
            if char not in allowed:
                raise error(
                    f"unknown character {char!r} (valid: {_VALID_TEXT})", first_line + r, c + 1
                )


def _check_rectangular(rows: list[str], first_line: int, error) -> None:
    """Every row as long as the most common row length (ties: the first row's)."""
    counts = Counter(len(row) for row in rows)
    top = max(counts.values())
    expected = next(len(row) for row in rows if counts[len(row)] == top)
    for r, row in enumerate(rows):
        if len(row) != expected:
            kind = "shorter" if len(row) < expected else "longer"
            raise error(
                f"ragged rows: this row has {len(row)} characters, {kind} than "
                f"the level's {expected}",
                first_line + r,
                min(len(row), expected) + 1,
            )


def _collect(rows: list[str]):
    """Walls, targets, boxes and player cells (in reading order) of valid rows."""
    walls, targets, boxes, players = [], [], [], []
    for r, row in enumerate(rows):
        for c, char in enumerate(row):
            if char == WALL:
                walls.append((r, c))
            if char in (TARGET, BOX_ON_TARGET, PLAYER_ON_TARGET):
                targets.append((r, c))
            if char in (BOX, BOX_ON_TARGET):
                boxes.append((r, c))
            if char in (PLAYER, PLAYER_ON_TARGET):
                players.append((r, c))
    return walls, targets, boxes, players


def _index_from_name(name: str | None) -> int | None:
    """The integer a ``; N`` header name stands for, else None."""
    if name is None:
        return None
    try:
        return int(name)
    except ValueError:
        return None


def _blocks(text: str) -> Iterator[tuple[str | None, int, list[str]]]:
    """(header name, first line number, rows) for each level of a file's text.

    A level is a maximal run of lines that are neither blank (whitespace
    only) nor ``;`` headers. A header names the level that follows it.
    """
    name: str | None = None
    start = 0
    rows: list[str] = []
    lines = text.split("\n")
    for number, line in enumerate(lines + [""], start=1):
        line = line[:-1] if line.endswith("\r") else line
        if line.startswith(";") or not line.strip():
            if rows:
                yield name, start, rows
                name, rows = None, []
            if line.startswith(";"):
                name = line[1:].strip()
            continue
        if not rows:
            start = number
        rows.append(line)
