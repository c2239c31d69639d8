"""Trainers honour their budgets and update the policy at the smallest one
they accept; `hier_agents.train`'s observation flags and what a run records
about them (issue 26)."""

from __future__ import annotations

import json

import pytest
import torch

from physics_planning.cli import UsageError
from hier_agents import train as train_cli
from hier_agents.baselines.impala import learner
from hier_agents.run import run
from hier_agents.learning import ppo, train_options, train_skill


def _watch(monkeypatch, module, name, params_of):
    """Wraps ``module.name`` (an update step): records, per call, whether the
    parameters ``params_of(args, kwargs)`` (name -> tensor) changed and the
    call's ``actor`` keyword."""
    calls = []
    real = getattr(module, name)

    def wrapped(*args, **kwargs):
        before = {k: v.detach().clone() for k, v in params_of(args, kwargs).items()}
        out = real(*args, **kwargs)
        after = params_of(args, kwargs)
        calls.append(
            {
                "changed": {k for k in before if not torch.equal(before[k], after[k])},
                "actor": kwargs.get("actor", True),
            }
        )
        return out

    monkeypatch.setattr(module, name, wrapped)
    return calls


# -- hier_agents.train -----------------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_impala_run(tmp_path_factory):
    """A 10-frame budget, below one batch (4 unrolls of 5 frames): one update
    of 2 unrolls; the learner step is watched."""
    logdir = tmp_path_factory.mktemp("impala")
    with pytest.MonkeyPatch.context() as mp:
        calls = _watch(
            mp,
            learner,
            "learner_step",
            lambda args, kwargs: {
                k: v for k, v in args[0].named_parameters() if k.startswith("mean_head")
            },
        )
        counters = learner.train(
            learner.TrainConfig(
                env="mujoban/level1",
                steps=10,
                unroll_length=5,
                batch_size=4,
                actors=1,
                envs_per_actor=2,
                cameras=False,
                state=True,
                logdir=str(logdir),
                checkpoint_every_s=1e9,
                log_every_s=0.0,
                progress=False,
            )
        )
    return logdir, counters, calls


def test_a_budget_below_one_batch_trains_one_smaller_batch_that_moves_the_policy(tiny_impala_run):
    logdir, counters, calls = tiny_impala_run
    assert counters["frames"] == 10 and counters["updates"] == 1
    assert len(calls) == 1 and calls[0]["changed"] == {"mean_head.weight", "mean_head.bias"}
    # The run records the default that deviates from the original's (envs.explicit_options).
    assert json.loads((logdir / "config.json").read_text())["env_overrides"] == {"sleep": True}


def test_env_options_reach_the_actors_environments():
    config = train_cli.config_from_args(
        train_cli.parse_args(
            ["mujoban/level1", "--env-option", "sleep=False", "--observations", "main-camera"]
        )
    )
    assert config.env_overrides == {"sleep": False, "egocentric_camera": None}


@pytest.mark.slow
def test_the_run_records_what_the_agent_observed_and_play_reports_it(tiny_impala_run, tmp_path):
    from envs.mujoban.levels import BOXOBAN_DIR

    logdir, _, _ = tiny_impala_run
    config = json.loads((logdir / "config.json").read_text())
    assert config["observations"] == ["proprio", "state"] and config["privileged"] is True
    assert config["trainer"] == learner.TRAINER
    # env_options reach the evaluation environment (a Boxoban file's levels).
    summary = run(
        "mujoban/level1",
        1,
        0,
        agent=f"checkpoint:{logdir}",
        progress=False,
        levels=str(BOXOBAN_DIR / "medium-valid-000.txt"),
    )
    assert summary["observations"] == ["proprio", "state"] and summary["privileged"] is True
    assert len(summary["rows"]) == 1
    with pytest.raises(UsageError, match="no_such_option"):
        run(
            "mujoban/level1",
            1,
            agent=f"checkpoint:{logdir}",
            progress=False,
            env_options={"no_such_option": 1},
        )
    # A run directory from before these fields: inferred from the checkpoint.
    old = tmp_path / "old"
    old.mkdir()
    ckpt = torch.load(logdir / "checkpoint.pt", weights_only=False)
    for key in ("observations", "privileged", "trainer"):
        del ckpt["config"][key]
    torch.save(ckpt, old / "checkpoint.pt")
    summary = run("mujoban/level1", 1, agent=f"checkpoint:{old}", progress=False)
    assert summary["observations"] == ["proprio", "state"] and summary["privileged"] is True


