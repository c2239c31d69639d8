"""Stable-Baselines3 as an agent kind: training (`hier_agents.baselines.sb3`),
kept checkpoints at exact budgets, resuming, the ``sb3:PATH`` agent played by
the episode runner, and its observations equal to the gymnasium wrapper's."""

from __future__ import annotations

import json
import tempfile
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


# SAC (the slower to train) with the slow tests.
@pytest.fixture(scope="module", params=["PPO", pytest.param("SAC", marks=pytest.mark.slow)])
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


def test_resuming_extends_the_run(tmp_path, monkeypatch):
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    first = _train("PPO", tmp_path, frames=128, save_at=(128,))
    second = _train("PPO", tmp_path, frames=256, save_at=(128, 256))
    assert not list(scratch.glob("SB3-*"))  # the logs are the run's: no SB3-<date> folders
    assert (first["frames"], second["frames"]) == (128, 256)
    assert second["cpu_s"] > first["cpu_s"] and second["wall_s"] > first["wall_s"]
    assert json.loads((tmp_path / "checkpoints" / "frames-256.json").read_text())["frames"] == 256
    again = _train("PPO", tmp_path, frames=256, save_at=(128, 256))  # nothing left to train
    assert again["frames"] == 256
    with pytest.raises(UsageError, match="algo"):
        _train("SAC", tmp_path, frames=256)  # another run's directory


@pytest.mark.slow
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


class _Counting(gymnasium.Env):
    """Reward 1 per step; the episode ends after ``length`` steps."""

    observation_space = gymnasium.spaces.Box(-1, 1, (1,), np.float32)
    action_space = gymnasium.spaces.Box(-1, 1, (1,), np.float32)

    def __init__(self, length: int):
        self.length, self.steps, self.actions = length, 0, []

    def reset(self, *, seed=None, options=None):
        self.steps = 0
        return np.zeros(1, np.float32), {}

    def step(self, action):
        self.steps += 1
        self.actions.append(float(action[0]))
        done = self.steps >= self.length
        return np.zeros(1, np.float32), 1.0, done, False, {"steps": self.steps}


def test_action_repeat_holds_until_the_episode_ends():
    from envs.gymnasium_env import ActionRepeat

    inner = _Counting(length=10)
    env = ActionRepeat(inner, 4)
    env.reset()
    results = [env.step(np.array([i / 10], np.float32)) for i in range(3)]
    assert [r[1] for r in results] == [4.0, 4.0, 2.0]  # rewards summed, last hold cut
    assert [r[4]["held"] for r in results] == [4, 4, 2]
    assert [r[2] for r in results] == [False, False, True]
    assert inner.actions == pytest.approx([0.0] * 4 + [0.1] * 4 + [0.2] * 2)
    for repeat in (0, 1.5, True):
        with pytest.raises(ValueError, match="repeat must be an integer >= 1"):
            ActionRepeat(_Counting(1), repeat)


def test_action_repeat_counts_control_steps_and_the_agent_holds(tmp_path):
    """With action_repeat 4, SB3's num_timesteps counts decisions and frames
    are 4 times them; budgets are multiples of a rollout of 32 x 2 x 4 frames;
    the sb3: agent decides every 4 control steps, as in training."""
    from hier_agents.agents.sb3 import Sb3Agent, load_run

    with pytest.raises(UsageError, match=r"multiple of one rollout \(256 frames\)"):
        Sb3Config.from_options(
            ENV,
            {
                **SMALL,
                "hyperparameters": HYPER["PPO"],
                "action_repeat": 4,
                "frames": 512,
                "save_at": [128],
            },
        )
    counters = _train("PPO", tmp_path, frames=512, save_at=(256,), action_repeat=4)
    assert counters["frames"] == 512
    kept = load_run(str(tmp_path / "checkpoints" / "frames-256.zip"))
    assert kept.counters["frames"] == 256 and kept.config["action_repeat"] == 4
    env = envs.load(ENV, **kept.env_overrides())
    try:
        agent = Sb3Agent(kept, env)
        assert agent.training_frames == 256  # 64 decisions x 4
        calls = []
        predict = agent.model.predict
        agent.model.predict = lambda *a, **k: calls.append(1) or predict(*a, **k)
        timestep = env.reset()
        agent.reset(None, timestep, seed=0)
        actions = []
        for _ in range(9):
            actions.append(agent.act(timestep))
            timestep = env.step(actions[-1])
        assert len(calls) == 3  # steps 0, 4 and 8
        assert all(a is actions[0] for a in actions[:4]) and actions[4] is not actions[0]
        agent.reset(None, env.reset(), seed=0)
        agent.act(timestep)
        assert len(calls) == 4  # a new episode decides at once
    finally:
        env.close()
    with pytest.raises(UsageError, match="action_repeat=4, not 1"):
        _train("PPO", tmp_path, frames=1024, save_at=())


def test_a_spec_sees_the_main_camera_and_proprioception_as_the_cpu_preset():
    # TOML has no null: false switches the egocentric camera off, so the
    # sensors are the top camera and proprioception (IMPALA's main-camera).
    import tomllib

    from hier_agents.baselines.sb3.trainer import make_env

    table = tomllib.loads(
        'sb3 = { obs = "sensors", '
        "env_options = { egocentric_camera = false, top_camera = [48, 48] } }"
    )["sb3"]
    config = Sb3Config.from_options(ENV, {**SMALL, **table})
    assert config.policy == "MultiInputPolicy"
    env = make_env(config.env, config.obs, config.env_options)
    try:
        spaces = env.observation_space.spaces
    finally:
        env.close()
    assert spaces["top_camera"].shape == (48, 48, 3) and "egocentric_camera" not in spaces
    assert {key for key in spaces if key.startswith("walker/")}
