"""The run-directory convention (`hier_agents.learning.rundir`): exact resume,
Ctrl-C, atomic checkpoints, config.json, scalars.jsonl."""

from __future__ import annotations

import json
import os
import random
import signal

import numpy as np
import pytest
import torch

from physics_planning.cli import UsageError
from hier_agents.learning import ppo, rundir
from hier_agents.learning.rundir import RunDir
from toy_rl import Gaussian, Target


def toy_trainer(path, updates: int, resume: bool = False, on_update=None):
    """A complete small trainer on RunDir + ppo. The environments are reseeded
    from the update count each update, so that their state is a function of
    the checkpoint (what exact resume needs). Returns (policy, optimiser, run)."""
    rundir.seed_everything(0)
    policy = Gaussian()
    cfg = ppo.PPOConfig(lr=0.01, anneal_lr=True, epochs=2, minibatches=2)
    optimizer = torch.optim.Adam(policy.parameters(), lr=cfg.lr)
    run = RunDir(
        path, {"updates": updates, "lr": cfg.lr, "width": 1}, resume=resume, fixed=("width",)
    )
    state = {"updates": 0}
    data = run.load()
    if data is not None:
        policy.load_state_dict(data["policy"])
        optimizer.load_state_dict(data["optimizer"])
        state.update(data["state"])
    envs = ppo.make_vector_env([Target] * 2)
    collector = ppo.RolloutCollector(envs, policy, steps=8)
    bar = run.progress(updates, state["updates"], desc="toy", unit="update", disable=True)
    save = lambda: run.save(  # noqa: E731
        {
            "policy": policy.state_dict(),
            "optimizer": optimizer.state_dict(),
            "state": state,
        }
    )
    try:
        with run.interruptible():
            while state["updates"] < updates and not run.stop_requested:
                collector.reset(seed=1000 + state["updates"])
                # Draws from numpy's and python's RNGs too: their states must resume.
                noise = np.random.rand() + random.random()
                _, stats = ppo.iteration(
                    collector, optimizer, cfg, fraction_left=1 - state["updates"] / updates
                )
                state["updates"] += 1
                run.log(state["updates"], {**stats, "noise": noise})
                bar.update(1)
                if on_update is not None:
                    on_update(state["updates"])
            save()
    finally:
        envs.close()
        run.close()
    return policy, optimizer, run


def test_a_resumed_run_continues_bit_identically(tmp_path):
    straight, straight_opt, _ = toy_trainer(tmp_path / "straight", 6)
    toy_trainer(
        tmp_path / "split", 6, on_update=lambda n: n == 3 and os.kill(os.getpid(), signal.SIGINT)
    )
    assert (
        torch.load(tmp_path / "split" / "checkpoint.pt", weights_only=True)["state"]["updates"] == 3
    )
    # A fresh process state: other random states, new objects.
    torch.manual_seed(123)
    np.random.seed(123)
    random.seed(123)
    resumed, resumed_opt, run = toy_trainer(tmp_path / "split", 6, resume=True)
    assert run.resumed
    for (name, a), b in zip(straight.state_dict().items(), resumed.state_dict().values()):
        assert torch.equal(a, b), name
    assert str(straight_opt.state_dict()) == str(resumed_opt.state_dict())
    lines = [
        [json.loads(line) for line in open(tmp_path / d / "scalars.jsonl")]
        for d in ("straight", "split")
    ]
    assert lines[0] == lines[1] and [line["step"] for line in lines[0]] == list(range(1, 7))


def test_ctrl_c_finishes_the_update_saves_and_restores_the_handler(tmp_path):
    before = signal.getsignal(signal.SIGINT)
    policy, _, run = toy_trainer(
        tmp_path, 50, on_update=lambda n: n == 2 and os.kill(os.getpid(), signal.SIGINT)
    )
    assert run.stop_requested and signal.getsignal(signal.SIGINT) is before
    saved = torch.load(tmp_path / "checkpoint.pt", weights_only=True)
    assert saved["state"]["updates"] == 2
    for name, tensor in policy.state_dict().items():
        assert torch.equal(saved["policy"][name], tensor), name
    assert len((tmp_path / "scalars.jsonl").read_text().splitlines()) == 2
    # A second Ctrl-C aborts at once.
    with pytest.raises(KeyboardInterrupt):
        with RunDir(tmp_path / "other", {}) as other, other.interruptible():
            os.kill(os.getpid(), signal.SIGINT)
            assert other.stop_requested
            os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is before


def test_an_interrupted_save_leaves_the_previous_checkpoint_whole(tmp_path, monkeypatch):
    with RunDir(tmp_path, {"a": 1}) as run:
        run.save({"step": 1})
        real_save = torch.save

        def crash(obj, f, *args, **kwargs):  # half a file, then the "crash"
            real_save(obj, f, *args, **kwargs)
            with open(f, "r+b") as fh:
                fh.truncate(10)
            raise KeyboardInterrupt

        monkeypatch.setattr(torch, "save", crash)
        with pytest.raises(KeyboardInterrupt):
            run.save({"step": 2})
        monkeypatch.undo()
        assert torch.load(run.checkpoint_path, weights_only=True)["step"] == 1
        assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("events")) == [
            "checkpoint.pt",
            "config.json",
            "scalars.jsonl",
        ]
        run.save({"step": 3}, keep="step-3")
        assert torch.load(tmp_path / "checkpoints" / "step-3.pt", weights_only=True)["step"] == 3
        # A lean kept copy leaves out what only resuming reads; checkpoint.pt keeps it all.
        run.save(
            {"step": 4, "optimizer": {"m": 1}},
            keep="step-4",
            lean=lambda data: {k: v for k, v in data.items() if k not in ("optimizer", "rng")},
        )
        lean = torch.load(tmp_path / "checkpoints" / "step-4.pt", weights_only=True)
        assert lean["step"] == 4 and "optimizer" not in lean and "rng" not in lean
        assert lean["config"] == run.config
        full = torch.load(run.checkpoint_path, weights_only=True)
        assert full["optimizer"] == {"m": 1} and "rng" in full


