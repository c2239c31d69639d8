"""MuJoBan: Sokoban in MuJoCo, pushed by a rolling ball (Mirza et al. 2020).

Names registered with `envs.load` and gymnasium:

* ``mujoban/level1`` ... ``mujoban/level5``: generated levels of the paper's
  difficulty table (5x5/1 box ... 10x10/4 boxes), shown in a 10x10 arena;
* the same with ``-pegs``: pegs at every interior grid intersection;
* ``mujoban/curriculum`` and ``mujoban/curriculum-pegs``: difficulties drawn
  with the paper's training ratios 0.25/0.25/0.2/0.2/0.1.

Any of them takes ``levels="path/to/boxoban.txt"`` to play a file's levels in
order instead.
"""

from __future__ import annotations

import os

from envs import _config
from envs.core import Environment
from envs.mujoban import arena, sources
from envs.mujoban.levels import Level, LevelError
from envs.mujoban.task import Mujoban
from envs.registry import EnvEntry, register


def make(
    *,
    difficulty: int | None = None,
    pegs: bool = False,
    seed: int | None = None,
    levels: str | os.PathLike | None = None,
    level_order: str = "sequential",
    grid_shape=sources.ARENA_SHAPE,
    top_camera=(96, 96),
    egocentric_camera=(96, 96),
    randomize_appearance: bool = True,
    time_limit: float = 45.0,
    control_timestep: float = 0.05,
    physics_timestep: float = 0.001,
    pad_tolerance: float = 0.1,
    noslip_iterations: int = 5,
    sleep: bool = arena.SLEEP,
    render_size=(256, 256),
    multisamples: int = 4,
    raise_on_physics_error: bool = True,
    lazy_cameras: bool = False,
) -> Environment:
    """Builds a MuJoBan environment.

    The defaults are the original task (physics_planning_games' MuJoBan, with
    the paper's 0.05 s control step) but for ``sleep``: 1 ms physics steps, boxes of half-size
    0.4 m sliding on floor friction, pegs that block boxes and walker, and a
    pad covered while a box centre is within 0.1 cells of it along both axes.
    See `envs.mujoban.task` for the full list.

    Args:
      difficulty: 1-5 for one paper difficulty, None for the curriculum.
      pegs: grid pegs that block diagonal box motion (and the walker).
      seed: random seed (levels, wall and floor textures, initial heading).
      levels: a Boxoban-format file whose levels are played instead of
        generated ones.
      level_order: ``"sequential"`` (file order, from the first level again
        after the last) or ``"shuffle"`` (uniformly at random) for `levels`.
      grid_shape: arena size in cells; smaller levels are padded with walls.
      top_camera, egocentric_camera: ``(height, width)`` or None to switch off.
      lazy_cameras: render a camera frame only when the agent reads it from
        the timestep (before the next step); see `envs.core.Environment`.
      randomize_appearance: draw the wall and floor textures every episode.
      multisamples: samples per pixel of rendered frames; default 4, the
        original's (frames identical to its own). ``0`` is a cheaper look:
        object outlines move by up to a pixel, nothing else changes.
      time_limit: seconds (45 s = 900 control steps of 0.05 s).
      control_timestep: seconds per agent action (the paper's 0.05).
      physics_timestep: seconds per MuJoCo step; default 0.001 (the
        original's). ``0.005`` is a documented deviation: 5x cheaper physics,
        slightly different contact dynamics.
      pad_tolerance: cells (along both axes) a box centre may be from a pad
        centre while covering it; default 0.1 (the original's full-cell pad
        and 0.4 m box). ``0.3`` is the more lenient deviation.
      noslip_iterations: MuJoCo noslip solver iterations; default 5 (the
        original's). ``0`` is a documented deviation: ~2x faster on level 5.
      sleep: MuJoCo's sleeping of resting bodies; default True, a
        documented deviation (4-5x cheaper physics on Boxoban levels, the
        bodies' behaviour within 1% of the original's,
        `envs.mujoban.behaviour`). ``False`` is the original's
        (`envs.original_options`).
      render_size: largest ``(height, width)`` of `Environment.render` frames.
      raise_on_physics_error: raise on a diverging simulation (else the
        episode ends with discount 0).
    """
    options = dict(locals())  # the keyword arguments above: no other name is bound yet
    source = check_config(**options)
    return _build_environment(source, **options)


def _build_environment(
    source,
    *,
    difficulty,
    pegs,
    seed,
    grid_shape,
    top_camera,
    egocentric_camera,
    randomize_appearance,
    time_limit,
    control_timestep,
    physics_timestep,
    pad_tolerance,
    noslip_iterations,
    sleep,
    render_size,
    multisamples,
    raise_on_physics_error,
    lazy_cameras,
    **file_options,
) -> Environment:
    """Builds `make`'s environment from its checked arguments. ``source`` is
    `check_config`'s `sources.FileLevels` of the level file, or None for
    generated levels; ``file_options`` (``levels``, ``level_order``) were
    read into it and are not needed again."""
    if source is None:
        source = (
            sources.CurriculumLevels()
            if difficulty is None
            else sources.GeneratedLevels(difficulty)
        )
    task = Mujoban(
        source,
        grid_shape=grid_shape,
        max_boxes=source.max_boxes,
        pegs=pegs,
        top_camera=top_camera,
        egocentric_camera=egocentric_camera,
        randomize_appearance=randomize_appearance,
        time_limit=time_limit,
        control_timestep=control_timestep,
        physics_timestep=physics_timestep,
        pad_tolerance=pad_tolerance,
        noslip_iterations=noslip_iterations,
        sleep=sleep,
        render_size=render_size,
        multisamples=multisamples,
    )
    return Environment(
        task, seed=seed, raise_on_physics_error=raise_on_physics_error, lazy_cameras=lazy_cameras
    )