def test_another_trainers_run_directory_is_refused_in_one_line(tiny_impala_run, capsys):
    logdir, _, _ = tiny_impala_run
    with pytest.raises(SystemExit) as exc:
        train_options.main(
            ["mujoban/level1", "--option-steps", "128", "--resume", "--logdir", str(logdir)]
        )
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1
    assert "holds a run of python -m hier_agents.train" in err


@pytest.mark.parametrize(
    "argv, expected",
    [
        ([], dict(cameras=True, image_size=96, envs_per_actor=32, env_overrides={}, state=False)),
        (
            ["--preset", "cpu"],
            dict(
                cameras=True,
                image_size=48,
                envs_per_actor=8,
                env_overrides={"egocentric_camera": None},
            ),
        ),
        (
            ["--preset", "cpu", "--envs-per-actor", "4", "--image-size", "64"],
            dict(image_size=64, envs_per_actor=4, env_overrides={"egocentric_camera": None}),
        ),
        (["--observations", "proprio", "--state"], dict(cameras=False, state=True)),
        ([], dict(unroll_length=100, batch_size=None)),  # the paper's: 128 x 100 on MuJoBan
        (["--preset", "small-batches"], dict(unroll_length=20, batch_size=16)),
        (["--preset", "small-batches", "--batch-size", "8"], dict(unroll_length=20, batch_size=8)),
    ],
)
def test_the_default_agent_sees_the_cameras_and_presets_lighten_it(argv, expected):
    config = train_cli.config_from_args(train_cli.parse_args(["mujoban/level1", *argv]))
    for key, value in expected.items():
        assert getattr(config, key) == value, key
    if argv == []:
        assert config.resolved_batch() == 128


def test_the_board_games_main_camera_is_their_only_one():
    config = train_cli.config_from_args(
        train_cli.parse_args(["mujoxo/mixture", "--observations", "main-camera"])
    )
    assert config.cameras and config.env_overrides == {}


def test_input_spec_keys_and_privilege():
    from hier_agents.baselines.impala.agent_env import InputSpec

    plain = InputSpec(
        images=(("top_camera", (3, 8, 8)),),
        proprio_dim=3,
        planner_shape=None,
        planner_action_dim=0,
        action_dim=2,
    )
    assert plain.keys == ("proprio", "top_camera") and not plain.privileged
    planner = InputSpec(
        images=(),
        proprio_dim=3,
        planner_shape=(8, 10, 10),
        planner_action_dim=4,
        action_dim=2,
        state_shape=(4, 10, 10),
    )
    assert planner.keys == ("proprio", "planner", "planner_action", "state")
    assert planner.privileged


@pytest.mark.parametrize(
    "argv, message",
    [
        (["mujoban/level1", "--frames", "50"], "--frames >= 100"),
        (["mujoban/level1", "--seed", "-1"], "--seed"),
        (["mujoban/level1", "--observations", "camera"], "did you mean 'cameras'"),
        (["mujoban/level1", "--preset", "cpus"], "did you mean 'cpu'"),
        (["mujoban/level1", "--envs-per-actor", "0"], "--envs-per-actor"),
        (["mujoban/level1", "--env-option", "sleep=maybe"], "sleep must be True or False"),
        (["mujoxo/mixture", "--env-option", "sleep=False"], "unknown key 'sleep'"),
    ],
)
def test_train_refuses_bad_inputs_in_one_line(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        train_cli.main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and message in err, err


def test_train_refuses_a_file_as_logdir_before_any_work(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    with pytest.raises(SystemExit) as exc:
        train_cli.main(
            ["mujoban/level1", "--observations", "proprio", "--logdir", str(tmp_path / "file")]
        )
    assert exc.value.code == 2 and "is a file" in capsys.readouterr().err


# -- PPO trainers ----------------------------------------------------------------------


def test_ppo_budget_helpers():
    assert ppo.iterations(0, 16, "x", "y") == 0 and ppo.iterations(40, 16, "x", "y") == 2
    with pytest.raises(
        UsageError, match="--frames 5 is less than one PPO update .16 steps.; give 16"
    ):
        ppo.iterations(5, 16, "--frames 5", "give 16")
    assert [ppo.critic_warmup(n, 3) for n in (0, 1, 2, 3, 4, 9)] == [0, 0, 1, 2, 3, 3]


def _skill_args(tmp_path, *more):
    return [
        "ball",
        "--envs",
        "1",
        "--rollout",
        "16",
        "--eval-episodes",
        "0",
        "--seed",
        "1",
        "--logdir",
        str(tmp_path),
        *more,
    ]


def test_train_skill_updates_the_actor_at_its_smallest_budgets(tmp_path, monkeypatch):
    calls = _watch(
        monkeypatch,
        ppo,
        "iteration",
        lambda args, kwargs: dict(args[0].policy.actor[-1].named_parameters()),
    )
    # No warm start: one PPO iteration (1 env x 16 steps) is the smallest budget.
    assert train_skill.main(_skill_args(tmp_path / "a", "--frames", "16", "--bc-frames", "0")) == 0
    assert [c["actor"] for c in calls] == [True] and calls[0]["changed"] == {"weight", "bias"}
    # After a warm start, a budget of one iteration updates the actor, not
    # only the critic (--critic-warmup 3 is capped).
    calls.clear()
    assert (
        train_skill.main(
            _skill_args(
                tmp_path / "b",
                "--frames",
                "48",
                "--bc-frames",
                "32",
                "--dagger-frames",
                "0",
                "--bc-epochs",
                "1",
                "--critic-warmup",
                "3",
            )
        )
        == 0
    )
    assert [c["actor"] for c in calls] == [True] and calls[0]["changed"] == {"weight", "bias"}
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert summary["frames"] == 48 and summary["actor_iterations"] == 1


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--frames", "8", "--bc-frames", "0"], "give --frames >= 16"),
        (
            ["--frames", "40", "--bc-frames", "32", "--dagger-frames", "0"],
            "give --frames 32 (the warm start only) or >= 48",
        ),
        (["--frames", "20", "--bc-frames", "32", "--dagger-frames", "0"], "--frames >= 32"),
        (["--frames", "16", "--bc-frames", "0", "--resume"], "nothing to resume"),
        (["--frames", "16", "--estimator", "camra"], "did you mean 'camera'"),
    ],
)
def test_train_skill_refuses_bad_inputs_in_one_line(argv, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        train_skill.main(_skill_args(tmp_path / "run", *argv))
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "run").exists()


