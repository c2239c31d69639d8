"""The estimator-accuracy benchmark runs end to end on a few frames."""

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _benchmark():
    path = ROOT / "benchmarks" / "estimator_accuracy.py"
    sys.path.insert(0, str(path.parent))  # for its `_common` import
    spec = importlib.util.spec_from_file_location("estimator_accuracy", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_estimator_accuracy_writes_its_json(tmp_path):
    module = _benchmark()
    out = tmp_path / "accuracy.json"
    frames = len(module.SOURCES)  # one frame per level source
    assert (
        module.main(
            ["--frames", str(frames), "--seed", "3", "--render-steps", "5", "--json", str(out)]
        )
        == 0
    )
    result = json.loads(out.read_text())
    assert {
        "provenance",
        "frame_shape",
        "frames",
        "seed",
        "sources",
        "render_ms_per_step",
        "rows",
        "per_source",
    } <= set(result)
    assert {"command", "commit", "date", "machine"} <= set(result["provenance"])
    assert result["frame_shape"] == list(module.FRAME_SHAPE)
    rows = {row["estimator"]: row for row in result["rows"]}
    assert set(rows) == {"camera", "camera/every", "oracle"}
    assert rows["camera"]["privileged"] is False and rows["oracle"]["privileged"] is True
    keys = {
        "frames",
        "whole_grid_accuracy",
        "walls_accuracy",
        "targets_accuracy",
        "boxes_accuracy",
        "player_accuracy",
        "failures",
        "walker_error_median_cells",
        "walker_error_p95_cells",
        "box_error_median_cells",
        "box_error_p95_cells",
        "ms_per_estimate",
        "ms_per_reset",
    }
    for row in rows.values():
        assert keys <= set(row)
        assert row["frames"] == frames
        assert 0.0 <= row["whole_grid_accuracy"] <= 1.0
    # The oracle is the sanity row: always right.
    assert rows["oracle"]["whole_grid_accuracy"] == 1.0
    assert rows["oracle"]["failures"] == 0
    assert set(result["per_source"]) == set(result["sources"])
    assert set(result["render_ms_per_step"]) == {
        "none",
        "96x96",
        "x".join(map(str, module.FRAME_SHAPE)) + " (the estimator's)",
    }
    for row in rows.values():
        assert 0 <= row["teleport_frames"] <= row["frames"]
        assert 0.0 <= row["whole_grid_accuracy_without_teleports"] <= 1.0
