"""The learned skills' specs (`hier_agents.learning.skill_spec.SkillSpec`), by name.

`register_all(specs)` fills the ``name -> spec`` table
(`hier_agents.learning.skill_spec.SPECS`); each spec's module is imported
only then. One line per skill in ``_SPECS``: (name, module, attribute).
"""

from __future__ import annotations

import importlib

__all__ = ["register_all"]

#: (spec name, module, attribute) of every learned skill's spec.
_SPECS = (
    ("ball", "hier_agents.learning.skills.ball", "BALL_SPEC"),
    ("arm", "hier_agents.learning.skills.arm", "ARM_SPEC"),
)


def register_all(specs: dict) -> None:
    """Adds every known skill spec to ``specs`` (name -> `SkillSpec`)."""
    for name, module, attribute in _SPECS:
        specs[name] = getattr(importlib.import_module(module), attribute)
