"""The wheel users install (`pip install .`, not editable) holds every
package and the data the commands need: the shipped Boxoban levels and
licence, the learned checkpoints."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_wheel_holds_the_packages_levels_and_checkpoints(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    (wheel,) = tmp_path.glob("physics_planning-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for package in ("physics_planning", "envs", "skills", "abstract_planners", "hier_agents"):
        assert f"{package}/__init__.py" in names, package
    for path in (
        "hier_agents/agents/runner.py",
        "envs/mujoban/data/boxoban/LICENSE",
        "envs/mujoban/data/boxoban/medium-valid-000.txt",
        "envs/mujoban/data/boxoban/hard-001-200.txt",
        "skills/learned/ball_policy.pt",
        "skills/learned/arm_policy.pt",
        "abstract_planners/learned/options.pt",
    ):
        assert path in names, path
    assert not any(name.startswith(("tests/", "benchmarks/", "results/")) for name in names)
