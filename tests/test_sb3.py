"""Stable-Baselines3 as an agent kind: training (`hier_agents.baselines.sb3`),
kept checkpoints at exact budgets, resuming, the ``sb3:PATH`` agent played by
the episode runner, and its observations equal to the gymnasium wrapper's."""

from __future__ import annotations

import json
import shutil

import gymnasium
import numpy as np
import pytest

import envs
from hier_agents.baselines.sb3 import Sb3Config, train
from physics_planning.cli import UsageError

ENV = "mujoban/level1"
#: Small, fast runs: 2 environments in this process, 2 s episodes (40 steps).
SMALL = {"n_envs": 2, "vec": "dummy", "env_options": {"time_limit": 2.0}, "no_progress": True}
HYPER = {
    "PPO": {"n_steps": 32, "batch_size": 32, "n_epochs": 1},
    "SAC": {"buffer_size": 1000, "learning_starts": 64, "batch_size": 32},
}


def _train(algo: str, logdir, frames: int = 256, save_at=(128, 256), **extra) -> dict:
    options = {
        **SMALL,
        "algo": algo,
        "hyperparameters": HYPER[algo],
        "frames": frames,
        "save_at": list(save_at),
        "logdir": str(logdir),
        **extra,
    }
    return train(Sb3Config.from_options(ENV, options))


@pytest.fixture(scope="module", params=["PPO", "SAC"])
def trained(request, tmp_path_factory):
    """(algo, run directory, counters) of a 256-frame run kept at 128 and 256."""
    logdir = tmp_path_factory.mktemp(request.param.lower())
    return request.param, logdir, _train(request.param, logdir)


def test_training_keeps_checkpoints_at_exact_budgets(trained):
    algo, logdir, counters = trained
    assert counters["frames"] == 256
    assert counters["wall_s"] > 0 and counters["cpu_s"] > 0
    for budget in (128, 256):
        assert (logdir / "checkpoints" / f"frames-{budget}.zip").is_file()
        sidecar = json.loads((logdir / "checkpoints" / f"frames-{budget}.json").read_text())
        assert sidecar["frames"] == budget
    assert (logdir / "model.zip").is_file()
    assert (logdir / "replay_buffer.pkl").is_file() == (algo == "SAC")
    config = json.loads((logdir / "config.json").read_text())
    assert config["algo"] == algo and config["privileged"] is True
    assert "full_entity_layer" in config["observations"]
    assert config["env_options"]["top_camera"] is None  # obs="state": no cameras
    rows = [json.loads(line) for line in (logdir / "scalars.jsonl").read_text().splitlines()]
    assert rows[-1]["frames"] == 256 and "episodes/success_rate" in rows[-1]


def test_the_episode_runner_plays_a_run_and_a_kept_checkpoint(trained):
    from hier_agents.run import run

    algo, logdir, _ = trained
    for path, frames in ((logdir, 256), (logdir / "checkpoints" / "frames-128.zip", 128)):
        summary = run(
            ENV,
            episodes=2,
            seed=0,
            agent=f"sb3:{path}",
            progress=False,
            env_options={"time_limit": 2.0},
        )
        assert summary["privileged"] is True
        assert summary["training_frames"] == frames
        assert len(summary["rows"]) == 2
        assert all("error" not in row for row in summary["rows"])


def test_the_agent_observes_what_the_gymnasium_env_gives(trained):
    from hier_agents.agents.sb3 import Sb3Agent, load_run

    _, logdir, _ = trained
    sb3_run = load_run(str(logdir))
    gym_env = gymnasium.make(ENV, obs="state", **envs.no_cameras(ENV))
    env = envs.load(ENV, **sb3_run.env_overrides())
    try:
        agent = Sb3Agent(sb3_run, env)
        for seed in (0, 7):
            expected, _ = gym_env.reset(seed=seed)
            env.seed(seed)
            got = agent.observation(env.reset())
            assert got.dtype == expected.dtype == np.float32
            np.testing.assert_array_equal(got, expected)
        action = agent.act(env.reset())
        assert action.shape == gym_env.action_space.shape
    finally:
        gym_env.close()
        env.close()


