"""The agent kinds' registry: kinds by name, ``NAME[:ARG]`` resolved in one place.

The shipped kinds (`hier_agents.agents.kinds.SHIPPED`) are registered on
first use; `register` adds another without touching the runner,
``hier_agents.run`` or ``hier_agents.compare``. A package outside this one
registers its kinds in every process (worker processes, comparison jobs) by
declaring an entry point in the group `ENTRY_POINTS`
(``physics_planning.agents``) naming an `AgentKind` instance (registered
when it loads) or a module that calls `register`.
"""

from __future__ import annotations

from hier_agents.agents.base import AgentKind
from physics_planning.cli import UsageError, close_hint

__all__ = ["ENTRY_POINTS", "KINDS", "forms", "kind_of", "register", "resolve"]

#: name -> kind, in registration order (``modular`` first: the default).
KINDS: dict[str, AgentKind] = {}


def register(kind: AgentKind) -> AgentKind:
    """Makes ``kind`` playable by name everywhere; returns it. ValueError when
    the name is taken or not a plain word."""
    if not kind.name or ":" in kind.name or kind.name in KINDS:
        raise ValueError(
            f"cannot register the agent kind {kind.name!r}: empty, with ':' or "
            f"taken (registered: {', '.join(KINDS)})"
        )
    KINDS[kind.name] = kind
    return kind


#: The entry-point group of agent kinds defined outside this package.
ENTRY_POINTS = "physics_planning.agents"
_loaded = False


def _kinds() -> dict[str, AgentKind]:
    """The registry, with the shipped kinds and those of installed packages'
    `ENTRY_POINTS` loaded (once per process)."""
    global _loaded
    if not _loaded:
        _loaded = True
        from importlib.metadata import entry_points

        from hier_agents.agents.kinds import SHIPPED

        for shipped in SHIPPED:
            if shipped.name not in KINDS:
                register(shipped)
        for point in entry_points(group=ENTRY_POINTS):
            loaded = point.load()
            if isinstance(loaded, AgentKind) and loaded.name not in KINDS:
                register(loaded)
    return KINDS


def forms() -> list[str]:
    """Every accepted ``--agent`` form, in registration order."""
    return [form for kind in _kinds().values() for form in kind.forms()]


def resolve(spec: str) -> tuple[AgentKind, object]:
    """(kind, parsed argument) of ``NAME`` or ``NAME:ARG``.

    Raises:
      UsageError: an unknown kind (naming the closest and the valid forms), a
        missing, unexpected or malformed argument.
    """
    kinds = _kinds()
    name, sep, text = str(spec).partition(":")
    kind = kinds.get(name)
    if kind is None:
        raise UsageError(
            f"unknown agent {spec!r}{close_hint(name, kinds)}; valid: {', '.join(forms())}"
        )
    if not sep:
        if kind.arg_required:
            raise UsageError(f"the agent {name!r} needs an argument: {name}:{kind.metavar}")
        return kind, kind.default()
    return kind, kind.parse(text)


def kind_of(spec: str) -> AgentKind:
    """The kind named by ``spec``'s ``NAME`` (UsageError when unknown)."""
    kinds = _kinds()
    name = str(spec).partition(":")[0]
    if name not in kinds:
        raise UsageError(
            f"unknown agent {spec!r}{close_hint(name, kinds)}; valid: {', '.join(forms())}"
        )
    return kinds[name]
