"""Procedurally generated Sokoban levels by reverse play.

The method follows Racanière et al. 2017 ("Imagination-augmented agents for
deep reinforcement learning", appendix), which MuJoBan (Mirza et al. 2020)
uses for its five training difficulties:

1. **Room.** Start from a grid of walls and carve floor with a random walk
   (occasionally carving a 2x2 patch, and changing direction at random)
   inside the outer wall ring until 45-60 % of the interior is floor.
2. **Solved state.** Put ``num_boxes`` targets and the player on distinct
   random floor cells, with a box on every target.
3. **Reverse play.** Walk the player at random; a step away from an adjacent
   box may *pull* it into the cell the player leaves. A pull is exactly the
   inverse of a Sokoban push, so every state reached can be pushed back to
   the solved state.
4. **Score.** Each state along the walk scores
   ``box swaps x total box displacement`` (swaps: how often the pulled box
   differs from the previously pulled one; displacement: Manhattan distance of
   each box from where it started). The best-scoring state over several
   walks becomes the level; states with every box on a target are never used.

The level is therefore solvable by construction, and the reverse walk, read
backwards with every direction flipped, is a solution (see
``generate_level(..., return_solution=True)``).

Only the random generator passed in (or ``np.random.default_rng(seed)``) is
used, so equal seeds give equal levels.

This module holds the API (difficulties, `generate_level`, `Curriculum`)
and step 1, the room; steps 2-5 are `envs.mujoban.generator_reverse_play`.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Literal, Sequence, overload

import numpy as np

# Steps 2-5 (reverse play, the level); the names stay importable from here.
from envs.mujoban.generator_reverse_play import (
    _LETTERS,  # noqa: F401
    _PLACEMENTS,  # noqa: F401
    _PULL_PROB,  # noqa: F401
    _STEPS_PER_CELL,  # noqa: F401
    _WALKS,  # noqa: F401
    _best_reverse_play,
    _distance,  # noqa: F401
    _Found,  # noqa: F401
    _reverse_walk,  # noqa: F401
    _shorten,  # noqa: F401
    _to_level,
)
from envs.mujoban.levels import Level

__all__ = [
    "DIFFICULTIES",
    "MIN_SIZE",
    "Curriculum",
    "Difficulty",
    "difficulty",
    "generate_level",
    "max_boxes",
]


@dataclass(frozen=True)
class Difficulty:
    """One row of the paper's difficulty table.

    Attributes:
      level: difficulty number, 1 (easiest) to 5.
      size: the room is ``size`` x ``size`` cells, outer wall ring included.
      num_boxes: boxes (and targets) in the room.
      ratio: the difficulty's share of the training curriculum.
    """

    level: int
    size: int
    num_boxes: int
    ratio: float


#: The paper's difficulties, easiest first.
DIFFICULTIES: tuple[Difficulty, ...] = (
    Difficulty(level=1, size=5, num_boxes=1, ratio=0.25),
    Difficulty(level=2, size=7, num_boxes=1, ratio=0.25),
    Difficulty(level=3, size=7, num_boxes=2, ratio=0.2),
    Difficulty(level=4, size=8, num_boxes=3, ratio=0.2),
    Difficulty(level=5, size=10, num_boxes=4, ratio=0.1),
)

#: Smallest room (outer walls included): a 3x3 interior.
MIN_SIZE = 5
#: Fraction of the interior carved into floor, drawn uniformly per room.
FLOOR_FRACTION = (0.45, 0.60)
#: Probability that the carving walk changes direction at a step.
_TURN_PROB = 0.35
#: Probability that the carving walk carves a 2x2 patch instead of one cell.
_PATCH_PROB = 0.25
#: Rooms tried before giving up.
_MAX_ROOMS = 200

#: (row, col) step per direction (up, down, left, right), as `_LETTERS`.
_ROW_COL = ((-1, 0), (1, 0), (0, -1), (0, 1))


def difficulty(level: int) -> Difficulty:
    """The `Difficulty` numbered ``level`` (1..5).

    Raises:
      ValueError: if ``level`` is not an integer in 1..5.
    """
    if not _is_int(level) or not 1 <= level <= len(DIFFICULTIES):
        raise ValueError(f"difficulty must be an integer in 1..{len(DIFFICULTIES)}, got {level!r}")
    return DIFFICULTIES[int(level) - 1]


def max_boxes(size: int) -> int:
    """The most boxes `generate_level` accepts for a ``size`` x ``size`` room.

    A quarter of the interior cells: rooms are only about half floor, and
    targets, player and room to pull boxes all need floor.
    """
    return (size - 2) ** 2 // 4


@overload
def generate_level(
    level_or_size: int,
    num_boxes: int | None = None,
    *,
    seed: int | None = None,
    rng: np.random.Generator | None = None,
    return_solution: Literal[False] = False,
) -> Level: ...


@overload
def generate_level(
    level_or_size: int,
    num_boxes: int | None = None,
    *,
    seed: int | None = None,
    rng: np.random.Generator | None = None,
    return_solution: Literal[True],
) -> tuple[Level, list[str]]: ...


@overload
def generate_level(
    level_or_size: int,
    num_boxes: int | None = None,
    *,
    seed: int | None = None,
    rng: np.random.Generator | None = None,
    return_solution: bool = False,
) -> Level | tuple[Level, list[str]]: ...


def generate_level(
    level_or_size: int,
    num_boxes: int | None = None,
    *,
    seed: int | None = None,
    rng: np.random.Generator | None = None,
    return_solution: bool = False,
) -> Level | tuple[Level, list[str]]:
    """A random solvable Sokoban level made by reverse play (see module docstring).

    Call either ``generate_level(difficulty)`` with a paper difficulty 1..5, or
    ``generate_level(size, num_boxes)`` for a custom ``size`` x ``size`` room
    (outer wall ring included).

    Args:
      level_or_size: a difficulty (1..5) when ``num_boxes`` is None, else the
        room size (>= 5).
      num_boxes: number of boxes for a custom room, 1..``max_boxes(size)``.
      seed: seed for ``np.random.default_rng``; mutually exclusive with ``rng``.
      rng: the random generator to draw from (advanced by the call).
      return_solution: also return a solution: the player's moves, each one of
        ``"U" "D" "L" "R"`` (up = towards row 0), pushes included.

    Returns:
      The level, or ``(level, solution)`` with ``return_solution=True``.

    Raises:
      ValueError: for a difficulty outside 1..5, a size below 5, a box count
        outside 1..max_boxes(size), or both ``seed`` and ``rng``.
      RuntimeError: if no usable level was found in a bounded number of rooms.
    """
    size, boxes = _resolve_shape(level_or_size, num_boxes)
    rng = _make_rng(seed, rng)
    for _ in range(_MAX_ROOMS):
        floor = _carve_room(size, boxes, rng)
        if floor is None:
            continue
        found = _best_reverse_play(floor, size, boxes, rng)
        if found is not None:
            level, solution = _to_level(floor, size, found)
            return (level, solution) if return_solution else level
    raise RuntimeError(
        f"could not generate a {size}x{size} level with {boxes} boxes in "
        f"{_MAX_ROOMS} rooms; try fewer boxes or a larger size"
    )


# -- arguments -----------------------------------------------------------------


def _is_int(value) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _resolve_shape(level_or_size: int, num_boxes: int | None) -> tuple[int, int]:
    """(size, num_boxes) from a difficulty, or validated explicit values."""
    if num_boxes is None:
        spec = difficulty(level_or_size)
        return spec.size, spec.num_boxes
    if not _is_int(level_or_size) or level_or_size < MIN_SIZE:
        raise ValueError(
            f"size must be an integer >= {MIN_SIZE} (outer walls included), got {level_or_size!r}"
        )
    size = int(level_or_size)
    if not _is_int(num_boxes) or not 1 <= num_boxes <= max_boxes(size):
        raise ValueError(
            f"num_boxes must be an integer in 1..{max_boxes(size)} for a "
            f"{size}x{size} room, got {num_boxes!r}"
        )
    return size, int(num_boxes)


def _make_rng(seed: int | None, rng: np.random.Generator | None) -> np.random.Generator:
    if rng is not None and seed is not None:
        raise ValueError("pass either seed or rng, not both")
    if rng is None:
        return np.random.default_rng(seed)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


# -- step 1: the room ------------------------------------------------------------


def _carve_room(size: int, num_boxes: int, rng: np.random.Generator) -> bytearray | None:
    """A room as a flat ``size*size`` bytearray (1 = floor), or None if too small.

    Floor is carved by one random walk inside the outer wall ring, so it is
    connected.
    """
    inner = size - 2
    wanted = int(round(rng.uniform(*FLOOR_FRACTION) * inner * inner))
    wanted = min(inner * inner, max(wanted, 2 * num_boxes + 3))
    steps = 20 * inner * inner
    turns = rng.random(steps) < _TURN_PROB
    patches = rng.random(steps) < _PATCH_PROB
    new_dirs = rng.integers(0, 4, steps)
    spins = rng.integers(0, 4, steps)
    corners = rng.integers(0, 2, (steps, 2))
    r, c = (int(v) for v in rng.integers(1, size - 1, 2))
    direction = int(rng.integers(0, 4))
    floor = bytearray(size * size)
    carved = 0
    for t in range(steps):
        cells = [(r, c)]
        if patches[t]:
            r0 = min(max(r - int(corners[t, 0]), 1), size - 3)
            c0 = min(max(c - int(corners[t, 1]), 1), size - 3)
            cells = [(r0, c0), (r0 + 1, c0), (r0, c0 + 1), (r0 + 1, c0 + 1)]
        for cr, cc in cells:
            if not floor[cr * size + cc]:
                floor[cr * size + cc] = 1
                carved += 1
        if carved >= wanted:
            break
        if turns[t]:
            direction = int(new_dirs[t])
        r, c, direction = _walk_step(r, c, direction, size, int(spins[t]))
    return floor if carved >= 2 * num_boxes + 3 else None


def _walk_step(r: int, c: int, direction: int, size: int, spin: int) -> tuple[int, int, int]:
    """One carving step; at the outer ring, turn to the first free direction
    among ``spin, spin + 1, ...`` (mod 4)."""
    for d in (direction, spin, (spin + 1) % 4, (spin + 2) % 4, (spin + 3) % 4):
        dr, dc = _ROW_COL[d]
        if 1 <= r + dr <= size - 2 and 1 <= c + dc <= size - 2:
            return r + dr, c + dc, d
    return r, c, direction  # unreachable: an interior cell has an interior neighbour


# -- curriculum ---------------------------------------------------------------------


class Curriculum:
    """The paper's training curriculum: a difficulty drawn by ratio, then a level.

    Args:
      ratios: probabilities of difficulties 1..5; five non-negative numbers
        summing to 1. Default: the paper's 0.25/0.25/0.2/0.2/0.1.

    Raises:
      ValueError: for ratios that are not five non-negative numbers summing
        to 1 (within 1e-6).
    """

    def __init__(self, ratios: Sequence[float] | None = None) -> None:
        if ratios is None:
            ratios = tuple(d.ratio for d in DIFFICULTIES)
        self.ratios: tuple[float, ...] = _check_ratios(ratios)
        self._cumulative = np.cumsum(self.ratios)

    def __repr__(self) -> str:
        return f"Curriculum(ratios={self.ratios})"

    def sample_difficulty(self, rng: np.random.Generator) -> Difficulty:
        """A difficulty drawn with the curriculum's ratios."""
        index = int(np.searchsorted(self._cumulative, rng.random(), side="right"))
        if index >= len(DIFFICULTIES):  # rounding left the sum just below 1
            index = max(i for i, p in enumerate(self.ratios) if p > 0)
        return DIFFICULTIES[index]

    def sample(self, rng: np.random.Generator) -> tuple[Difficulty, Level]:
        """A difficulty drawn with the curriculum's ratios and a level of it."""
        spec = self.sample_difficulty(rng)
        return spec, generate_level(spec.level, rng=rng)


def _check_ratios(ratios: Sequence[float]) -> tuple[float, ...]:
    try:
        values = tuple(float(p) for p in ratios)
    except (TypeError, ValueError):
        raise ValueError(f"ratios must be {len(DIFFICULTIES)} numbers, got {ratios!r}") from None
    if len(values) != len(DIFFICULTIES):
        raise ValueError(
            f"ratios must have {len(DIFFICULTIES)} entries (one per difficulty), got {len(values)}"
        )
    if not all(np.isfinite(p) and p >= 0 for p in values):
        raise ValueError(f"ratios must be non-negative, got {values}")
    if abs(sum(values) - 1.0) > 1e-6:
        raise ValueError(f"ratios must sum to 1 (within 1e-6), got sum {sum(values)!r}")
    return values
