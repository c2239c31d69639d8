"""``python -m hier_agents.compare SPEC --check EPISODES``: stored evaluations
replayed and compared with their records (`hier_agents.compare.check`).

The replays here are stand-in job processes (their rows chosen by the
test); `test_compare.test_a_shipped_checkpoint_replays_its_committed_rows`
replays real shipped checkpoints.
"""

from __future__ import annotations

import json

import pytest

from hier_agents.compare import check
from hier_agents.compare import jobs as jobs_mod
from hier_agents.compare.__main__ import main
from hier_agents.compare.spec import load
from test_compare import _fake_records, e2e_spec


def test_differences_compare_the_stored_fields_but_timing():
    stored = [
        {"episode": 0, "solved": True, "steps": 30, "return": 11.0, "wall_s": 1.0},
        {"episode": 1, "solved": False, "steps": 900, "return": 0.1, "wall_s": 2.0},
    ]
    same = [
        {**stored[0], "wall_s": 5.0, "newer_field": 3},
        {**stored[1], "return": 0.1 * (1 + 1e-12)},
    ]
    assert check.differences(stored, same) == []
    assert check.differences(stored, same[:1]) == []
    flipped = [same[0], {**same[1], "solved": True}]
    assert check.differences(stored, flipped) == ["episode 1: solved False stored, True replayed"]
    lacking = [{k: v for k, v in same[0].items() if k != "steps"}]
    assert check.differences(stored, lacking) == ["episode 0: steps 30 stored, '(absent)' replayed"]
    assert check.differences(stored[:1], same) == ["2 rows replayed, 1 stored"]


def _replays(planned, changed: set, ran: list):
    """A stand-in `job_process` for check jobs: stores the rows
    `_fake_records` gives, with ``solved`` flipped for the seeds in
    ``changed``."""

    def fake(job, cache, log):
        ran.append(job)
        _fake_records(cache, planned, [job])
        if job.inputs["seed"] in changed:
            record = jobs_mod.load_record(cache, job.key)
            for row in record["result"]["rows"]:
                row["solved"] = not row["solved"]
            jobs_mod.store_record(cache, record)
        return 0, 0.0

    return fake


def _stored(tmp_path):
    """A spec whose modular and random agents' evaluations are stored (the
    e2e series is not trained: its points cannot be replayed)."""
    path = e2e_spec(tmp_path)
    spec = load(path)
    planned = jobs_mod.plan(spec)
    stored = [j for j in planned if j.kind == "eval" and j.point["agent"] != "e2e"]
    _fake_records(spec.cache, planned, stored)
    return path, spec, planned


def test_check_replays_each_points_first_episodes_and_passes_when_they_agree(
    tmp_path, monkeypatch, capsys
):
    path, spec, planned = _stored(tmp_path)
    ran: list = []
    monkeypatch.setattr("hier_agents.compare.backends.job_process", _replays(planned, set(), ran))
    records_before = sorted(p.name for p in (spec.cache / "jobs").iterdir())
    assert main([str(path), "--quiet", "--cpus", "1", "--check", "1"]) == 0
    # one replay per point (the first shard), of its first episode only
    firsts = [j for j in planned if j.kind == "eval" and j.inputs["first_episode"] == 0]
    points = {(j.point["agent"], j.inputs["seed"]) for j in firsts if j.point["agent"] != "e2e"}
    assert {(j.point["agent"], j.inputs["seed"]) for j in ran} == points
    assert len(ran) == len(points)
    assert all(j.inputs["episodes"] == 1 and j.inputs["first_episode"] == 0 for j in ran)
    # the cache's records are untouched; the replays are in CACHE/checks
    assert sorted(p.name for p in (spec.cache / "jobs").iterdir()) == records_before
    assert (spec.cache / "checks" / "train").is_symlink()
    verdict = json.loads((spec.cache / "check.json").read_text())
    assert len(verdict["points"]) == len(points)
    assert all(p["differences"] == [] for p in verdict["points"])
    assert {(n["point"]["agent"], n["why"]) for n in verdict["not_replayed"]} == {
        ("e2e", "no stored record")
    }
    captured = capsys.readouterr()
    assert "none differs from a record of this CPU kind" in captured.err
    assert "not replayed: e2e at 200 frames on mujoban/level1, seed 0" in captured.err


def test_check_fails_on_a_difference_and_names_it(tmp_path, monkeypatch, capsys):
    path, spec, planned = _stored(tmp_path)
    monkeypatch.setattr("hier_agents.compare.backends.job_process", _replays(planned, {1}, []))
    assert main([str(path), "--quiet", "--cpus", "1", "--check", "2"]) == 1
    verdict = json.loads((spec.cache / "check.json").read_text())
    differing = [p for p in verdict["points"] if p["differences"]]
    assert {p["point"]["seed"] for p in differing} == {1}
    assert differing[0]["differences"] == [
        "episode 0: solved True stored, False replayed",
        "episode 1: solved False stored, True replayed",
    ]
    out = capsys.readouterr().out
    assert "modular on mujoban/level1, seed 1: episode 0: solved True stored" in out


def test_a_difference_from_a_record_of_another_cpu_is_reported_not_failed(tmp_path, monkeypatch):
    path, spec, planned = _stored(tmp_path)
    for job in planned:
        record = jobs_mod.load_record(spec.cache, job.key)
        if record is not None:
            record["provenance"] = {"machine": {"cpu": "Some Other CPU"}}
            jobs_mod.store_record(spec.cache, record)
    monkeypatch.setattr("hier_agents.compare.backends.job_process", _replays(planned, {1}, []))
    assert main([str(path), "--quiet", "--cpus", "1", "--check", "1"]) == 0
    verdict = json.loads((spec.cache / "check.json").read_text())
    assert all(p["other_cpu"] for p in verdict["points"])
    assert "differ, other CPU" in check.summary_table(verdict["points"])


@pytest.mark.parametrize("flag", ["--reevaluate", "--retrain", "--report-only"])
def test_check_refuses_flags_that_run_or_skip_jobs(tmp_path, flag, capsys):
    path, _, _ = _stored(tmp_path)
    with pytest.raises(SystemExit) as stop:
        main([str(path), "--check", "1", flag])
    assert stop.value.code == 2
    assert f"--check replays stored evaluations: drop {flag}" in capsys.readouterr().err
