"""Which cases of a parametrized test the README's test command runs.

A test parametrized over a product of choices (families, estimators,
planners, skills, names) runs every case with the slow tests
(``python -m pytest -m slow``) and, with the README's test command, a
covering subset: every value of every facet appears in at least one fast
case, so a choice that breaks on its own still fails the fast suite; the
pairings the subset leaves out are checked by the slow suite.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterable, Sequence
from typing import Any

import pytest


def cover(cases: Sequence[Any], facets: Callable[..., Iterable[Hashable]]) -> list[Any]:
    """Return ``cases`` with all but a covering subset marked slow.

    Args:
      cases: plain argument values (one value or a tuple per case) or
        ``pytest.param`` sets; their ids and marks are kept.
      facets: called with a case's arguments, returns the features it
        covers, e.g. ``[("family", fam), ("estimator", fam, est)]``.

    Returns:
      The cases in their order, those outside the subset as ``pytest.param``
      with ``pytest.mark.slow`` added. The subset is chosen greedily (the
      case covering the most uncovered features first, the earliest on a
      tie), so it is the same on every collection.

    Raises:
      ValueError: if ``cases`` is empty.
    """
    if not cases:
        raise ValueError("cover() needs at least one case")
    sets = [_as_param(case) for case in cases]
    features = [set(facets(*case.values)) for case in sets]
    uncovered = set().union(*features)
    fast: set[int] = set()
    while uncovered:
        best = max(range(len(sets)), key=lambda i: (len(features[i] & uncovered), -i))
        fast.add(best)
        uncovered -= features[best]
    if not fast:  # no case names a feature: keep the first one fast
        fast.add(0)
    return [
        case
        if i in fast
        else pytest.param(*case.values, marks=[*case.marks, pytest.mark.slow], id=case.id)
        for i, case in enumerate(sets)
    ]


def _as_param(case: Any):
    if hasattr(case, "values") and hasattr(case, "marks"):
        return case
    values = case if isinstance(case, tuple) else (case,)
    return pytest.param(*values)


def family_and_game(name: str) -> list[tuple]:
    """Facets of a registered environment name for `cover`: its family, and
    what changes the code it runs within the family (MuJoBan's pegs; a
    MuJoBoard game's input rule, layout and look)."""
    from envs.boards.games import GAMES
    from envs.boards.mujoboard import REGISTERED

    family, _, variant = name.partition("/")
    facets: list[tuple] = [("family", family)]
    if family == "mujoban":
        facets.append(("pegs", variant.endswith("-pegs")))
    elif family == "mujoboard":
        game = {entry[0]: entry[1] for entry in REGISTERED}[variant]
        rules = GAMES[game]
        facets += [("input", rules.input), ("layout", rules.layout), ("look", rules.look)]
    return facets
