"""Agents as named parts (`hier_agents.agents`): an outside agent kind,
registered without touching `run`, `players` or `compare`, plays
``hier_agents.run`` and a comparison spec; the registry's errors."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from child_env import child_env
from hier_agents.agents import KINDS, register, resolve
from physics_planning.cli import UsageError

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: An agent kind as an outside package would write it: actions of zero
#: scaled by ARG (the walker holds still), cameras off, nothing privileged.
KIND_MODULE = textwrap.dedent("""
    import numpy as np

    import envs
    from hier_agents.agents import AgentKind, AgentSetup
    from hier_agents.modular.agent import OptionStats
    from physics_planning.cli import UsageError


    class HoldStill:
        privileged = False
        training_frames = 0
        estimates = False
        scene = None
        gave_up = None

        def __init__(self, action_spec, scale):
            self.action = np.zeros(action_spec.shape) * scale
            self.episode_stats = OptionStats()
            self.resets = 0

        def reset(self, description, timestep, seed=None):
            self.resets += 1

        def act(self, timestep):
            return self.action

        def end_episode(self, timestep):
            pass

        def close(self):
            pass


    class HoldStillKind(AgentKind):
        name = "hold-still"
        help = "an outside kind: zero actions"
        metavar = "SCALE"

        def parse(self, text):
            try:
                return float(text)
            except ValueError:
                raise UsageError(f"hold-still:SCALE takes a number, got {text!r}") from None

        def default(self):
            return 1.0

        def setup(self, env_name, arg, options):
            def build(view, seed, simulator):
                return HoldStill(view.action_spec(), arg)
            return AgentSetup(dict(envs.no_cameras(env_name)), "observations",
                              {"condition": f"holds still (scale {arg})"}, build)

        def describe(self, summary):
            return summary.get("condition", summary["agent"])


    KIND = HoldStillKind()
""")


def _write_package(folder):
    """The kind's module and a distribution declaring it as an entry point."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "hold_still_kind.py").write_text(KIND_MODULE)
    info = folder / "hold_still_kind-0.0.dist-info"
    info.mkdir(exist_ok=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: hold-still-kind\nVersion: 0.0\n")
    (info / "entry_points.txt").write_text(
        "[physics_planning.agents]\nhold-still = hold_still_kind:KIND\n"
    )
    return folder


@pytest.fixture
def hold_still(tmp_path):
    """The outside kind registered in this process (removed afterwards)."""
    path = _write_package(tmp_path / "site") / "hold_still_kind.py"
    spec = importlib.util.spec_from_file_location("hold_still_kind", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    resolve("modular")  # the shipped kinds first
    register(module.KIND)
    yield module.KIND
    KINDS.pop("hold-still", None)


def test_an_outside_kind_plays_hier_agents_run_and_is_listed(hold_still, tmp_path, capsys):
    from hier_agents import run as run_lib

    out = tmp_path / "run.json"
    assert (
        run_lib.main(
            [
                "mujoban/level1",
                "--agent",
                "hold-still:0.5",
                "--episodes",
                "2",
                "--env-option",
                "time_limit=1",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    summary = json.loads(out.read_text())
    assert summary["agent"] == "hold-still:0.5" and summary["episodes"] == 2
    assert summary["condition"] == "holds still (scale 0.5)"
    assert [row["solved"] for row in summary["rows"]] == [False, False]
    assert {row["failure_reason"] for row in summary["rows"]} == {"time limit"}
    assert "holds still (scale 0.5)" in capsys.readouterr().out
    assert run_lib.main(["--list"]) == 0
    assert "hold-still | hold-still:SCALE" in capsys.readouterr().out


def test_an_outside_kinds_bad_argument_and_options_are_refused_in_one_line(hold_still):
    from hier_agents.run import run

    with pytest.raises(UsageError, match="takes a number"):
        resolve("hold-still:fast")
    with pytest.raises(ValueError, match="takes no option planner"):
        run("mujoban/level1", 1, agent="hold-still", planner="random", progress=False)


def test_a_kind_without_environment_flags_refuses_them_in_one_line(hold_still, monkeypatch, capsys):
    from hier_agents import run as run_lib

    monkeypatch.setattr(hold_still, "env_flags", False)
    with pytest.raises(ValueError, match="--env-option do not apply to --agent hold-still"):
        run_lib.run(
            "mujoban/level1", 1, agent="hold-still", env_options={"sleep": False}, progress=False
        )
    levels = Path(__file__).parents[1] / "envs/mujoban/data/boxoban/medium-valid-000.txt"
    with pytest.raises(SystemExit) as ended:
        run_lib.main(["mujoban/level1", "--agent", "hold-still", "--levels", str(levels)])
    assert ended.value.code == 2
    assert "--levels does not apply to --agent hold-still" in capsys.readouterr().err


@pytest.mark.slow
def test_an_outside_kind_declared_as_an_entry_point_plays_a_comparison_spec(tmp_path):
    site = _write_package(tmp_path / "site")
    spec = tmp_path / "spec.toml"
    spec.write_text(
        textwrap.dedent("""
        name = "outside"
        cache = "cache"
        envs = ["mujoban/level1"]
        seeds = [0]
        episodes = 2

        [[agent]]
        label = "holds still"
        agent = "hold-still:0.5"
    """)
    )
    env = child_env()
    env["PYTHONPATH"] = os.pathsep.join([str(site), ROOT])
    done = subprocess.run(
        [sys.executable, "-m", "hier_agents.compare", str(spec), "--cpus", "1"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    comparison = json.loads((tmp_path / "cache" / "comparison.json").read_text())
    (point,) = comparison["points"]
    assert point["agent"] == "holds still" and point["env"] == "mujoban/level1"
    records = [json.loads(p.read_text()) for p in (tmp_path / "cache" / "jobs").glob("*.json")]
    (record,) = records
    assert record["inputs"]["agent"] == {"kind": "hold-still", "arg": "hold-still:0.5"}
    assert [row["solved"] for row in record["result"]["rows"]] == [False, False]


def test_the_registry_names_the_closest_kind_and_refuses_a_taken_name():
    with pytest.raises(UsageError, match="did you mean 'random'"):
        resolve("randon:3")
    with pytest.raises(UsageError, match="needs an argument: checkpoint:PATH"):
        resolve("checkpoint")
    with pytest.raises(ValueError, match="taken"):
        register(KINDS["random"])
    kind, hold = resolve("random:7")
    assert (kind.name, hold, kind.form(hold)) == ("random", 7, "random:7")


def test_every_kind_keeps_its_job_inputs_so_cached_comparisons_stay_valid():
    """The comparison's job keys hash these dicts: the shipped kinds keep the
    form the committed job records were made with."""
    modular, _ = resolve("modular")
    random_kind, hold = resolve("random:10")
    assert random_kind.job_inputs("mujoban/level1", hold, {}) == {"kind": "random", "hold": 10}
    assert modular.job_inputs("mujoban/level1", None, {"estimator": "oracle"}) == {
        "kind": "modular",
        "estimator": "oracle",
        "learned_files": {},
    }
    assert random_kind.from_job_inputs({"kind": "random", "hold": 10}) == (10, {})
