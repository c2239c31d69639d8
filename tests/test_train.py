"""The actor-learner loop: updates, checkpoints and resumption, Ray actors, CLI, evaluation."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
import torch

from hier_agents import run as run_lib
from hier_agents import train as train_cli
from hier_agents.baselines.impala.checkpoints import load_checkpoint, net_from_checkpoint
from hier_agents.baselines.impala.learner import TrainConfig, train

TINY = dict(
    env="mujoban/level1",
    unroll_length=5,
    batch_size=2,
    actors=1,
    envs_per_actor=2,
    cameras=False,
    checkpoint_every_s=1e9,
    log_every_s=0.0,
    progress=False,
)


def test_a_tiny_run_updates_logs_and_checkpoints(tmp_path):
    own = time.process_time()
    counters = train(
        TrainConfig(condition="expert-planner", steps=30, logdir=str(tmp_path), **TINY)
    )
    own = time.process_time() - own
    # 30 frames at 2 unrolls x 5 steps per update: 3 updates.
    assert counters["updates"] == 3 and counters["frames"] == 30
    # CPU seconds count the actor processes too, not only this (learner) process.
    assert counters["cpu_s"] > own
    ckpt = load_checkpoint(tmp_path)
    assert ckpt["counters"]["frames"] == 30 and ckpt["config"]["condition"] == "expert-planner"
    net, spec = net_from_checkpoint(ckpt)
    assert spec.planner_shape is not None
    for name, tensor in net.state_dict().items():
        assert torch.equal(tensor, ckpt["model"][name]), name
    lines = [json.loads(line) for line in open(tmp_path / "scalars.jsonl")]
    assert [line["frames"] for line in lines] == [line["step"] for line in lines] == [10, 20, 30]
    assert all(np.isfinite(line["loss/loss"]) for line in lines)
    assert list(tmp_path.glob("events.out.tfevents.*")), "no TensorBoard event file"
    config = json.loads((tmp_path / "config.json").read_text())
    assert config["condition"] == "expert-planner" and config["steps"] == 30
    assert ckpt["config"] == config and set(ckpt["rng"]) == {"torch", "numpy", "python"}
    assert not list(tmp_path.glob("*.tmp")), "a temporary checkpoint was left behind"


def test_ppos_ingredients_train_and_the_optimizer_is_part_of_the_run(tmp_path):
    ppo = dict(optimizer="adam", clip_ratio=0.2, normalize_advantages=True, passes=2)
    counters = train(
        TrainConfig(condition="vanilla", steps=20, logdir=str(tmp_path), **ppo, **TINY)
    )
    assert counters["updates"] == 2
    assert np.isfinite(counters["last_stats"]["loss"])
    assert 0 <= counters["last_stats"]["ratio_clipped_fraction"] <= 1
    ckpt = load_checkpoint(tmp_path)
    assert all("exp_avg" in s for s in ckpt["optimizer"]["state"].values())  # Adam's moments
    # The optimiser's state cannot continue as another optimiser's.
    with pytest.raises(ValueError, match="optimizer='adam'"):
        train(TrainConfig(condition="vanilla", steps=40, logdir=str(tmp_path), **TINY))


@pytest.mark.slow
def test_passes_take_that_many_gradient_steps_on_each_batch(tmp_path, monkeypatch):
    from hier_agents.baselines.impala import learner

    steps = []
    real = learner.learner_step

    def counting(net, optimizer, batch, config, value_states=None):
        steps.append(value_states is not None)
        return real(net, optimizer, batch, config, value_states)

    monkeypatch.setattr(learner, "learner_step", counting)
    counters = train(TrainConfig(steps=20, passes=3, logdir=str(tmp_path), **TINY))
    # 20 frames at 2 unrolls x 5 steps per update: 2 updates of 3 steps each,
    # the value core's carried states taken from each update's last step.
    assert counters["updates"] == 2
    assert steps == [False, False, True] * 2


@pytest.mark.slow
def test_a_resumed_run_continues_from_its_step_count(tmp_path):
    train(TrainConfig(condition="vanilla", steps=20, logdir=str(tmp_path), **TINY))
    first = load_checkpoint(tmp_path)
    assert first["counters"]["frames"] == 20 and first["counters"]["updates"] == 2
    counters = train(TrainConfig(condition="vanilla", steps=40, logdir=str(tmp_path), **TINY))
    assert counters["frames"] == 40 and counters["updates"] == 4
    frames = [json.loads(line)["frames"] for line in open(tmp_path / "scalars.jsonl")]
    assert frames == [10, 20, 30, 40]
    assert json.loads((tmp_path / "config.json").read_text())["steps"] == 40
    # CPU seconds add up over the resumed parts.
    assert counters["cpu_s"] > first["counters"]["cpu_s"] > 0
    # The resumed weights are the saved ones, trained further.
    second = load_checkpoint(tmp_path)
    assert any(not torch.equal(first["model"][k], second["model"][k]) for k in first["model"])
    # A finished run is not run again; another condition in the same logdir is refused.
    assert (
        train(TrainConfig(condition="vanilla", steps=40, logdir=str(tmp_path), **TINY))["updates"]
        == 4
    )
    with pytest.raises(ValueError, match="condition"):
        train(TrainConfig(condition="expert-planner", steps=60, logdir=str(tmp_path), **TINY))


@pytest.mark.slow
def test_ray_actors_feed_the_learner(tmp_path):
    import ray  # a hard dependency: imported, never skipped

    try:
        counters = train(
            TrainConfig(
                condition="random-planner",
                steps=40,
                backend="ray",
                logdir=str(tmp_path),
                **dict(TINY, actors=2),
            )
        )
    finally:
        ray.shutdown()
    assert counters["updates"] == 4 and counters["frames"] == 40


@pytest.mark.slow
def test_the_checkpoint_plays_through_hier_agents_run(tmp_path, capsys):
    train(TrainConfig(condition="expert-planner", steps=10, logdir=str(tmp_path / "run"), **TINY))
    out = tmp_path / "eval.json"
    assert (
        run_lib.main(
            [
                "mujoban/level1",
                "--agent",
                f"checkpoint:{tmp_path / 'run'}",
                "--episodes",
                "1",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    summary = json.loads(out.read_text())
    for key in (
        "env",
        "episodes",
        "success_rate",
        "mean_return",
        "mean_steps",
        "subgoal_success_rate",
        "wall_s",
    ):
        assert key in summary, key
    assert summary["training_frames"] == 10 and summary["condition"] == "expert-planner"
    assert "checkpoint:" in capsys.readouterr().out


@pytest.mark.slow
def test_a_state_input_run_trains_resumes_only_as_state_and_plays(tmp_path):
    logdir = tmp_path / "run"
    config = dict(condition="vanilla", logdir=str(logdir), state=True, state_channels=8, **TINY)
    train(TrainConfig(steps=10, **config))
    ckpt = load_checkpoint(logdir / "checkpoint.pt")
    assert ckpt["config"]["state"] is True
    assert tuple(ckpt["input_spec"]["state_shape"]) == (4, 10, 10)
    net, spec = net_from_checkpoint(ckpt)
    assert spec.state_shape == (4, 10, 10) and net.state_encoder.conv.out_channels == 8
    with pytest.raises(ValueError, match="state"):
        train(TrainConfig(steps=20, **{**config, "state": False}))
    with pytest.raises(ValueError, match="state_channels"):
        train(TrainConfig(steps=20, **{**config, "state_channels": 100}))
    out = tmp_path / "eval.json"
    assert (
        run_lib.main(
            [
                "mujoban/level1",
                "--agent",
                f"checkpoint:{logdir}",
                "--episodes",
                "1",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    assert json.loads(out.read_text())["training_frames"] == 10


@pytest.mark.parametrize(
    "argv, message",
    [
        (["mujoban/level1", "--condition", "cheater"], "vanilla"),
        (["mujoban/nope"], "mujoban/level1"),
        (["mujoban/level1", "--backend", "mpi"], "ray"),
        (["mujoban/level1", "--frames", "0"], "--frames"),
        (["mujoban/level1", "--passes", "0"], "--passes"),
        (["mujoban/level1", "--state-channels", "0"], "--state-channels"),
        (["mujoban/level1", "--optimizer", "sgd"], "adam"),
        (["mujoban/level1", "--clip-ratio", "1"], "clip_ratio must be < 1"),
        (["mujoban/level1", "--clip-ratio", "-0.2"], "--clip-ratio"),
    ],
)
def test_train_cli_rejects_bad_arguments(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        train_cli.main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err


def test_run_cli_rejects_a_missing_checkpoint_and_modular_flags(tmp_path, capsys):
    with pytest.raises(SystemExit):
        run_lib.main(["mujoban/level1", "--agent", f"checkpoint:{tmp_path / 'none'}"])
    assert "no checkpoint" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        run_lib.main(["mujoban/level1", "--agent", "checkpoint:x", "--planner", "random"])
    err = capsys.readouterr().err  # one line, about either of the two mistakes
    assert err.count("\n") == 1 and ("--planner" in err or "no checkpoint" in err), err


def _toy_unrolls(net, rng, T=8, B=16):
    """A contextual bandit through the real actor/learner code paths: the
    proprio input is a target point x in [-0.8, 0.8]^2, the reward for action
    a is 1 - |clip(a) - x|^2 / 2 (best: a = x), each step is its own episode."""
    x = rng.uniform(-0.8, 0.8, size=(T + 1, B, 2)).astype(np.float32)
    state = net.initial_state(B)
    first = np.ones((T + 1, B), dtype=bool)
    actions = np.empty((T, B, 2), np.float32)
    log_probs = np.empty((T, B), np.float32)
    for t in range(T):
        a, lp, state = net.act({"proprio": x[t]}, first[t], state, policy_only=True)
        actions[t], log_probs[t] = a, lp
    rewards = 1.0 - 0.5 * np.square(np.clip(actions, -1, 1) - x[:T]).sum(-1)
    zeros = np.zeros((T, B), np.float32)
    unrolls = []
    for i in range(B):
        unrolls.append(
            {
                "obs": {"proprio": x[:, i]},
                "first": first[:, i],
                "actions": actions[:, i],
                "log_probs": log_probs[:, i],
                "rewards_env": rewards[:, i].astype(np.float32),
                "discounts_env": zeros[:, i],
                "rewards_abs": zeros[:, i],
                "discounts_abs": zeros[:, i],
                "state": [s[i].numpy().copy() for s in net.initial_state(B)],
                "stream": (0, i),
            }
        )
    return unrolls, float(rewards.mean())


def test_the_learner_improves_the_return_of_a_tiny_task():
    from hier_agents.baselines.impala.agent_env import InputSpec
    from hier_agents.baselines.impala.learner import learner_step, make_batch
    from hier_agents.baselines.impala.network import ImpalaNet

    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    spec = InputSpec(
        images=(), proprio_dim=2, planner_shape=None, planner_action_dim=0, action_dim=2
    )
    net = ImpalaNet(spec, two_values=False)
    optimizer = torch.optim.RMSprop(net.parameters(), lr=1e-3, eps=1e-5)
    config = TrainConfig(env="mujoban/level1", entropy_cost=0.0)
    value_states: dict = {}
    returns = []
    for _ in range(80):
        unrolls, mean_reward = _toy_unrolls(net, rng)
        returns.append(mean_reward)
        batch = make_batch(unrolls, net, value_states)
        learner_step(net, optimizer, batch, config, value_states)
    start, end = np.mean(returns[:10]), np.mean(returns[-10:])
    # Random Gaussian actions (std >= 0.32) score about 0.6; a policy whose
    # mean tracks x approaches 1 - variance.
    assert end > start + 0.1, (start, end)


@pytest.mark.parametrize(
    "name, condition, cameras",
    [
        ("mujoban/level1", "vanilla", True),
        ("mujoban/level1", "expert-planner", False),
        ("mujoxo/mixture", "random-planner", True),
        ("mujogo/7x7", "expert-planner", False),
    ],
)
def test_every_environment_observation_goes_through_the_network(name, condition, cameras, request):
    from hier_agents.baselines.impala.agent_env import AgentEnv
    from hier_agents.baselines.impala.network import ImpalaNet

    if name.startswith("mujogo"):
        request.getfixturevalue("gnugo")
    with AgentEnv(name, condition, seed=0, cameras=cameras) as env:
        net = ImpalaNet(env.input_spec, two_values=condition != "vanilla")
        obs = env.reset()
        assert set(obs) == (
            {"proprio"}
            | {n for n, _ in env.input_spec.images}
            | ({"planner"} if env.input_spec.planner_shape else set())
            | ({"planner_action"} if env.input_spec.planner_action_dim else set())
        )
        out, _ = net(
            {k: torch.as_tensor(v)[None, None] for k, v in obs.items()},
            torch.ones(1, 1, dtype=torch.bool),
        )
        assert out.mean.shape == (1, 1, env.input_spec.action_dim)
        assert (out.value_abs is None) == (condition == "vanilla")
        action, _, _ = net.act(
            {k: v[None] for k, v in obs.items()}, np.ones(1, bool), net.initial_state(1)
        )
        result = env.step(action[0])
        assert set(result.obs) == set(obs)


@pytest.mark.slow
def test_ctrl_c_saves_a_checkpoint_and_the_run_resumes_from_it(tmp_path):
    """SIGINT to the whole process group (what Ctrl-C does): the actors must
    not die under the learner; it finishes, checkpoints and exits."""
    import os
    import signal
    import subprocess
    import sys
    import time

    logdir = tmp_path / "run"
    cmd = [
        sys.executable,
        "-m",
        "hier_agents.train",
        "mujoban/level1",
        "--condition",
        "vanilla",
        "--frames",
        "100000000",
        "--unroll-length",
        "5",
        "--batch-size",
        "2",
        "--actors",
        "1",
        "--observations",
        "proprio",
        "--envs-per-actor",
        "2",
        "--log-every",
        "0",
        "--logdir",
        str(logdir),
        "--no-progress",
    ]
    proc = subprocess.Popen(
        cmd,
        start_new_session=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
    )
    try:
        progress = logdir / "scalars.jsonl"
        for _ in range(600):  # the first update (start-up takes a few seconds)
            if progress.exists() and progress.read_text().count("\n") >= 2:
                break
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.2)
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, err
    assert "interrupted: checkpoint saved" in err and "Traceback" not in err, err
    saved = load_checkpoint(logdir)["counters"]
    assert saved["frames"] == json.loads(out)["frames"] >= 20
    assert saved["frames"] == 10 * saved["updates"]
    logged = [json.loads(line)["frames"] for line in open(logdir / "scalars.jsonl")]
    assert logged[-1] == saved["frames"]
    counters = train(
        TrainConfig(condition="vanilla", steps=saved["frames"] + 10, logdir=str(logdir), **TINY)
    )
    assert counters["frames"] == saved["frames"] + 10
    assert counters["updates"] == saved["updates"] + 1


@pytest.mark.slow
def test_kept_checkpoints_give_a_learning_curve(tmp_path, capsys):
    import subprocess
    import sys
    from pathlib import Path

    run_dir = tmp_path / "run"
    config = dict(TINY, checkpoint_every_s=0.0)  # a checkpoint after every update
    train(
        TrainConfig(
            condition="expert-planner",
            steps=20,
            logdir=str(run_dir),
            keep_checkpoints=True,
            **config,
        )
    )
    kept = sorted(p.name for p in (run_dir / "checkpoints").glob("*.pt"))
    assert kept == ["frames-10.pt", "frames-20.pt"]
    # Kept copies are policies: float16 weights without the value side (and no
    # optimiser); the network loads them as float32.
    copy = load_checkpoint(run_dir / "checkpoints" / "frames-20.pt")
    assert "optimizer" not in copy and "optimizer" in load_checkpoint(run_dir)
    assert copy["policy_only"] and not any(k.startswith("value_") for k in copy["model"])
    assert {t.dtype for t in copy["model"].values()} == {torch.float16}
    net, _ = net_from_checkpoint(copy)
    full = torch.load(run_dir / "checkpoint.pt", weights_only=False)["model"]
    for name in copy["model"]:
        weight = net.state_dict()[name]
        assert weight.dtype == torch.float32
        torch.testing.assert_close(weight, full[name].half().float())
    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "curve.json"
    subprocess.run(
        [
            sys.executable,
            str(root / "benchmarks" / "learning_curve.py"),
            str(run_dir),
            "--every-frames",
            "10",
            "--eval-episodes",
            "1",
            "--json",
            str(out),
        ],
        check=True,
        capture_output=True,
        cwd=root,
    )
    curve = json.loads(out.read_text())["runs"][0]
    assert curve["condition"] == "expert-planner"
    assert [r["frames"] for r in curve["training"]] == [10, 20]
    assert [r["frames"] for r in curve["evaluation"]] == [10, 20]
    assert all(0.0 <= r["success_rate"] <= 1.0 for r in curve["evaluation"])


def test_random_agents_play_through_hier_agents_run(tmp_path, capsys):
    out = tmp_path / "random.json"
    assert (
        run_lib.main(
            ["mujoban/level1", "--agent", "random:10", "--episodes", "2", "--json", str(out)]
        )
        == 0
    )
    summary = json.loads(out.read_text())
    assert summary["agent"] == "random:10" and summary["episodes"] == 2
    assert summary["subgoal_success_rate"] is None
    assert [r["steps"] for r in summary["rows"]] == [
        r["steps"]
        for r in run_lib.run("mujoban/level1", 2, agent="random:10", progress=False)["rows"]
    ]  # seeded
    assert "held 10 steps" in capsys.readouterr().out
    for bad in ("random:0", "random:x", "randomly"):
        with pytest.raises(SystemExit):
            run_lib.main(["mujoban/level1", "--agent", bad])
        assert "random" in capsys.readouterr().err


@pytest.mark.slow
def test_a_killed_actor_is_replaced_and_a_failing_one_stops_the_learner(capfd):
    import os
    import signal

    from hier_agents.baselines.impala.actors import LocalActors
    from hier_agents.baselines.impala.agent_env import AgentEnv
    from hier_agents.baselines.impala.network import ImpalaNet
    from hier_agents.executor import WORKER_RETRIES

    with AgentEnv("mujoban/level1", "vanilla", cameras=False) as env:
        net = ImpalaNet(env.input_spec, two_values=False)
    config = TrainConfig("mujoban/level1", unroll_length=5, envs_per_actor=1, cameras=False)
    actors = LocalActors(config, 2, net)
    try:
        assert len(actors.get(timeout=300)) == 1  # working
        os.kill(actors.pool._local[1][0].pid, signal.SIGKILL)
        for _ in range(1000):  # until the new actor 1 delivers
            if actors.get(timeout=300)[0]["stream"][0] == 1:
                break
        else:
            pytest.fail("the replaced actor never delivered")
        assert actors.restarts == 1
    finally:
        actors.close()
    err = capfd.readouterr().err
    assert (
        "hier_agents: a worker process died (killed by SIGKILL); running actor 1's unroll" in err
        and f"again in a new process (retry 1 of {WORKER_RETRIES})" in err
    ), err
    bad = LocalActors(
        TrainConfig(
            "mujoban/level1", envs_per_actor=1, cameras=False, env_overrides={"no_such_option": 1}
        ),
        1,
        net,
    )
    try:
        with pytest.raises(RuntimeError, match="(?s)actor 0 failed.*no_such_option"):
            bad.get(timeout=300)
    finally:
        bad.close()


@pytest.mark.slow
def test_learner_speed_benchmark_writes_its_row(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "speed.json"
    subprocess.run(
        [
            sys.executable,
            str(root / "benchmarks" / "learner_speed.py"),
            "--frames",
            "10000",
            "--actors",
            "1",
            "--envs-per-actor",
            "2",
            "--batch-size",
            "2",
            "--train-option",
            "action_repeat=2",
            "--bare-steps",
            "200",
            "--json",
            str(out),
        ],
        check=True,
        capture_output=True,
        cwd=root,
    )
    row = json.loads(out.read_text())
    assert row["env"] == "mujoban/level1" and row["actors"] == 1
    assert row["train_options"] == {"action_repeat": 2}
    # An update is 2 unrolls of 100 agent steps, each holding its action 2 control steps.
    assert row["frames"] >= 10000 and row["updates"] == row["frames"] // 400
    for key in ("learner_frames_per_s", "env_steps_per_s", "parallel_env_steps_per_s"):
        assert row[key] > 0, key
    assert row["ratio"] == pytest.approx(row["learner_frames_per_s"] / row["env_steps_per_s"])
    assert row["ratio_to_parallel"] == pytest.approx(
        row["learner_frames_per_s"] / row["parallel_env_steps_per_s"]
    )


def test_action_repeat_counts_control_steps_and_the_checkpoint_agent_holds(tmp_path):
    from hier_agents.agents.runner import Play, Player

    logdir = tmp_path / "run"
    counters = train(TrainConfig(steps=20, action_repeat=2, logdir=str(logdir), **TINY))
    assert counters["frames"] == 20 and counters["updates"] == 1  # 2 unrolls of 5 x 2 frames
    with pytest.raises(ValueError, match="multiple of the frames of one unroll"):
        TrainConfig(steps=40, action_repeat=2, save_at=(25,), **TINY).validate()
    player = Player(
        Play("mujoban/level1", agent=f"checkpoint:{logdir}", options={"stochastic": True})
    )
    try:
        agent, timestep = player.agent, player.env.reset()
        agent.reset(player.description, timestep, seed=0)
        actions = []
        for _ in range(6):
            actions.append(agent.act(timestep))
            timestep = player.env.step(actions[-1])
        for k in (0, 2, 4):  # each sampled action is held for 2 control steps
            np.testing.assert_array_equal(actions[k], actions[k + 1])
        assert not np.array_equal(actions[0], actions[2])
        assert not np.array_equal(actions[2], actions[4])
    finally:
        player.close()


def test_a_kept_copy_is_a_float16_policy_that_loads_as_float32_and_acts_the_same():
    import dataclasses

    from hier_agents.baselines.impala.agent_env import InputSpec
    from hier_agents.baselines.impala.checkpoints import kept_copy
    from hier_agents.baselines.impala.network import net_for

    spec = InputSpec(
        images=(),
        proprio_dim=5,
        planner_shape=None,
        planner_action_dim=0,
        action_dim=2,
        state_shape=(4, 3, 3),
    )
    config = {"condition": "vanilla", "state_channels": 8}
    model = net_for(spec, config).state_dict()
    data = {
        "model": model,
        "optimizer": {"m": 1},
        "rng": 0,
        "config": config,
        "input_spec": dataclasses.asdict(spec),
        "counters": {"frames": 10},
    }
    copy = kept_copy(data)
    assert set(copy) == {"model", "config", "input_spec", "counters", "policy_only"}
    assert {t.dtype for t in copy["model"].values()} == {torch.float16}
    assert set(copy["model"]) == {k for k in model if not k.startswith("value_")}
    assert model["proprio_encoder.weight"].dtype == torch.float32  # the data is left as it was
    assert kept_copy(copy)["model"].keys() == copy["model"].keys()  # a copy of a copy: the same
    net, _ = net_from_checkpoint(copy)
    assert net.policy_only
    for name in copy["model"]:
        assert net.state_dict()[name].dtype == torch.float32
        torch.testing.assert_close(net.state_dict()[name], model[name].half().float())
    # It acts as the full network with the same rounded weights does; it has no values.
    full, _ = net_from_checkpoint({**data, "model": {k: v.half() for k, v in model.items()}})
    obs = {"proprio": np.ones((1, 5), np.float32), "state": np.zeros((1, 4, 3, 3), np.float32)}
    first = np.ones(1, bool)
    a, _, _ = net.act(obs, first, net.initial_state(1), deterministic=True)
    b, _, _ = full.act(obs, first, full.initial_state(1), deterministic=True)
    np.testing.assert_array_equal(a, b)
    batch = {k: torch.as_tensor(v)[None] for k, v in obs.items()}
    with pytest.raises(RuntimeError, match="policy-only"):
        net(batch, torch.ones(1, 1, dtype=torch.bool))
    broken = {**copy, "model": {k: v for k, v in copy["model"].items() if "mean_head" not in k}}
    with pytest.raises(RuntimeError, match="missing"):
        net_from_checkpoint(broken)


@pytest.mark.slow
@pytest.mark.parametrize("condition", ["vanilla", "expert-planner"])
def test_an_actors_unrolls_are_the_same_on_one_physics_thread_or_two(condition):
    """`Actor` advances its environments' physics together (`envs.vector.PhysicsPool`):
    two threads give the unrolls of one, frame for frame, action repeat and
    episode ends included (a 2 s time limit: 40 control steps)."""
    from hier_agents.baselines.impala.actors import Actor

    unrolls = []
    for threads in (1, 2):
        config = TrainConfig(
            condition=condition,
            action_repeat=3,
            env_threads=threads,
            state=True,
            env_overrides={"time_limit": 2.0},
            **{**TINY, "envs_per_actor": 3, "unroll_length": 8},
        )
        torch.manual_seed(0)  # the same initial network
        actor = Actor(config, actor_id=0)
        try:
            unrolls.append([actor.unroll() for _ in range(3)])
        finally:
            actor.close()
    ended = 0
    for one, two in zip(*unrolls):
        for a, b in zip(one, two):
            ended += len(a["episodes"])
            assert a.keys() == b.keys()
            for key in ("actions", "log_probs", "rewards_env", "discounts_env", "first"):
                np.testing.assert_array_equal(a[key], b[key])
            for key in a["obs"]:
                np.testing.assert_array_equal(a["obs"][key], b["obs"][key])
            assert [e["episode_steps"] for e in a["episodes"]] == [
                e["episode_steps"] for e in b["episodes"]
            ]
    assert ended >= 3  # every environment's episode ended within the 72 agent steps
