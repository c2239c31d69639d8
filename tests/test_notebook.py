"""The notebooks run from top to bottom (small settings) and show what they are committed with.

Each notebook is committed with the outputs of a full-size run
(``python notebooks/save_outputs.py notebooks/*.ipynb``). The test runs
it with ``NOTEBOOK_SMALL=1`` (fewer episodes, smaller budgets) and checks that
every code cell still produces the kinds of output its committed copy shows
(text on stdout, images), plus a few strings that say the run did its job.
"""

from __future__ import annotations

import pytest

import os
from pathlib import Path

import nbformat
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"
#: Committed notebooks stay small enough to read and review.
MAX_BYTES = 1_500_000


def _kinds(cell) -> list[str]:
    """What a code cell shows: ``stdout`` and the MIME types of its displays
    (stderr, warnings among it, depends on the machine and is left out)."""
    kinds = []
    for out in cell.get("outputs", []):
        if out["output_type"] == "stream":
            if out["name"] == "stdout":
                kinds.append("stdout")
        elif out["output_type"] == "error":
            kinds.append("error")
        else:
            kinds.extend(sorted(k for k in out.get("data", {}) if k != "text/plain"))
    return sorted(set(kinds))


def _text(notebook) -> str:
    return "".join(
        out.get("text", "")
        for cell in notebook.cells
        if cell.cell_type == "code"
        for out in cell.get("outputs", [])
    )


def _run(name: str, monkeypatch, tmp_path):
    """(committed, executed) copies of ``notebooks/<name>``; the executed one
    ran with the small settings and its temporary files in ``tmp_path``."""
    path = NOTEBOOKS / name
    monkeypatch.setenv("NOTEBOOK_SMALL", "1")
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    committed = nbformat.read(path, as_version=4)
    executed = nbformat.read(path, as_version=4)
    NotebookClient(
        executed,
        timeout=600,
        kernel_name="python3",
        resources={"metadata": {"path": str(NOTEBOOKS)}},
    ).execute()
    return committed, executed


def _check_shows_what_it_is_committed_with(path: Path, committed, executed) -> None:
    assert path.stat().st_size < MAX_BYTES
    code = [(c, e) for c, e in zip(committed.cells, executed.cells) if c.cell_type == "code"]
    assert all(c.get("execution_count") for c, _ in code), f"{path.name}: committed unexecuted"
    for k, (c, e) in enumerate(code):
        assert _kinds(e) == _kinds(c), (
            f"{path.name}, code cell {k}: shows {_kinds(e)}, committed with {_kinds(c)}"
        )
    assert any("image/png" in _kinds(c) for c, _ in code), f"{path.name}: no image"


@pytest.mark.slow
def test_swap_planners_and_skills_notebook(monkeypatch, tmp_path):
    path = NOTEBOOKS / "swap_planners_and_skills.ipynb"
    committed, executed = _run(path.name, monkeypatch, tmp_path)
    _check_shows_what_it_is_committed_with(path, committed, executed)
    for text in (_text(executed), _text(committed)):
        assert "solved" in text and "skill arm-touch" in text and "skill learned-arm" in text


@pytest.mark.slow
def test_train_and_swap_a_learned_part_notebook(monkeypatch, tmp_path):
    path = NOTEBOOKS / "train_and_swap_a_learned_part.ipynb"
    committed, executed = _run(path.name, monkeypatch, tmp_path)
    _check_shows_what_it_is_committed_with(path, committed, executed)
    for text in (_text(executed), _text(committed)):
        assert "behaviour cloning" in text and "DAgger" in text
        assert "95% Wilson" in text and "my-ball" in text and "learned-ball" in text
    assert "budget: 200 cloning" in _text(executed)
    assert "budget: 3000 cloning" in _text(committed)
    # The run directory was made in the temporary directory and removed by the notebook.
    assert not any(tmp_path.glob("learned_ball_*"))
    assert not any(NOTEBOOKS.glob("**/ball_policy.pt"))
