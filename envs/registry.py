"""Named environments: ``envs.load(name, seed=None, **overrides)`` and ``envs.names()``.

Every name is also registered with gymnasium under the same id when ``envs``
is imported (``gymnasium.make("mujoban/level1")`` after ``import envs``, or
``gymnasium.make("envs:mujoban/level1")`` without it).
"""

from __future__ import annotations

import difflib
import inspect
from dataclasses import dataclass, field
from typing import Any, Callable

from envs.core import Environment
from physics_planning.cli import UsageError, close_hint


@dataclass(frozen=True)
class EnvEntry:
    """A registered environment: a factory plus its fixed keyword arguments."""

    name: str
    factory: Callable[..., Environment]
    kwargs: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    #: Checks the factory's keyword arguments (seed included) without building
    #: anything; raises TypeError/ValueError naming the bad value (`check`).
    validate: Callable[..., Any] | None = None
    #: The original implementation's values of the settings whose defaults here
    #: differ from them (`original_options`); empty when every default is the
    #: original's.
    original: dict[str, Any] = field(default_factory=dict)


_REGISTRY: dict[str, EnvEntry] = {}


def register(entry: EnvEntry) -> None:
    """Makes ``entry.name`` loadable with `load` and, as the same id, with
    ``gymnasium.make``. Raises ValueError when the name is taken."""
    if entry.name in _REGISTRY:
        raise ValueError(f"environment {entry.name!r} is already registered")
    _REGISTRY[entry.name] = entry
    gymnasium_id(entry.name)


def gymnasium_id(name: str) -> None:
    """Registers ``name`` with gymnasium (idempotent): ``gymnasium.make(name)``
    builds `envs.gymnasium_env.GymnasiumEnv` on it, ``gymnasium.make_vec(name,
    num_envs)`` an `envs.vector.BatchedVectorEnv`."""
    import gymnasium

    if name not in gymnasium.envs.registration.registry:
        gymnasium.register(
            id=name,
            entry_point="envs.gymnasium_env:GymnasiumEnv",
            vector_entry_point="envs.vector:make",
            kwargs={"env_name": name},
        )


def names() -> list[str]:
    """All registered environment names, sorted."""
    return sorted(_REGISTRY)


def describe(name: str) -> str:
    return _entry(name).description


def overrides(name: str) -> list[str]:
    """Keyword overrides that `load` accepts for `name`."""
    entry = _entry(name)
    params = inspect.signature(entry.factory).parameters
    return sorted(p for p in params if p not in entry.kwargs and p != "seed")


def no_cameras(name: str) -> dict[str, None]:
    """The overrides that turn off every camera of `name` (nothing is rendered):
    ``envs.load(name, **envs.no_cameras(name))``."""
    return {k: None for k in overrides(name) if k.endswith("_camera")}


def original_options(name: str) -> dict[str, Any]:
    """The overrides that give `name` the original implementation's settings
    where our defaults deviate from them (MuJoBan: ``{"sleep": False}``):
    ``envs.load(name, **envs.original_options(name))``. Empty when every
    default is the original's."""
    return dict(_entry(name).original)


def explicit_options(name: str, overrides: dict | None = None) -> dict[str, Any]:
    """``overrides`` with the value of every setting whose default deviates
    from the original's (`original_options`) named: what a run records, so
    that its record keeps its meaning when a default changes
    (`recorded_options` reads it back)."""
    entry = _entry(name)
    defaults = _defaults(entry)
    return {**{k: defaults[k] for k in entry.original}, **(overrides or {})}


def recorded_options(name: str, overrides: dict | None = None) -> dict[str, Any]:
    """The `envs.load` overrides a run's record of ``overrides`` stands for:
    a setting whose default deviates from the original's and that the record
    does not name (a run recorded before that default deviated) is the
    original's (`original_options`); `explicit_options` records name it."""
    return {**original_options(name), **(overrides or {})}


