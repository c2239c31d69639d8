"""Training the ball skill (`hier_agents.learning.train_skill`) and the shipped policy."""

import json

import numpy as np
import pytest
import torch

from hier_agents.learning.train_skill import Agent, main
from skills.learned import POLICY_PATH, LearnedBallSkill, load_policy


def test_shipped_checkpoint_loads():
    assert POLICY_PATH.exists()
    assert POLICY_PATH.stat().st_size < 2_000_000
    policy = load_policy()
    out = policy(np.zeros(12))
    assert out.shape == (2,) and np.all(np.isfinite(out))


def test_shipped_checkpoint_solves_a_level1_episode():
    """Observation-only: the camera estimator behind the boundary."""
    from hier_agents.run import run

    summary = run("mujoban/level1", 1, seed=0, skill="learned-ball", progress=False)
    assert summary["privileged"] is False
    assert summary["rows"][0]["solved"], summary["rows"][0]


def test_numpy_policy_matches_torch():
    agent = Agent(12, 2)
    from skills.learned.ball import NumpyPolicy

    numpy_policy = NumpyPolicy(agent.actor.state_dict())
    x = np.random.default_rng(0).normal(size=(5, 12)).astype(np.float32)
    with torch.no_grad():
        expected = agent.actor(torch.as_tensor(x)).numpy()
    got = np.array([numpy_policy(row) for row in x])
    np.testing.assert_allclose(got, expected, atol=1e-5)


def test_teacher_mode_is_the_scripted_skill():
    """`LearnedBallSkill("teacher")` acts exactly as `BallSkill`."""
    import envs
    from abstract_planners.sokoban_solver import SokobanSolverPlanner
    from hier_agents.estimators import OracleEstimator
    from skills.ball import BallSkill

    actions = []
    for skill in (BallSkill(), LearnedBallSkill("teacher")):
        env = envs.load("mujoban/level2", seed=4, **envs.no_cameras("mujoban/level2"))
        est = OracleEstimator(env)
        ts = env.reset()
        est.reset(env.description(), ts)
        scene = est.estimate(ts)
        skill.reset(env.description(), SokobanSolverPlanner().next_push(scene.state), scene)
        seq = []
        for _ in range(30):
            a = skill.act(ts, scene)
            seq.append(a)
            ts = env.step(a)
            scene = est.estimate(ts)
        actions.append(np.array(seq))
    np.testing.assert_allclose(actions[0], actions[1], atol=1e-12)


@pytest.mark.slow
def test_cli_trains_checkpoints_and_resumes(tmp_path, capsys):
    args = [
        "ball",
        "--frames",
        "400",
        "--bc-frames",
        "100",
        "--dagger-frames",
        "100",
        "--rollout",
        "50",
        "--envs",
        "2",
        "--save-every",
        "1",
        "--logdir",
        str(tmp_path),
        "--eval-episodes",
        "2",
        "--seed",
        "1",
    ]
    assert main(args) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["frames"] == 400 and summary["bc_frames"] == 200
    assert summary["iterations"] == 2
    assert (tmp_path / "checkpoint.pt").exists() and (tmp_path / "config.json").exists()
    lines = (tmp_path / "scalars.jsonl").read_text().splitlines()
    assert [json.loads(line)["step"] for line in lines[:2]] == [300, 400]
    load_policy(tmp_path / "ball_policy.pt")
    assert any(p.name.startswith("events.out.tfevents") for p in tmp_path.iterdir())
    assert "95% Wilson" in capsys.readouterr().out
    # Two PPO iterations: the default three critic-only ones are capped at one.
    assert summary["actor_iterations"] == 1
    # Resume: two more iterations from the checkpoint, no second warm start,
    # no second critic-only phase.
    assert main(args[:2] + ["600"] + args[3:] + ["--resume"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["frames"] == 600 and summary["iterations"] == 4
    assert summary["bc_frames"] == 200 and summary["actor_iterations"] == 3
    # Without --resume the finished run is not overwritten.
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2 and "already holds a run" in capsys.readouterr().err


@pytest.mark.slow
def test_a_resumed_run_continues_bit_identically(tmp_path):
    """Straight to 500 frames == to 400, stop, resume to 500 (slow: three
    trainer runs; tests/test_rundir.py checks the convention quickly). One
    critic-only iteration, which neither budget caps, so both runs have the
    same schedule."""
    common = [
        "ball",
        "--bc-frames",
        "100",
        "--dagger-frames",
        "100",
        "--rollout",
        "50",
        "--envs",
        "2",
        "--save-every",
        "1",
        "--eval-episodes",
        "0",
        "--seed",
        "2",
        "--critic-warmup",
        "1",
    ]
    assert main(common + ["--frames", "500", "--logdir", str(tmp_path / "straight")]) == 0
    assert main(common + ["--frames", "400", "--logdir", str(tmp_path / "split")]) == 0
    torch.manual_seed(12345)  # the resumed run must restore every random state itself
    np.random.seed(12345)
    assert main(common + ["--frames", "500", "--logdir", str(tmp_path / "split"), "--resume"]) == 0
    a = torch.load(tmp_path / "straight" / "checkpoint.pt", weights_only=False)
    b = torch.load(tmp_path / "split" / "checkpoint.pt", weights_only=False)
    assert a["state"]["frames"] == b["state"]["frames"] == 500
    for key, value in a["agent"].items():
        assert torch.equal(value, b["agent"][key]), key
