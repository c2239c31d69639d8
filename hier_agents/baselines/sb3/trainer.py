"""`train`: a Stable-Baselines3 algorithm trained on a gymnasium environment,
in a run directory (`hier_agents.learning.rundir.RunDir`).

The run directory ``logdir`` holds:

* ``model.zip``: the latest model (SB3's format, ``ALGO.load``), with
  ``model.json`` beside it: the counters when it was saved (``frames``,
  ``episodes``, ``wall_s``, ``cpu_s``);
* ``checkpoints/frames-B.zip`` for each ``save_at`` budget B, with
  ``frames-B.json`` (the same counters). Training stops exactly at B: the
  budgets are multiples of one collection (`Sb3Config.granularity`), and
  `train` runs ``learn`` in segments ending at each budget. Only a run
  interrupted (Ctrl-C) between collections and resumed reaches a later
  budget off the collection grid; its checkpoint is then the first one past
  B, and ``frames-B.json`` says its true frame count;
* ``replay_buffer.pkl`` (off-policy algorithms): the replay buffer, so that a
  resumed run continues with it;
* ``config.json``: the `Sb3Config`, the trainer, and what the policy reads:
  ``observations`` (the environment's observation keys), ``observation_keys``
  (`envs.gymnasium_env.observation_keys`: how they are arranged),
  ``privileged`` (the keys include one the environment declares privileged:
  ``obs="state"``'s abstract state), ``sb3_version``;
* ``scalars.jsonl`` and TensorBoard events: ``frames``, ``episodes/count``,
  ``episodes/return`` and ``episodes/success_rate`` (the last 100 episodes;
  success is ``info["is_success"]``), ``perf/frames_per_s``, ``wall_s``,
  ``cpu_s``.

Frames are environment control steps summed over the ``n_envs``
environments: SB3's ``num_timesteps`` (the algorithm's steps) times
``action_repeat`` (`envs.gymnasium_env.ActionRepeat`). Running the same config again on the
same ``logdir`` continues from ``model.zip`` (and the replay buffer) at its
frame count, with environments seeded anew for the new part: a larger
``frames`` extends the run. ``wall_s`` and ``cpu_s`` (this process plus the
environment subprocesses, read from ``/proc``; elsewhere this process only)
sum over every part. Learning-rate schedules see each segment as a whole
``learn`` call (SB3 computes their progress per call).
"""

from __future__ import annotations

import dataclasses
import io
import os
import sys
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from hier_agents.baselines.sb3.config import ALGORITHMS, Sb3Config
from hier_agents.learning.rundir import KEPT, RunDir
from physics_planning.cli import UsageError, atomic_write, plural, write_json

__all__ = ["FIXED", "MODEL", "REPLAY", "TRAINER", "make_env", "train"]

#: The trainer recorded in its run directories.
TRAINER = "python -m hier_agents.baselines.sb3"
#: The latest model's file in the run directory; the replay buffer's.
MODEL, REPLAY = "model.zip", "replay_buffer.pkl"
#: Config keys a continued run must share with the saved one.
FIXED = (
    "env",
    "algo",
    "policy",
    "obs",
    "n_envs",
    "action_repeat",
    "env_options",
    "hyperparameters",
    "seed",
)
#: Seconds between progress lines and between scalars rows.
_PROGRESS_S, _LOG_S = 30.0, 10.0


def make_env(env: str, obs: str, env_options: dict, action_repeat: int = 1):
    """The `envs.gymnasium_env.GymnasiumEnv` of ``env`` with observation
    ``obs`` and `envs.load` overrides ``env_options`` (JSON lists become
    tuples: camera sizes), each action held ``action_repeat`` control steps
    (`envs.gymnasium_env.ActionRepeat`) when above 1."""
    from envs.gymnasium_env import ActionRepeat, GymnasiumEnv

    options: dict[str, Any] = {
        k: tuple(v) if isinstance(v, list) else v for k, v in env_options.items()
    }
    made = GymnasiumEnv(env, obs=obs, **options)
    return made if action_repeat == 1 else ActionRepeat(made, action_repeat)


def train(config: Sb3Config) -> dict:
    """Trains (or continues) ``config``'s run to ``config.frames`` frames.

    Returns:
      The counters: ``frames`` (SB3's ``num_timesteps`` x ``action_repeat``), ``episodes``,
      ``wall_s``, ``cpu_s`` (over every part of the run), ``return`` and
      ``success_rate`` (means over the last 100 episodes, when any ended).

    Raises:
      UsageError: `Sb3Config.validate`'s; the logdir is a file or holds a run
        this config cannot continue (`RunDir`); the algorithm refuses the
        environment's spaces or a hyperparameter's value.
    """
    import envs

    config.validate()
    config.env_options = envs.explicit_options(config.env, config.env_options)
    run = RunDir(
        config.logdir,
        dataclasses.asdict(config),
        resume=None,
        fixed=FIXED,
        env_key="env_options",
        trainer=TRAINER,
        checkpoint=MODEL,
    )

    try:
        return _Session(config, run).train()
    finally:
        run.close()


