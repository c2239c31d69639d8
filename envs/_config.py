"""Cheap checks of `envs.load` overrides, run before anything is built.

Every registered factory has a validator (``EnvEntry.validate``) that looks
at each override's type and range without compiling a model, opening a GL
context or starting an engine; `envs.load` runs it first, so a bad value
fails in microseconds with a `TypeError` (wrong type) or `ValueError` (wrong
value; `envs.mujoban.LevelError` for a bad level file) whose message names
the setting and the value. The factories and tasks keep their own checks.
"""

from __future__ import annotations

import math
import numbers
import os

import numpy as np

#: Bounds that keep a valid-looking value from exhausting memory or time.
MAX_IMAGE_SIDE = 4096
MAX_SUBSTEPS = 10_000  # physics steps per control step
MAX_EPISODE_STEPS = 10_000_000  # control steps per episode
MAX_GRID_SIDE = 64
MAX_NOSLIP_ITERATIONS = 1_000


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def check_bool(name: str, value) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {_show(value)}")
    return bool(value)


def check_real(
    name: str, value, *, low: float | None = None, high: float | None = None, low_open: bool = False
) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {_show(value)}")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"{name} must be a finite number, got {_show(value)}")
    if low is not None and (number <= low if low_open else number < low):
        bound = f"> {low:g}" if low_open else f">= {low:g}"
        raise ValueError(f"{name} must be {bound}, got {_show(value)}")
    if high is not None and number > high:
        raise ValueError(f"{name} must be <= {high:g}, got {_show(value)}")
    return number


def check_int(name: str, value, low: int, high: int | None = None) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {_show(value)}")
    number = int(value)
    if number < low or (high is not None and number > high):
        allowed = f"{low}..{high}" if high is not None else f">= {low}"
        raise ValueError(f"{name} must be an integer in {allowed}, got {_show(value)}")
    return number


def check_seed(value) -> None:
    if value is not None:
        check_int("seed", value, 0)


def check_choice(name: str, value, choices) -> None:
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{name} must be one of {list(choices)}, got {_show(value)}")


def check_pair(name: str, value, low: int, high: int) -> tuple[int, int]:
    """A (rows, cols) / (height, width) pair of integers in low..high."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
        raise TypeError(f"{name} must be a (height, width) pair of integers, got {_show(value)}")
    if len(value) != 2:
        raise ValueError(f"{name} must be a (height, width) pair of integers, got {_show(value)}")
    first, second = (check_int(name, side, low, high) for side in value)
    return first, second


def check_camera(name: str, value) -> None:
    """A camera's ``(height, width)``, or None: off (`envs.load` takes False too)."""
    if value is None:
        return
    try:
        check_pair(name, value, 1, MAX_IMAGE_SIDE)
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"{exc}; None (false in TOML) switches it off") from None


def check_timing(time_limit, control_timestep, physics_timestep) -> None:
    control = check_real("control_timestep", control_timestep, low=0.0, low_open=True, high=10.0)
    physics = check_real("physics_timestep", physics_timestep, low=0.0, low_open=True)
    if physics > control:
        raise ValueError(
            f"physics_timestep {_show(physics_timestep)} must be <= "
            f"control_timestep {_show(control_timestep)}"
        )
    substeps = control / physics
    if substeps > MAX_SUBSTEPS:
        raise ValueError(
            f"physics_timestep {_show(physics_timestep)} gives {substeps:.3g} physics "
            f"steps per control step of {control:g} s (at most {MAX_SUBSTEPS})"
        )
    if abs(substeps - round(substeps)) > 1e-6:  # composer's own tolerance
        raise ValueError(
            f"control_timestep {_show(control_timestep)} must be a multiple of "
            f"physics_timestep {_show(physics_timestep)}"
        )
    limit = check_real("time_limit", time_limit, low=0.0, low_open=True)
    if limit / control > MAX_EPISODE_STEPS:
        raise ValueError(
            f"time_limit {_show(time_limit)} is more than {MAX_EPISODE_STEPS:,} "
            f"control steps of control_timestep {_show(control_timestep)} s"
        )


def check_common(seed, render_size, raise_on_physics_error, lazy_cameras) -> None:
    check_seed(seed)
    check_pair("render_size", render_size, 1, MAX_IMAGE_SIDE)
    check_bool("raise_on_physics_error", raise_on_physics_error)
    check_bool("lazy_cameras", lazy_cameras)


def check_path(name: str, value) -> None:
    if not isinstance(value, (str, os.PathLike)):
        raise TypeError(f"{name} must be a path (str or os.PathLike), got {_show(value)}")
    path = os.fspath(value)
    if isinstance(path, bytes) or not path or "\0" in path:
        raise ValueError(f"{name} must be a file path, got {_show(value)}")
