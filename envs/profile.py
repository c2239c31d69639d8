"""Where a run's time goes: exclusive wall-clock seconds per named section.

`PROFILE` is this process's profiler, off by default (a section then costs
one attribute check). When on, ``with PROFILE.section("render"):`` adds the
time spent inside the block to ``"render"``, minus the time of sections
opened inside it, so nested sections are never counted twice: a camera
rendered while an estimator reads a lazy frame counts as ``render``, not
``estimator``. The sections the library opens:

* ``physics``: `envs.Environment` reset and step (the simulation, the task's
  hooks and observations), rendering excluded;
* ``render``: camera frames (`envs.rendering.Cameras.render`);
* ``estimator``, ``planner``, ``skill``: the modular agent's parts
  (`hier_agents.modular`).

`hier_agents.run` (``--profile``) turns them into shares of each episode's
wall time, the rest being ``other`` (the agent's own loop, the observation
boundary, Python).
"""

from __future__ import annotations

import time

#: The sections the library opens, in report order.
SECTIONS = ("physics", "render", "estimator", "planner", "skill")


class _Off:
    __slots__ = ()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


_OFF = _Off()


class _Section:
    __slots__ = ("_profile", "_name", "_start")

    def __init__(self, profile: "Profile", name: str):
        self._profile, self._name = profile, name

    def __enter__(self):
        self._start = time.perf_counter()
        self._profile._stack.append(0.0)  # time of sections nested inside this one
        return self

    def __exit__(self, *exc):
        profile = self._profile
        elapsed = time.perf_counter() - self._start
        nested = profile._stack.pop()
        profile.totals[self._name] = profile.totals.get(self._name, 0.0) + elapsed - nested
        if profile._stack:
            profile._stack[-1] += elapsed
        return False


class Profile:
    """Exclusive seconds per section name (``totals``) while ``enabled``."""

    def __init__(self) -> None:
        self.enabled = False
        self.totals: dict[str, float] = {}
        self._stack: list[float] = []

    def section(self, name: str):
        """A context manager timing its block as ``name`` (a no-op when off)."""
        return _Section(self, name) if self.enabled else _OFF

    def take(self) -> dict[str, float]:
        """The totals since the last `take` (or since enabled), then zeroed."""
        out, self.totals = self.totals, {}
        return out


#: This process's profiler.
PROFILE = Profile()