def _part_seed(seed: int, frames: int) -> int:
    """The seed of a run part starting at ``frames`` (environment ``i`` gets it + i)."""
    return int(np.random.SeedSequence([seed, frames]).generate_state(1)[0] % 2**31)


def _proc_cpu(pid: int) -> float:
    """CPU seconds (user + system) of process ``pid`` from ``/proc``; 0 when unreadable."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return 0.0


class _Session:
    """One part of a run: the vector environment, the model, the clocks."""

    def __init__(self, config: Sb3Config, run: RunDir):
        self.config, self.run = config, run
        self.counters = {"frames": 0, "episodes": 0, "wall_s": 0.0, "cpu_s": 0.0}
        saved = run.path / "model.json"
        if run.resumed and saved.is_file():
            import json

            self.counters.update(json.loads(saved.read_text()))
        self.start, self.process0 = time.perf_counter(), time.process_time()
        self.wall0, self.cpu0 = self.counters["wall_s"], self.counters["cpu_s"]
        self.children: dict[int, float] = {}  # env subprocess pid -> its last CPU seconds
        self.venv: Any = None
        self.model: Any = None

    def clock(self) -> None:
        """Brings ``wall_s`` and ``cpu_s`` up to now (subprocesses read while alive)."""
        for pid in self.children:
            self.children[pid] = max(self.children[pid], _proc_cpu(pid))
        self.counters["wall_s"] = self.wall0 + time.perf_counter() - self.start
        self.counters["cpu_s"] = (
            self.cpu0 + time.process_time() - self.process0 + sum(self.children.values())
        )

    def train(self) -> dict:
        """Builds, learns to each budget (saving there), saves; the counters."""
        import torch

        torch.set_num_threads(1)
        self._record_observations()
        self._build()
        assert self.model is not None
        frames = self.frames()
        self.counters["frames"] = frames
        if frames >= self.config.frames:
            print(
                f"{self.run.checkpoint_path} already has {plural(frames, 'frame')}, the "
                f"budget is {plural(self.config.frames, 'frame')}: nothing to train",
                file=sys.stderr,
            )
            self._close()
            return self._result()
        try:
            with self.run.interruptible():
                self._learn()
        finally:
            self.clock()
            self._close()
            self.clock()
            self._save(self.run.path / MODEL)
            if ALGORITHMS[self.config.algo] == "off":
                self._save_replay()
        return self._result()

    def _record_observations(self) -> None:
        """Records in ``config.json`` what the policy reads (one probe environment)."""
        import stable_baselines3

        from envs.gymnasium_env import flat_keys, observation_keys

        config = self.config
        probe = make_env(config.env, config.obs, config.env_options)
        try:
            keys = observation_keys(probe.dm_env, config.obs)
            privileged = probe.dm_env.privileged_observations
            if ALGORITHMS[config.algo] == "off" and not hasattr(probe.action_space, "low"):
                raise UsageError(f"{config.algo} needs a Box action space, {config.env} has none")
        finally:
            probe.close()
        flat = flat_keys(keys)
        self.run.record(
            observations=flat,
            observation_keys=keys,
            privileged=any(k in privileged for k in flat),
            sb3_version=stable_baselines3.__version__,
        )

    def _build(self) -> None:
        """The vector environment and the model, new or loaded from the run."""
        from stable_baselines3.common.logger import Logger
        from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

        config = self.config
        thunk = partial(make_env, config.env, config.obs, config.env_options, config.action_repeat)
        vec = SubprocVecEnv if config.vec == "subproc" else DummyVecEnv
        self.venv = VecMonitor(vec([thunk] * config.n_envs))
        if config.vec == "subproc":
            self.children = {p.pid: 0.0 for p in self.venv.venv.processes}
        algorithm = config.algorithm()
        model_path = self.run.checkpoint_path
        try:
            if self.run.resumed:
                self.model = algorithm.load(model_path, env=self.venv, device="cpu")
                self.model._last_obs = None  # the new environments start new episodes
                replay = self.run.path / REPLAY
                if ALGORITHMS[config.algo] == "off" and replay.is_file():
                    self.model.load_replay_buffer(replay)
                print(f"resuming {model_path} at {plural(self.frames(), 'frame')}", file=sys.stderr)
            else:
                self.model = algorithm(
                    config.policy,
                    self.venv,
                    seed=config.seed,
                    device="cpu",
                    verbose=0,
                    **config.hyperparameters,
                )
        except (TypeError, ValueError, AssertionError) as exc:
            self._close()
            raise UsageError(f"{config.algo} refused the run: {exc}") from None
        # The run directory holds the logs (`_Callback`); SB3's own logger
        # would make an empty folder SB3-<date> in the temporary directory
        # at every `learn`.
        self.model.set_logger(Logger(folder=None, output_formats=[]))
        self.model.set_random_seed(_part_seed(config.seed, self.frames()))

    def frames(self) -> int:
        """The frames the model has trained on: its ``num_timesteps`` (the
        algorithm's steps) times ``action_repeat``."""
        assert self.model is not None
        return int(self.model.num_timesteps) * self.config.action_repeat

    def _learn(self) -> None:
        """``learn`` in segments, one per remaining ``save_at`` budget and the last."""
        config, model = self.config, self.model
        assert model is not None
        callback = _Callback(self)
        for target in [b for b in config.save_at if b > self.frames()] + [config.frames]:
            if self.frames() >= target:
                continue
            model.learn(
                -(-(target - self.frames()) // config.action_repeat),  # steps, rounded up
                callback=callback,
                reset_num_timesteps=False,
                progress_bar=False,
            )
            self.counters["frames"] = self.frames()
            callback.log()
            if self.run.stop_requested:
                print(
                    f"interrupted: saved at {plural(self.frames(), 'frame')}; run the "
                    f"same command to resume",
                    file=sys.stderr,
                )
                return
            if target in config.save_at:
                self._save(self.run.path / KEPT / f"frames-{target}.zip")

    def _save(self, path: Path) -> None:
        """The model at ``path`` (atomically) and its counters at ``path`` .json."""
        assert self.model is not None
        self.counters["frames"] = self.frames()
        buffer = io.BytesIO()
        self.model.save(buffer)
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda tmp: Path(tmp).write_bytes(buffer.getvalue()))
        write_json(path.with_suffix(".json"), self._result())

    def _save_replay(self) -> None:
        assert self.model is not None
        buffer = io.BytesIO()
        self.model.save_replay_buffer(buffer)
        atomic_write(self.run.path / REPLAY, lambda tmp: Path(tmp).write_bytes(buffer.getvalue()))

    def _result(self) -> dict:
        """The counters, with the last 100 episodes' mean return and success rate."""
        result = dict(self.counters)
        model = self.model
        if model is not None and model.ep_info_buffer:
            result["return"] = float(np.mean([e["r"] for e in model.ep_info_buffer]))
        if model is not None and model.ep_success_buffer:
            result["success_rate"] = float(np.mean(model.ep_success_buffer))
        return result

    def _close(self) -> None:
        if self.venv is not None:
            self.venv.close()
            self.venv = None


class _Callback(BaseCallback):
    """Counts episodes, logs scalars every `_LOG_S` s, prints progress every
    `_PROGRESS_S` s, and stops ``learn`` on a stop request."""

    def __init__(self, session: _Session):
        super().__init__()
        self.session = session
        self.last_log = self.last_print = time.perf_counter()
        self.frames_at_log = session.counters["frames"]

    def _on_step(self) -> bool:
        session = self.session
        session.counters["episodes"] += int(np.sum(self.locals.get("dones", 0)))
        session.counters["frames"] = session.frames()
        now = time.perf_counter()
        if now - self.last_log >= _LOG_S:
            self.log()
        if session.config.progress and now - self.last_print >= _PROGRESS_S:
            self.last_print = now
            result = session._result()
            print(
                f"{session.config.env} {session.config.algo}: "
                f"{result['frames']}/{session.config.frames} frames, "
                f"{result['episodes']} episodes, return {result.get('return', float('nan')):.2f}, "
                f"success {result.get('success_rate', float('nan')):.2f}",
                file=sys.stderr,
            )
        return not session.run.stop_requested

    def log(self) -> None:
        """One scalars row (`RunDir.log`) at the current frame count."""
        session, now = self.session, time.perf_counter()
        session.clock()
        result = session._result()
        fps = (result["frames"] - self.frames_at_log) / max(now - self.last_log, 1e-9)
        scalars = {
            "frames": result["frames"],
            "episodes/count": result["episodes"],
            "perf/frames_per_s": fps,
            "wall_s": result["wall_s"],
            "cpu_s": result["cpu_s"],
        }
        for key in ("return", "success_rate"):
            if key in result:
                scalars[f"episodes/{key}"] = result[key]
        session.run.log(result["frames"], scalars)
        self.last_log, self.frames_at_log = now, result["frames"]
