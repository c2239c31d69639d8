"""`envs.profile` (exclusive time per section) and ``hier_agents.run --profile``."""

from __future__ import annotations

import pytest

from envs import profile as profile_mod
from envs.profile import SECTIONS, Profile


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_nested_sections_count_their_time_once(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(profile_mod.time, "perf_counter", clock)
    p = Profile()
    with p.section("estimator"):
        clock.now += 1.0
    assert p.totals == {}  # off: nothing is counted
    p.enabled = True
    with p.section("estimator"):
        clock.now += 1.0
        with p.section("render"):  # a lazy frame rendered while the estimator reads it
            clock.now += 3.0
            with p.section("render"):
                clock.now += 0.5
        clock.now += 0.25
    with pytest.raises(RuntimeError), p.section("physics"):
        clock.now += 2.0
        raise RuntimeError("a section closed by an error still counts")
    assert p.take() == {"estimator": 1.25, "render": 3.5, "physics": 2.0}
    assert p.take() == {}


def test_run_profile_rows_and_summary_add_up_to_the_wall_time():
    from hier_agents.run import format_table, run

    summary = run("mujoban/level1", 2, 0, progress=False, profile=True)
    prof = summary["profile"]
    assert set(prof["seconds"]) == set(SECTIONS) | {"other"}
    assert sum(prof["seconds"].values()) == pytest.approx(prof["wall_s"], rel=1e-6)
    assert prof["wall_s"] == pytest.approx(sum(r["wall_s"] for r in summary["rows"]))
    assert sum(prof["shares"].values()) == pytest.approx(1.0)
    # The named sections account for nearly all of an episode: physics, the
    # camera estimator's frames and estimates, the planner and the skill all ran.
    assert prof["shares"]["other"] < 0.25
    for name in ("physics", "render", "estimator", "planner", "skill"):
        assert prof["seconds"][name] > 0, name
    for row in summary["rows"]:
        assert sum(row["profile_s"].values()) <= row["wall_s"] + 1e-6
    assert "time spent in     physics" in format_table(summary)
    plain = run("mujoban/level1", 1, 0, progress=False)
    assert "profile" not in plain and "profile_s" not in plain["rows"][0]
    assert not profile_mod.PROFILE.enabled