def test_config_json_is_checked_and_merged_on_resume(tmp_path):
    with RunDir(tmp_path, {"env": "a", "steps": 10, "path": tmp_path}) as run:
        run.save({})
        run.log(5, {"loss": 1.5, "name": "x", "nan": float("nan")})
    assert json.loads((tmp_path / "config.json").read_text())["path"] == str(tmp_path)
    with pytest.raises(ValueError, match="env='a'"):
        RunDir(tmp_path, {"env": "b"}, resume=True, fixed=("env",))
    with RunDir(tmp_path, {"env": "a", "steps": 20}, resume=True, fixed=("env",)) as run:
        assert run.resumed and run.config == {"env": "a", "steps": 20, "path": str(tmp_path)}
        run.log(6, {"loss": 1.0})
    assert json.loads((tmp_path / "config.json").read_text())["steps"] == 20
    lines = [json.loads(line) for line in open(tmp_path / "scalars.jsonl")]
    assert [line["step"] for line in lines] == [5, 6] and lines[0]["name"] == "x"
    # Not resuming: a directory without a checkpoint starts a fresh run (the
    # scalars restart); one that holds a run is refused, untouched.
    (tmp_path / "checkpoint.pt").rename(tmp_path / "moved.pt")
    RunDir(tmp_path, {"env": "b"}).close()
    assert (tmp_path / "scalars.jsonl").read_text() == ""
    (tmp_path / "moved.pt").rename(tmp_path / "checkpoint.pt")
    with pytest.raises(UsageError, match="already holds a run"):
        RunDir(tmp_path, {"env": "c"})
    assert json.loads((tmp_path / "config.json").read_text())["env"] == "b"


def test_resume_modes_and_refusals_leave_the_directory_untouched(tmp_path):
    # resume=True needs a checkpoint; nothing is created when it is refused.
    with pytest.raises(UsageError, match="nothing to resume"):
        RunDir(tmp_path / "new", {}, resume=True)
    assert not (tmp_path / "new").exists()
    # resume=None: start, then continue.
    with RunDir(tmp_path / "auto", {"env": "a"}, resume=None, trainer="t1", fixed=("env",)) as run:
        assert not run.resumed
        run.record(observations=["proprio"], privileged=False)
        run.save({})
    saved = json.loads((tmp_path / "auto" / "config.json").read_text())
    assert saved["trainer"] == "t1" and saved["observations"] == ["proprio"]
    assert (
        torch.load(tmp_path / "auto" / "checkpoint.pt", weights_only=False)["config"]["privileged"]
        is False
    )
    with RunDir(tmp_path / "auto", {"env": "a"}, resume=None, trainer="t1", fixed=("env",)) as run:
        assert run.resumed and run.config["observations"] == ["proprio"]
    # Another trainer's run, a run made before runs recorded their trainer
    # without the identifying key, a file: refused.
    with pytest.raises(UsageError, match="holds a run of t1, not of t2"):
        RunDir(tmp_path / "auto", {"env": "a"}, resume=None, trainer="t2", fixed=("env",))
    config = json.loads((tmp_path / "auto" / "config.json").read_text())
    del config["trainer"]
    (tmp_path / "auto" / "config.json").write_text(json.dumps(config))
    with pytest.raises(UsageError, match="not a run of t3"):
        RunDir(tmp_path / "auto", {"spec": "x"}, resume=None, trainer="t3", fixed=("spec",))
    with RunDir(tmp_path / "auto", {"env": "a"}, resume=None, trainer="t1", fixed=("env",)) as run:
        assert run.resumed  # the legacy run has the identifying key
    (tmp_path / "file").write_text("")
    with pytest.raises(UsageError, match="is a file"):
        RunDir(tmp_path / "file", {}, resume=None)


def test_rng_states_round_trip():
    rundir.seed_everything(5)
    saved = rundir.rng_state()
    first = (torch.rand(3), np.random.rand(3), random.random())
    rundir.seed_everything(6)
    rundir.set_rng_state(saved)
    second = (torch.rand(3), np.random.rand(3), random.random())
    assert torch.equal(first[0], second[0]) and np.array_equal(first[1], second[1])
    assert first[2] == second[2]


def test_a_run_made_before_a_default_changed_keeps_its_settings(tmp_path):
    """A MuJoBan run whose record names no ``sleep`` was made when every
    default was the original's: it continues with ``sleep=False`` and is
    refused with the new default, never silently continued on it."""
    old = {"env": "mujoban/level1", "env_overrides": {"top_camera": None}}
    with RunDir(tmp_path, old) as run:
        run.save({})
    explicit = {"top_camera": None, "sleep": True}  # what a run records now
    with pytest.raises(UsageError, match="env_overrides=.*'sleep': False"):
        RunDir(
            tmp_path,
            {**old, "env_overrides": explicit},
            fixed=("env_overrides",),
            env_key="env_overrides",
            resume=None,
        )
    pinned = {**old, "env_overrides": {"top_camera": None, "sleep": False}}
    with RunDir(
        tmp_path, pinned, fixed=("env_overrides",), env_key="env_overrides", resume=None
    ) as run:
        assert run.resumed and run.config["env_overrides"] == {"top_camera": None, "sleep": False}
