"""Level sources: where each MuJoBan episode's level comes from.

A level source is a callable ``source(rng) -> Level`` with two attributes that
size the arena before anything is compiled: ``max_shape`` (rows, cols) and
``max_boxes``. Sources draw only from the generator they are given, so an
environment seeded the same way plays the same levels.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from envs.mujoban import generator
from envs.mujoban.levels import Level, LevelError, read_levels

#: Every MuJoBan level is shown in a 10x10 arena (the paper's appendix).
ARENA_SHAPE = (10, 10)


@dataclass
class GeneratedLevels:
    """Fresh procedurally generated levels of one paper difficulty (1-5)."""

    difficulty: int

    def __post_init__(self):
        spec = generator.difficulty(self.difficulty)
        self.max_shape = (spec.size, spec.size)
        self.max_boxes = spec.num_boxes

    def __call__(self, rng: np.random.Generator) -> Level:
        return generator.generate_level(self.difficulty, rng=rng)


@dataclass
class CurriculumLevels:
    """The paper's training curriculum: a difficulty drawn with its ratio, then a level."""

    ratios: tuple[float, ...] | None = None

    def __post_init__(self):
        self._curriculum = generator.Curriculum(self.ratios)
        self.max_shape = ARENA_SHAPE
        self.max_boxes = max(d.num_boxes for d in generator.DIFFICULTIES)

    def __call__(self, rng: np.random.Generator) -> Level:
        return self._curriculum.sample(rng)[1]


@dataclass
class FileLevels:
    """The levels of a Boxoban-format file, played in order (then again from the start).

    Args:
      path: the level file.
      start: index of the first level to play.
      shuffle: play in a random order (drawn from the environment's generator)
        instead of file order.
    """

    path: str | os.PathLike
    start: int = 0
    shuffle: bool = False
    levels: list[Level] = field(init=False, repr=False)

    def __post_init__(self):
        self.levels = read_levels(self.path)
        if not self.levels:
            raise LevelError("the file holds no level", path=str(self.path))
        if not 0 <= self.start < len(self.levels):
            raise ValueError(f"start must be in [0, {len(self.levels) - 1}], got {self.start}")
        self.max_shape = (
            max(lvl.height for lvl in self.levels),
            max(lvl.width for lvl in self.levels),
        )
        self.max_boxes = max(len(lvl.boxes) for lvl in self.levels)
        self._next = self.start

    def restart(self, episode: int = 0) -> None:
        """The next level is the ``episode``-th from ``start`` (modulo the
        file's length); called when the environment is reseeded."""
        self._next = (self.start + int(episode)) % len(self.levels)

    def __call__(self, rng: np.random.Generator) -> Level:
        if self.shuffle:
            return self.levels[int(rng.integers(len(self.levels)))]
        level = self.levels[self._next]
        self._next = (self._next + 1) % len(self.levels)
        return level


@dataclass
class FixedLevels:
    """Given levels, played in order and repeated (for tests and scripted runs)."""

    levels: list[Level]

    def __post_init__(self):
        if not self.levels:
            raise ValueError("FixedLevels needs at least one level")
        for lvl in self.levels:
            if not isinstance(lvl, Level):
                raise TypeError(f"expected Level objects, got {type(lvl).__name__}")
        self.max_shape = (
            max(lvl.height for lvl in self.levels),
            max(lvl.width for lvl in self.levels),
        )
        self.max_boxes = max(len(lvl.boxes) for lvl in self.levels)
        self._next = 0

    def restart(self, episode: int = 0) -> None:
        """The next level is the ``episode``-th (modulo their number)."""
        self._next = int(episode) % len(self.levels)

    def __call__(self, rng: np.random.Generator) -> Level:
        level = self.levels[self._next]
        self._next = (self._next + 1) % len(self.levels)
        return level