def check_config(
    *,
    difficulty=None,
    pegs=False,
    seed=None,
    levels=None,
    level_order="sequential",
    grid_shape=sources.ARENA_SHAPE,
    top_camera=(96, 96),
    egocentric_camera=(96, 96),
    randomize_appearance=True,
    time_limit=45.0,
    control_timestep=0.05,
    physics_timestep=0.001,
    pad_tolerance=0.1,
    noslip_iterations=5,
    sleep=arena.SLEEP,
    render_size=(256, 256),
    raise_on_physics_error=True,
    lazy_cameras=False,
    multisamples=4,
):
    """Checks `make`'s arguments without building anything (`envs._config`).

    Returns the `sources.FileLevels` of ``levels`` (read and checked against
    the arena), or None without a file.

    Raises:
      TypeError, ValueError, LevelError: naming the bad setting and value.
    """
    if difficulty is not None:
        _config.check_int("difficulty", difficulty, 1, 5)
    _config.check_bool("pegs", pegs)
    _config.check_common(seed, render_size, raise_on_physics_error, lazy_cameras)
    _config.check_choice("level_order", level_order, ("sequential", "shuffle"))
    grid = _config.check_pair("grid_shape", grid_shape, 3, _config.MAX_GRID_SIDE)
    _config.check_camera("top_camera", top_camera)
    _config.check_camera("egocentric_camera", egocentric_camera)
    _config.check_bool("randomize_appearance", randomize_appearance)
    _config.check_timing(time_limit, control_timestep, physics_timestep)
    _config.check_real("pad_tolerance", pad_tolerance, low=0.0, low_open=True, high=0.5)
    _config.check_int("noslip_iterations", noslip_iterations, 0, _config.MAX_NOSLIP_ITERATIONS)
    _config.check_bool("sleep", sleep)
    _config.check_int("multisamples", multisamples, 0, 16)
    source = None
    if levels is not None:
        _config.check_path("levels", levels)
        try:
            source = sources.FileLevels(levels, shuffle=level_order == "shuffle")
        except (OSError, UnicodeDecodeError) as exc:
            raise LevelError(f"cannot read the level file: {exc}", path=str(levels)) from None
        _check_file_fits(source, grid)
        needed = None
    elif difficulty is None:
        needed = sources.ARENA_SHAPE
    else:
        needed = sources.GeneratedLevels(int(difficulty)).max_shape
    if needed is not None and (grid[0] < needed[0] or grid[1] < needed[1]):
        raise ValueError(
            f"grid_shape {_config._show(grid_shape)} is smaller than the "
            f"{needed[0]}x{needed[1]} levels of this environment"
        )
    return source


def _check_file_fits(source: sources.FileLevels, grid_shape: tuple[int, int]) -> None:
    """Raises LevelError, with file, level, line and column, for a level too large."""
    first_rows = _first_row_lines(source.path)
    for position, level in enumerate(source.levels):
        if level.height <= grid_shape[0] and level.width <= grid_shape[1]:
            continue
        first = first_rows[position] if position < len(first_rows) else None
        if level.width > grid_shape[1]:  # the first cell outside the arena
            line, column = first, grid_shape[1] + 1
        else:
            line, column = (first + grid_shape[0] if first else None), 1
        try:
            index = int(level.name) if level.name is not None else position
        except (TypeError, ValueError):
            index = position
        raise LevelError(
            f"level is {level.height}x{level.width}, larger than the arena's "
            f"{grid_shape[0]}x{grid_shape[1]} (pass grid_shape=(rows, cols) to enlarge it)",
            path=str(source.path),
            index=index,
            line=line,
            column=column,
        )


def _first_row_lines(path) -> list[int]:
    """1-based line number of each level's first row in a level file."""
    starts, inside = [], False
    with open(path) as f:
        for number, text in enumerate(f, start=1):
            row = text.rstrip("\r\n")
            if not row.strip() or row.startswith(";"):
                inside = False
            elif not inside:
                starts.append(number)
                inside = True
    return starts


def _register() -> None:
    for pegs in (False, True):
        suffix = "-pegs" if pegs else ""
        peg_text = " with grid pegs" if pegs else ""
        for difficulty in range(1, 6):
            register(
                EnvEntry(
                    f"mujoban/level{difficulty}{suffix}",
                    make,
                    {"difficulty": difficulty, "pegs": pegs},
                    f"MuJoBan, generated difficulty-{difficulty} levels{peg_text}",
                    validate=check_config,
                    original=arena.ORIGINAL,
                )
            )
        register(
            EnvEntry(
                f"mujoban/curriculum{suffix}",
                make,
                {"difficulty": None, "pegs": pegs},
                f"MuJoBan, the paper's 5-level training curriculum{peg_text}",
                validate=check_config,
                original=arena.ORIGINAL,
            )
        )


_register()

__all__ = ["Level", "LevelError", "Mujoban", "make", "sources"]
