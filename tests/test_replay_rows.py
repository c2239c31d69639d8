"""benchmarks/replay_rows.py: re-plays committed agent rows and compares them."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def replay_rows():
    if str(ROOT / "benchmarks") not in sys.path:
        sys.path.insert(0, str(ROOT / "benchmarks"))  # the scripts import `_common`
    spec = importlib.util.spec_from_file_location(
        "benchmark_replay_rows", ROOT / "benchmarks" / "replay_rows.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ROW = {
    "episode": 3,
    "return": 11.0,
    "steps": 23,
    "wall_s": 1.68,
    "subgoals_issued": 1,
    "subgoals_reached": 1,
    "estimation_failures": 0,
    "solved": True,
}


def test_a_row_differing_in_steps_differs_and_one_differing_only_in_time_is_identical(replay_rows):
    diffs, _ = replay_rows.compare_rows(ROW, {**ROW, "steps": 25, "wall_s": 9.0})
    assert diffs == [{"key": "steps", "committed": 23, "replayed": 25, "delta": 2}]
    assert replay_rows.compare_rows(ROW, {**ROW, "wall_s": 0.1, "profile_s": {"render": 1}}) == (
        [],
        [],
    )
    # A failure reason on one side only is a difference; a key only newer rows
    # record (estimates) is listed, not counted.
    diffs, one_sided = replay_rows.compare_rows(
        ROW, {**ROW, "solved": False, "failure_reason": "time limit", "estimates": 23}
    )
    assert {d["key"] for d in diffs} == {"solved", "failure_reason"}
    assert one_sided == ["estimates"]


def test_settings_that_cannot_be_replayed_are_skipped_with_the_reason(replay_rows):
    base = {
        "env": "mujoban/level5-pegs",
        "seed": 0,
        "agent": "modular",
        "planner": "sokoban-solver",
        "skill": "ball",
        "estimator": "camera",
        "env_options": {},
        "levels": "envs/mujoban/data/boxoban/unfiltered-valid-000.txt",
    }
    assert replay_rows.settings(base)["levels"].endswith("unfiltered-valid-000.txt")
    # A file from before summaries recorded deviations played the original's physics.
    assert replay_rows.settings(base)["env_options"] == {"sleep": False}
    now = {**base, "deviations": {"sleep": True, "time_limit": 5.0}}
    assert replay_rows.settings(now)["env_options"] == {"sleep": True, "time_limit": 5.0}
    with pytest.raises(replay_rows.Skip, match="not in the repository"):
        replay_rows.settings({**base, "levels": "/tmp/no_such_levels.txt"})
    with pytest.raises(replay_rows.Skip, match="estimator"):
        replay_rows.settings({k: v for k, v in base.items() if k != "estimator"})
    with pytest.raises(replay_rows.Skip, match="not present"):
        replay_rows.settings({**base, "skill": "learned-ball:runs/none/ball_policy.pt"})
    with pytest.raises(replay_rows.Skip, match="episode index"):
        replay_rows._committed_rows({"rows": [{"steps": 3}]})


def test_the_script_replays_one_committed_episode_identically(replay_rows, tmp_path):
    # A row recorded on the original's physics, before summaries named their
    # deviations from it: replayed on those settings (sleep=False), not today's default.
    out = tmp_path / "replay.json"
    status = replay_rows.main(
        [
            str(ROOT / "results/agent_original_physics/mujoban_level1.json"),
            *("--episodes", "1", "--json", str(out)),
        ]
    )
    assert status == 0
    report = json.loads(out.read_text())
    assert report["identical"] is True and report["replayed"] == 1 and report["skipped"] == []
    (entry,) = report["files"]
    assert entry["file"] == "results/agent_original_physics/mujoban_level1.json"
    assert entry["episodes"] == [0]
    assert entry["identical"] is True and entry["differences"] == []
    assert entry["commit"] and entry["settings"]["env"] == "mujoban/level1"
    assert len(entry["rows"]) == 1 and entry["rows"][0]["episode"] == 0
    assert "commit" in report["provenance"]

    # The same file with its first row's steps changed: reported, exit status 1.
    summary = json.loads((ROOT / "results/agent_original_physics/mujoban_level1.json").read_text())
    steps = summary["rows"][0]["steps"]
    summary["rows"][0]["steps"] = steps + 5
    changed = tmp_path / "changed.json"
    changed.write_text(json.dumps(summary))
    assert replay_rows.main([str(changed), "--episodes", "1", "--json", str(out)]) == 1
    (entry,) = json.loads(out.read_text())["files"]
    assert entry["identical"] is False
    assert entry["differences"] == [
        {"episode": 0, "key": "steps", "committed": steps + 5, "replayed": steps, "delta": -5}
    ]


def test_bad_input_is_one_line_and_status_2(replay_rows, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        replay_rows.main(["--only", "no-such-file-*", "--json", str(tmp_path / "r.json")])
    assert exit_info.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_a_replay_is_compared_with_a_baseline_reports_rows(replay_rows):
    entry = {"rows": [ROW, {**ROW, "episode": 4}]}
    replay_rows._against_baseline(entry, {3: {**ROW, "wall_s": 5.0}, 4: {**ROW, "episode": 4}})
    assert entry["baseline_identical"] is True and entry["baseline_differences"] == []
    replay_rows._against_baseline(entry, {3: {**ROW, "steps": 30}})
    assert entry["baseline_identical"] is False and entry["baseline_missing"] == [4]
    assert entry["baseline_differences"] == [
        {"episode": 3, "key": "steps", "committed": 30, "replayed": 23, "delta": -7}
    ]
