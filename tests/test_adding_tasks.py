"""The task-creation guide (docs/adding_tasks.md): every Python block runs as
written, in order, and the game example stays under 50 lines."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "adding_tasks.md"


def _blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", GUIDE.read_text(), flags=re.S)


def test_the_guide_has_its_two_examples():
    blocks = _blocks()
    assert len(blocks) == 2
    assert "register_game(" in blocks[0] and "register_mujoboard(" in blocks[0]
    assert "Mujoban(" in blocks[1] and "register(EnvEntry(" in blocks[1]


def test_adding_a_game_takes_under_50_lines():
    code = [
        line
        for line in _blocks()[0].splitlines()
        if line.strip() and not line.strip().startswith("#")
    ]
    assert len(code) < 50


@pytest.fixture
def registries():
    """The game and environment registries, restored after the test (the
    examples register names)."""
    import gymnasium

    from envs import registry
    from envs.boards.games import GAMES

    tables = (GAMES, registry._REGISTRY, gymnasium.envs.registration.registry)
    saved = [(table, dict(table)) for table in tables]
    yield
    for table, contents in saved:
        table.clear()
        table.update(contents)


@pytest.mark.parametrize("index", [0, 1], ids=["add-a-game", "add-a-grid-task"])
def test_every_guide_example_runs(index, registries):
    import gymnasium

    exec(compile(_blocks()[index], f"{GUIDE.name}[{index}]", "exec"), {"__name__": "guide"})
    name = ("mujoboard/four-on-five", "mujoban/corridors")[index]
    assert name in gymnasium.envs.registration.registry  # a gymnasium id too
