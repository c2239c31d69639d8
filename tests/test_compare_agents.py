"""`benchmarks/compare_agents.py`: modular specs, checkpoint curves, the random floors, the plot."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

from hier_agents.baselines.impala.learner import TrainConfig, train

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # for its `_common` import
_spec = importlib.util.spec_from_file_location("compare_agents",
                                               ROOT / "benchmarks" / "compare_agents.py")
compare = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(compare)

TINY = dict(env="mujoban/level1", cameras=False, unroll_length=5, batch_size=2, actors=1,
            envs_per_actor=2, log_every_s=0.0, progress=False)


def test_modular_specs_parse_and_bad_ones_name_the_part():
    assert compare.parse_modular("default") == {}
    assert compare.parse_modular("planner=random, skill=learned-ball") == {
        "planner": "random", "skill": "learned-ball"}
    for bad in ("planer=random", "skill", "skill=", "skill=a,skill=b"):
        with pytest.raises(ValueError, match="skill|planer"):
            compare.parse_modular(bad)


def _row(agent, series, frames, lo, hi):
    return {"agent": agent, "series": series, "training_frames": frames,
            "success_interval": [lo, hi]}


def test_a_series_clears_a_floor_only_when_its_interval_is_wholly_above():
    rows = [_row("checkpoint:a", "run", 100, 0.50, 0.70),   # overlaps random:10
            _row("checkpoint:b", "run", 200, 0.72, 0.90),   # above both
            _row("modular", "modular default", 0, 0.97, 1.0),
            _row("random:1", "random:1", 0, 0.10, 0.30),
            _row("random:10", "random:10", 0, 0.60, 0.71)]
    floors = compare.floor_summary(rows)
    assert floors["run"]["random:1"] == {"first_frames": 100, "largest_frames_tried": 200}
    assert floors["run"]["random:10"]["first_frames"] == 200
    assert floors["modular default"]["random:10"]["first_frames"] == 0
    rows[1]["success_interval"] = [0.70, 0.9]  # touches the floor's upper end: not cleared
    assert compare.floor_summary(rows)["run"]["random:10"]["first_frames"] is None


@pytest.mark.slow
def test_curves_learned_skill_frames_floors_and_plot(tmp_path):
    run_dir = tmp_path / "run"
    train(TrainConfig(condition="vanilla", steps=20, logdir=str(run_dir), state=True,
                      keep_checkpoints=True, checkpoint_every_s=0.0, **TINY))
    pairs = compare.expand_checkpoints([run_dir], curve=True, max_frames=None)
    assert [p.name for _, p in pairs] == ["frames-10.pt", "frames-20.pt"]
    assert [p.name for _, p in compare.expand_checkpoints([run_dir], True, 10)] == ["frames-10.pt"]
    assert [p.name for _, p in compare.expand_checkpoints([run_dir], True, None, [15, 19, 5])
            ] == ["frames-10.pt"]
    assert [p.name for _, p in compare.expand_checkpoints([run_dir], False, None)] == [
        "checkpoint.pt"]
    with pytest.raises(FileNotFoundError):
        compare.expand_checkpoints([tmp_path / "nothing"], True, None)

    out, png = tmp_path / "compare.json", tmp_path / "compare.png"
    proc = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "compare_agents.py"), "mujoban/level1",
         "--episodes", "2", "--modular", "default", "skill=learned-ball",
         "--checkpoint", str(run_dir), "--curve", "--random", "10",
         "--json", str(out), "--plot", str(png), "--no-progress"],
        check=True, capture_output=True, text=True, cwd=ROOT)
    data = json.loads(out.read_text())
    rows = data["rows"]
    assert [r["series"] for r in rows] == ["modular default", "modular skill=learned-ball",
                                           str(run_dir), str(run_dir), "random:10"]
    import torch
    meta = torch.load(ROOT / "skills" / "learned" / "ball_policy.pt", weights_only=True)["meta"]
    assert [r["training_frames"] for r in rows] == [0, meta["sim_steps"], 10, 20, 0]
    assert rows[0]["success_rate"] == 1.0 and rows[1]["success_rate"] == 1.0
    assert "PRIVILEGED" in rows[2]["observations"] and "cameras" in rows[0]["observations"]
    assert rows[2]["checkpoint_config"]["state"] is True
    assert set(data["clears_random_floor"]) == {"modular default", "modular skill=learned-ball",
                                                str(run_dir)}
    assert "first training budget clearing" in proc.stdout
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"

    # --reuse: the rows already played come back as they were, marked; new ones are played.
    out2 = tmp_path / "compare2.json"
    subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "compare_agents.py"), "mujoban/level1",
         "--episodes", "2", "--modular", "default", "planner=random",
         "--checkpoint", str(run_dir), "--curve", "--random", "10", "--reuse", str(out),
         "--json", str(out2), "--no-progress"], check=True, capture_output=True, text=True,
        cwd=ROOT)
    again = json.loads(out2.read_text())
    assert [r.get("reused", False) for r in again["rows"]] == [True, False, True, True, True]
    assert again["rows"][0]["success_rate"] == rows[0]["success_rate"]
    assert again["rows"][1]["planner"] == "random"
    assert again["reused_from"]["provenance"] == data["provenance"]
    # --keep-rows-of: the agents named are played again; every other row of the
    # earlier run is kept, marked, in its place, though its checkpoint is gone.
    import shutil
    shutil.rmtree(run_dir)
    out3 = tmp_path / "compare3.json"
    subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "compare_agents.py"), "mujoban/level1",
         "--episodes", "2", "--modular", "skill=learned-ball", "--random",
         "--keep-rows-of", str(out), "--json", str(out3), "--no-progress"],
        check=True, capture_output=True, text=True, cwd=ROOT)
    kept = json.loads(out3.read_text())
    assert [r["series"] for r in kept["rows"]] == [r["series"] for r in rows]
    assert [r.get("reused", False) for r in kept["rows"]] == [True, False, True, True, True]
    assert kept["reused_from"]["provenance"] == data["provenance"]
    assert set(kept["clears_random_floor"]) == set(data["clears_random_floor"])
    bad = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "compare_agents.py"), "mujoban/level1",
         "--episodes", "3", "--random", "10", "--reuse", str(out)],
        capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and "not this comparison" in bad.stderr