def deviations(name: str, options: dict | None = None) -> dict[str, Any]:
    """The settings of ``envs.load(name, **options)`` that differ from the
    original implementation's: ``options`` without those equal to the
    original's value (the factory's default, or `original_options`), plus
    each default that deviates from the original and ``options`` leaves as it
    is. Sequences become lists and a camera given as False becomes None, so
    equal settings give equal (JSON-able) dicts, sorted by key; a comparison's
    job keys name an environment so (`hier_agents.compare.jobs`).
    ``envs.load(name, **envs.original_options(name), **deviations(name, options))``
    builds the same environment as ``envs.load(name, **options)``.

    Raises:
      UnknownEnvironmentError, TypeError, ValueError: as `check`.
    """
    options = dict(options or {})
    check(name, **options)
    entry = _entry(name)
    defaults = _defaults(entry)
    reference = {**defaults, **entry.original}
    chosen = {**{k: defaults[k] for k in entry.original}, **_cameras_off(options)}
    out = {}
    for key in sorted(chosen):
        value = _plain(chosen[key])
        if key not in reference or value != _plain(reference[key]):
            out[key] = value
    return out


def _defaults(entry: EnvEntry) -> dict[str, Any]:
    """The factory's keyword defaults of ``entry``."""
    params = inspect.signature(entry.factory).parameters
    return {k: p.default for k, p in params.items() if p.default is not p.empty}


def _plain(value):
    """``value`` with tuples as lists (how JSON stores them)."""
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _cameras_off(kwargs: dict) -> dict:
    """``kwargs`` with a camera override of False made None (off): TOML, which
    has no null, switches a camera off with ``false``."""
    return {k: None if v is False and _is_camera(k) else v for k, v in kwargs.items()}


def _is_camera(key: str) -> bool:
    """Whether the override ``key`` sizes a camera (``top_camera``, ``front_camera_2``)."""
    return key.endswith("_camera") or "_camera_" in key


def check(name: str, seed: int | None = None, **kwargs) -> None:
    """Checks a configuration as `load` would, without building anything (no
    model compiled, no GL context, no engine started): microseconds.

    Raises:
      UnknownEnvironmentError: unknown name (a KeyError and a ValueError).
      TypeError: an override the environment does not have (the message
        names the closest valid one and lists them all), or of the wrong type.
      ValueError: a value out of range (`envs.mujoban.LevelError` for a bad
        level file); the message names the setting and the value.
    """
    entry = _entry(name)
    valid = overrides(name)
    unknown = sorted(set(kwargs) - set(valid))
    if unknown:
        raise TypeError(unknown_keywords_message(name, unknown, valid, "override"))
    if entry.validate is not None:
        entry.validate(seed=seed, **entry.kwargs, **_cameras_off(kwargs))


def unknown_keywords_message(name: str, unknown, valid, kind: str) -> str:
    """``"NAME: unknown KIND(s) 'x' (did you mean 'y'?); valid KINDs: [...]"``."""
    words = ", ".join(f"{k!r}{close_hint(k, valid)}" for k in unknown)
    plural = "s" if len(unknown) > 1 else ""
    return f"{name}: unknown {kind}{plural} {words}; valid {kind}s: {valid}"


def load(name: str, seed: int | None = None, **kwargs) -> Environment:
    """Builds the named environment as a dm_env ``Environment``.

    Args:
      name: one of `names()`, e.g. ``"mujoban/level5-pegs"``.
      seed: seed of the environment's random generator.
      **kwargs: overrides of the environment's settings, e.g.
        ``levels="file.txt"``, ``top_camera=None`` (or False: a camera off);
        `overrides(name)` lists them.

    Raises:
      KeyError: unknown name (the message lists the known ones;
        `UnknownEnvironmentError`, also a ValueError).
      TypeError: an override the environment does not have, or of the wrong type.
      ValueError: a value out of range. Bad configurations fail in `check`,
        before anything is built.
    """
    check(name, seed, **kwargs)
    entry = _entry(name)
    return entry.factory(seed=seed, **entry.kwargs, **_cameras_off(kwargs))


class UnknownEnvironmentError(UsageError, KeyError):
    """`load` was given a name that is not registered (a `UsageError`, so a
    command reports it in one line; also a KeyError)."""

    def __str__(self) -> str:  # KeyError would show the message's repr
        return str(self.args[0]) if self.args else ""


def _entry(name: str) -> EnvEntry:
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):  # TypeError: an unhashable name
        close = difflib.get_close_matches(str(name), _REGISTRY, n=3)
        hint = f" Did you mean {close}?" if close else ""
        raise UnknownEnvironmentError(
            f"unknown environment {name!r}.{hint} Known environments: {names()}"
        ) from None