def test_train_skill_json_folder_is_created_up_front(tmp_path):
    out = tmp_path / "new" / "folder" / "eval.json"
    train_skill.parse_args(["ball", "--evaluate", "--json", str(out)])
    assert out.parent.is_dir()


def test_train_options_updates_the_policy_at_its_smallest_budget(tmp_path, monkeypatch):
    calls = _watch(
        monkeypatch,
        ppo,
        "iteration",
        lambda args, kwargs: dict(args[0].policy.net.policy.named_parameters()),
    )
    assert (
        train_options.main(
            [
                "mujoban/level1",
                "--option-steps",
                "0",
                "--abstract-steps",
                "16",
                "--abstract-envs",
                "1",
                "--rollout",
                "16",
                "--eval-episodes",
                "0",
                "--logdir",
                str(tmp_path),
            ]
        )
        == 0
    )
    assert len(calls) == 1 and calls[0]["changed"] == {"weight", "bias"}
    assert json.loads((tmp_path / "summary.json").read_text())["abstract_steps"] == 16


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--option-steps", "10"], "give --option-steps 0 or >= 128"),
        (["--option-steps", "0"], "nothing to train"),
        (["--option-steps", "0", "--abstract-steps", "100"], "give --abstract-steps 0 or >= 1024"),
        (["--option-steps", "128", "--skill", "bal"], "did you mean 'ball'"),
        (["--option-steps", "128", "--resume"], "nothing to resume"),
    ],
)
def test_train_options_refuses_bad_inputs_in_one_line(argv, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        train_options.main(["mujoban/level1", "--logdir", str(tmp_path / "run"), *argv])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "run").exists()


def test_image_chunks_recomputed_in_backward_give_the_same_values_and_gradients(monkeypatch):
    """A learner batch of images is encoded in recomputed chunks (memory);
    the outputs and gradients are those of one pass."""
    from hier_agents.baselines.impala.network_parts import ImageEncoder

    torch.manual_seed(0)
    encoder = ImageEncoder((3, 16, 16))
    images = torch.randint(0, 256, (10, 3, 16, 16), dtype=torch.uint8)
    weights = torch.randn(10, 256)
    results = []
    for chunk in (100, 3):  # one pass; four chunks (the last one short)
        monkeypatch.setattr(ImageEncoder, "CHUNK", chunk)
        encoder.zero_grad()
        out = encoder(images)
        (out * weights).sum().backward()
        results.append((out.detach(), [p.grad.clone() for p in encoder.parameters()]))
    (one, one_grads), (chunked, chunked_grads) = results
    assert one.shape == chunked.shape == (10, 256)
    assert torch.allclose(one, chunked, atol=1e-6)
    for a, b in zip(one_grads, chunked_grads):  # float sums in another order
        assert (a - b).abs().max() <= 1e-5 * a.abs().max(), (a - b).abs().max()
