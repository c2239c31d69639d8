"""Plan time features, the step model, and the execution-time benchmark."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from abstract_planners.sokoban import SokobanState
from abstract_planners.sokoban_time import FEATURES, estimate_steps, fit_weights, plan_features

ROOT = Path(__file__).resolve().parents[1]
ROOM = SokobanState.from_text("########\n#      #\n# @$  .#\n#      #\n########")


def test_a_straight_push_is_one_stroke_and_a_detour_counts_its_turns():
    assert plan_features(ROOM, "RRR") == {"walk": 0, "push": 3, "stroke": 1, "turn": 0}
    # Walk round the box (down, right, right, up) then push it back left once.
    assert plan_features(ROOM, "DRRUL") == {"walk": 4, "push": 1, "stroke": 1, "turn": 3}
    # Two strokes: push right, step back round... here: push, then push again
    # after a walk away and back (a new stroke of the same box and direction).
    assert plan_features(ROOM, "RLRR")["stroke"] == 2
    with pytest.raises(ValueError, match="illegal"):
        plan_features(ROOM, "UU")


def test_the_step_model_is_linear_and_the_fit_recovers_known_weights():
    weights = {"start": 20.0, "walk": 4.0, "push": 9.0, "stroke": 12.0, "turn": 1.5}
    rng = np.random.default_rng(0)
    features = [
        dict(zip(FEATURES, map(int, rng.integers(1, 60, size=len(FEATURES))))) for _ in range(40)
    ]
    steps = [estimate_steps(f, weights) for f in features]
    fitted = fit_weights(features, steps)
    for key, value in weights.items():
        assert fitted[key] == pytest.approx(value, abs=1e-6)
    with pytest.raises(ValueError, match="at least"):
        fit_weights(features[:3], steps[:3])


@pytest.mark.slow
def test_the_benchmark_writes_a_row_per_level_with_its_keys(tmp_path):
    path = ROOT / "benchmarks" / "execution_time.py"
    sys.path.insert(0, str(path.parent))
    spec = importlib.util.spec_from_file_location("execution_time", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = tmp_path / "et.json"
    levels = ROOT / "envs" / "mujoban" / "data" / "boxoban" / "unfiltered-valid-000.txt"
    assert (
        module.main(
            [
                "--levels",
                str(levels),
                "--episodes",
                "2",
                "--estimator",
                "oracle",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    result = json.loads(out.read_text())
    assert result["summary"]["privileged"] is True and result["summary"]["levels"] == 2
    assert len(result["rows"]) == 2
    for row in result["rows"]:
        assert {
            "pushes",
            "moves",
            "features",
            "estimated_steps",
            "steps",
            "steps_per_push",
            "limit_share",
            "solved",
        } <= set(row)
        assert row["limit_share"] == pytest.approx(row["steps"] / 900, abs=1e-4)


def test_the_results_table_names_any_planner_but_mujobans_default():
    from hier_agents.modular.components import PLANNERS

    spec = importlib.util.spec_from_file_location(
        "agent_table", ROOT / "benchmarks" / "agent_table.py"
    )
    table = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(table)
    assert table.DEFAULT_MUJOBAN_PLANNER == next(iter(PLANNERS["mujoban"]))
