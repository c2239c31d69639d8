"""The speed benchmark's rows, and provenance."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _env_speed(tmp_path, *extra):
    out = tmp_path / "speed.json"
    subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "env_speed.py"),
            "--steps",
            "60",
            "--json",
            str(out),
            *extra,
        ],
        check=True,
        cwd=ROOT,
        capture_output=True,
    )
    return json.loads(out.read_text())


@pytest.mark.slow
def test_env_speed_rows_at_the_originals_timesteps_with_two_real_views(tmp_path):
    result = _env_speed(
        tmp_path,
        "--envs",
        "mujoban/level1",
        "mujoxo/mixture",
        "--cameras",
        "none",
        "front_camera",
        "front_camera+front_camera_2",
    )
    assert {"command", "commit", "date", "machine"} <= set(result["provenance"])
    rows = {(r["env"], tuple(r["cameras"])): r for r in result["rows"]}
    assert set(rows) == {
        ("mujoban/level1", ()),
        ("mujoxo/mixture", ()),
        ("mujoxo/mixture", ("front_camera",)),
        ("mujoxo/mixture", ("front_camera", "front_camera_2")),
    }
    mujoban, board = rows[("mujoban/level1", ())], rows[("mujoxo/mixture", ())]
    assert mujoban["physics_timestep"] == 0.001 and board["physics_timestep"] == 0.002
    for row in rows.values():
        assert row["steps_per_s"] > 0 and row["physics_limit_steps_per_s"] > 0
        # No figure of the original's here: benchmarks/original_speed.py measures it.
        assert "x_original" not in row


def test_env_speed_at_another_timestep_and_with_an_option(tmp_path):
    result = _env_speed(
        tmp_path,
        "--envs",
        "mujoban/level1",
        "--cameras",
        "none",
        "--physics-timestep",
        "0.005",
        "--env-option",
        "noslip_iterations=0",
    )
    (row,) = result["rows"]
    assert row["physics_timestep"] == 0.005 and row["env_options"] == {"noslip_iterations": 0}


def test_provenance_is_dirty_only_when_code_differs_from_the_commit(tmp_path):
    from hier_agents.provenance import _commit

    def git(*args):
        subprocess.run(
            ["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
            cwd=tmp_path,
            check=True,
            capture_output=True,
        )

    git("init", "-q")
    (tmp_path / "code.py").write_text("x = 1\n")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "speed.json").write_text("{}\n")
    git("add", "-A")
    git("commit", "-qm", "first")
    head = _commit(tmp_path)
    assert len(head) == 40
    (tmp_path / "results" / "speed.json").write_text('{"steps": 1}\n')  # a run rewrote its result
    (tmp_path / "notes.txt").write_text("untracked\n")
    assert _commit(tmp_path) == head
    (tmp_path / "code.py").write_text("x = 2\n")
    assert _commit(tmp_path) == head + "+dirty"


def test_sokoban_solver_benchmark_with_the_time_planner_never_estimates_slower(tmp_path):
    import importlib.util

    from envs.mujoban.levels import BOXOBAN_DIR

    if str(ROOT / "benchmarks") not in sys.path:
        sys.path.insert(0, str(ROOT / "benchmarks"))  # the scripts import `_common`
    spec = importlib.util.spec_from_file_location(
        "benchmark_sokoban_solver_run", ROOT / "benchmarks" / "sokoban_solver.py"
    )
    sokoban_solver = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(sokoban_solver)

    levels = BOXOBAN_DIR / "medium-valid-000.txt"
    push = sokoban_solver.run(levels, 10.0, limit=4)
    timed = sokoban_solver.run(levels, 10.0, limit=4, planner="sokoban-solver:time", weight=1.5)
    assert timed["planner"] == "sokoban-solver:time" and timed["weight"] == 1.5
    assert push["planner"] == "sokoban-solver" and push["weight"] is None
    assert timed["solved"] == push["solved"] == 4
    for a, b in zip(timed["levels"], push["levels"]):
        assert a["estimated_steps"] <= b["estimated_steps"] + 1e-6
    assert (
        sokoban_solver.main(
            [
                "--levels",
                str(levels),
                "--limit",
                "2",
                "--planner",
                "sokoban-solver:time",
                "--json",
                str(tmp_path / "s.json"),
            ]
        )
        == 0
    )


@pytest.mark.slow
def test_render_profile_rows_for_every_camera(tmp_path):
    out = tmp_path / "profile.json"
    subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "render_profile.py"),
            "--frames",
            "1",
            "--rounds",
            "1",
            "--json",
            str(out),
        ],
        check=True,
        cwd=ROOT,
        capture_output=True,
    )
    rows = json.loads(out.read_text())["rows"]
    cameras = {(r["case"], r["camera"]) for r in rows}
    assert len(cameras) == len(rows) == 10
    assert {r["multisamples"] for r in rows if "original" in r["case"]} == {4}
    for r in rows:
        for key in (
            "update_ms",
            "render_ms",
            "draw_ms",
            "readback_ms",
            "flip_ms",
            "frame_ms",
            "no_reflection_ms",
            "no_shadow_ms",
            "no_skybox_ms",
        ):
            assert r[key] >= 0, (r["case"], r["camera"], key)
