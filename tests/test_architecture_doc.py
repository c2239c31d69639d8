"""The recipes of docs/architecture.md run as written."""

import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"


def test_the_recipes_run(tmp_path):
    from hier_agents.modular.components import ESTIMATORS, PLANNERS

    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)
    assert len(blocks) == 4
    saved = (
        {fam: dict(PLANNERS[fam]) for fam in PLANNERS},
        {fam: dict(ESTIMATORS[fam]) for fam in ESTIMATORS},
    )
    namespace = {"tmp": tmp_path, "__name__": "architecture_doc"}
    try:
        for block in blocks:
            exec(compile(block, str(DOC), "exec"), namespace)
    finally:
        for table, copy in zip((PLANNERS, ESTIMATORS), saved):
            for fam, entries in copy.items():
                table[fam].clear()
                table[fam].update(entries)
        from hier_agents.agents import KINDS
        from hier_agents.learning.skill_spec import SPECS

        SPECS.pop("reach", None)
        KINDS.pop("still", None)