def test_resuming_extends_the_run(tmp_path):
    first = _train("PPO", tmp_path, frames=128, save_at=(128,))
    second = _train("PPO", tmp_path, frames=256, save_at=(128, 256))
    assert (first["frames"], second["frames"]) == (128, 256)
    assert second["cpu_s"] > first["cpu_s"] and second["wall_s"] > first["wall_s"]
    assert json.loads((tmp_path / "checkpoints" / "frames-256.json").read_text())["frames"] == 256
    again = _train("PPO", tmp_path, frames=256, save_at=(128, 256))  # nothing left to train
    assert again["frames"] == 256
    with pytest.raises(UsageError, match="algo"):
        _train("SAC", tmp_path, frames=256)  # another run's directory


def test_subprocess_environments_count_their_cpu(tmp_path):
    counters = _train("PPO", tmp_path, frames=64, save_at=(), vec="subproc")
    assert counters["frames"] == 64 and counters["cpu_s"] > 0


@pytest.mark.parametrize(
    "options, message",
    [
        ({"algo": "PPP"}, "unknown algo 'PPP' (did you mean 'PPO'?)"),
        (
            {"hyperparameters": {"n_step": 8}},
            "no hyperparameter 'n_step' (did you mean 'n_steps'?)",
        ),
        ({"obs": "sensors", "policy": "MlpPolicy"}, "use 'MultiInputPolicy'"),
        ({"frames": 10}, "less than one rollout"),
        ({"frames": 32768, "save_at": [100]}, "save_at 100: each must be a multiple"),
        ({"env_options": {"top_camra": (8, 8)}}, "did you mean 'top_camera'?"),
        ({"n_envs": "2"}, "n_envs must be an integer"),
        ({"lr": 0.1}, "unknown option 'lr'"),
    ],
)
def test_bad_options_are_one_line_usage_errors(options, message):
    with pytest.raises(UsageError) as info:
        Sb3Config.from_options(ENV, options)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_the_command_line(tmp_path, capsys):
    from hier_agents.baselines.sb3.cli import config_from_args, main

    config = config_from_args(
        [ENV, "--algo", "SAC", "--hyperparameters", "{train_freq = 4, batch_size = 16}"]
        + ["--env-option", "time_limit=2.0", "--save-at", "64", "--frames", "64"]
    )
    assert config.hyperparameters == {"train_freq": 4, "batch_size": 16}
    assert config.env_options["time_limit"] == 2.0 and config.save_at == (64,)
    with pytest.raises(SystemExit) as exit_info:
        main([ENV, "--hyperparameters", '{"n_step": 3}', "--logdir", str(tmp_path)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "n_steps" in err and len(err.splitlines()) == 1


def test_the_kind_is_listed_and_round_trips_job_inputs(trained, capsys):
    from hier_agents.agents import resolve
    from hier_agents.run_cli import print_components

    print_components()
    assert "sb3:PATH" in capsys.readouterr().out
    _, logdir, _ = trained
    kind, arg = resolve(f"sb3:{logdir}")
    inputs = kind.job_inputs(ENV, arg, {"stochastic": True})
    assert inputs["kind"] == "sb3" and len(inputs["model_sha256"]) == 64
    assert kind.from_job_inputs(json.loads(json.dumps(inputs))) == (
        str(logdir),
        {"stochastic": True},
    )
    with pytest.raises(UsageError, match="no SB3 model"):
        resolve(f"sb3:{logdir}/missing.zip")[0].check(ENV, f"{logdir}/missing.zip", {})
    with pytest.raises(UsageError, match="cannot play"):
        kind.check("mujoxo/mixture", arg, {})


def test_a_copied_run_without_config_is_refused(trained, tmp_path):
    from hier_agents.agents.sb3 import load_run

    _, logdir, _ = trained
    shutil.copy(logdir / "model.zip", tmp_path / "lonely.zip")
    with pytest.raises(UsageError, match="not a model of"):
        load_run(str(tmp_path / "lonely.zip"))
