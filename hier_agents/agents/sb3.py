"""The ``sb3:PATH`` agent kind: a Stable-Baselines3 model played by the episode runner.

PATH is a run directory of ``python -m hier_agents.baselines.sb3`` (its
latest ``model.zip``) or one of its ``.zip`` files (``model.zip``,
``checkpoints/frames-B.zip``). The run's ``config.json`` says what the
policy reads; the agent builds that observation from each timestep with the
gymnasium wrapper's own conversion (`envs.gymnasium_env.convert_observation`
of the recorded ``observation_keys``), so it sees what the policy saw in
training, and passes ``model.predict``'s action to the environment as the
wrapper does (unchanged), held for the run's ``action_repeat`` control
steps as in training. A policy trained on ``obs="state"`` reads the
privileged abstract state: it plays with the simulator's observations and is
reported PRIVILEGED; the others play behind the observation boundary. The
``stochastic`` option samples the policy (seeded by each episode's seed)
instead of taking its deterministic action. The runs use no observation or
reward normalisation (no ``VecNormalize``), so the model alone is the policy.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from hier_agents.agents.base import AgentSetup, HeldAction, trained_setup, TrainedKind
from hier_agents.modular.agent import OptionStats
from physics_planning.cli import UsageError

__all__ = ["Sb3Agent", "Sb3Kind", "Sb3Run", "load_run"]


class Sb3Run:
    """A saved SB3 model and its run's facts.

    Attributes:
      model_path: the ``.zip`` file.
      config: the run's ``config.json`` (`Sb3Config` fields, ``observation_keys``,
        ``privileged``, ...).
      counters: the model's ``.json`` sidecar (``frames``, ``wall_s``, ...; empty
        when missing).
    """

    def __init__(self, model_path: Path, config: dict, counters: dict):
        self.model_path, self.config, self.counters = model_path, config, counters

    def env_overrides(self) -> dict:
        """The camera settings the run trained with (sizes as tuples; None: off),
        which the policy's observations need. Its other ``env_options``
        (``time_limit``, ...) were training choices: the played environment
        is the one named, unless the player's own options say otherwise."""
        options = self.config.get("env_options", {})
        return {
            k: tuple(v) if isinstance(v, list) else v
            for k, v in options.items()
            if k.endswith("_camera")
        }

    def keys(self):
        """The recorded `envs.gymnasium_env.observation_keys` (lists as tuples)."""
        keys = self.config["observation_keys"]
        return tuple(keys) if isinstance(keys, list) else keys

    def sha256(self) -> str:
        """The model file's content hash (a retrained model is a new comparison job)."""
        return hashlib.sha256(self.model_path.read_bytes()).hexdigest()


def load_run(path: str) -> Sb3Run:
    """The `Sb3Run` of ``path``: a run directory (its ``model.zip``) or a ``.zip``
    in it (``model.zip`` or ``checkpoints/frames-B.zip``).

    Raises:
      UsageError: nothing there, or not a model of ``python -m hier_agents.baselines.sb3``.
    """
    from hier_agents.baselines.sb3.trainer import MODEL

    given = Path(path)
    model = given / MODEL if given.is_dir() else given
    if not model.is_file():
        raise UsageError(
            f"--agent sb3:{path}: no {MODEL} in that directory"
            if given.is_dir()
            else f"--agent sb3:{path}: no SB3 model or run directory at {path!r}"
        )
    for folder in (model.parent, model.parent.parent):
        if (folder / "config.json").is_file():
            config = json.loads((folder / "config.json").read_text())
            break
    else:
        config = {}
    if "observation_keys" not in config or "algo" not in config:
        raise UsageError(
            f"--agent sb3:{path}: {str(model)!r} is not a model of python -m "
            f"hier_agents.baselines.sb3 (no run config.json beside it)"
        )
    sidecar = model.with_suffix(".json")
    counters = json.loads(sidecar.read_text()) if sidecar.is_file() else {}
    return Sb3Run(model, config, counters)


class Sb3Kind(TrainedKind):
    """A Stable-Baselines3 model (module docstring)."""

    name = "sb3"
    help = "a Stable-Baselines3 model: a python -m hier_agents.baselines.sb3 run directory or .zip"

    def check(self, env_name: str, arg, options: dict) -> None:
        _check_family(load_run(arg), env_name, arg)

    def setup(self, env_name: str, arg, options: dict) -> AgentSetup:
        run = load_run(arg)
        _check_family(run, env_name, arg)
        config, stochastic = run.config, bool(options.get("stochastic", False))
        privileged = bool(config.get("privileged", False))
        overrides = run.env_overrides()
        summary = {
            "condition": f"{config['algo']} {config.get('policy', '')}".strip()
            + (" (sampled)" if stochastic else ""),
            "algo": config["algo"],
            "trained_env": config["env"],
            "training_frames": int(run.counters.get("frames", 0)),
            "observations": list(config.get("observations", [])),
            "privileged": privileged,
        }

        def build(view, seed, simulator):
            return Sb3Agent(run, view, stochastic=stochastic)

        return trained_setup(overrides, summary, build)

    def job_inputs(self, env_name: str, arg, options: dict) -> dict:
        """``{"kind": "sb3", "arg": "sb3:PATH", the options, "model_sha256"}``:
        a model retrained at the same path is a new job."""
        return {
            "kind": self.name,
            "arg": self.form(arg),
            **options,
            "model_sha256": load_run(arg).sha256(),
        }

    def from_job_inputs(self, inputs: dict) -> tuple[object, dict]:
        arg = self.parse(str(inputs["arg"]).partition(":")[2])
        return arg, {k: inputs[k] for k in self.options if k in inputs}


def _check_family(run: Sb3Run, env_name: str, path: str) -> None:
    """UsageError when ``run`` was trained on another family than ``env_name``'s."""
    from hier_agents.modular.families import family

    trained = run.config["env"]
    if family(trained) != family(env_name):
        raise UsageError(
            f"sb3:{path} was trained on {trained!r}, a {family(trained)} environment; "
            f"cannot play {env_name!r}"
        )


class Sb3Agent:
    """An SB3 model acting on timesteps (the `hier_agents.agents.base.Agent` contract).

    Args:
      run: the model and its run (`load_run`).
      view: the environment as the agent sees it (its ``observation_spec()``;
        the simulator itself for a privileged run).
      stochastic: sample the policy instead of its deterministic action.

    Raises:
      UsageError: the environment lacks an observation the policy reads, or
        gives it another shape than the policy's.
    """

    estimates = False
    scene = None
    gave_up = None

    def __init__(self, run: Sb3Run, view, *, stochastic: bool = False):
        import stable_baselines3
        import torch

        torch.set_num_threads(1)
        algorithm = getattr(stable_baselines3, run.config["algo"])
        self.model = algorithm.load(run.model_path, device="cpu")
        self.keys = run.keys()
        _check_shapes(self.keys, view.observation_spec(), self.model.observation_space)
        self.privileged = bool(run.config.get("privileged", False))
        self.held = HeldAction(run.config.get("action_repeat", 1))
        self.training_frames = int(self.model.num_timesteps) * self.held.repeat
        self.stochastic = bool(stochastic)
        self.episode_stats = OptionStats()

    def observation(self, timestep):
        """The policy's observation of ``timestep`` (the gymnasium wrapper's)."""
        from envs.gymnasium_env import convert_observation

        return convert_observation(self.keys, timestep.observation)

    def reset(self, description, timestep, seed: int | None = None) -> None:
        self.held.reset()
        if self.stochastic:
            import torch

            torch.manual_seed(0 if seed is None else int(seed))

    def act(self, timestep) -> np.ndarray:
        held = self.held.next()
        if held is not None:
            return held
        action, _ = self.model.predict(
            self.observation(timestep), deterministic=not self.stochastic
        )
        return self.held.hold(np.asarray(action))

    def end_episode(self, timestep) -> None:
        pass

    def close(self) -> None:
        pass


def _check_shapes(keys, spec: dict, space) -> None:
    """UsageError unless ``spec`` has every key of ``keys`` with the shapes ``space`` expects."""
    from envs.gymnasium_env import flat_keys

    flat = flat_keys(keys)
    missing = [k for k in flat if k not in spec]
    if missing:
        raise UsageError(
            f"the environment does not give the observations {missing} the SB3 policy reads"
        )
    got: object
    want: object
    if isinstance(keys, dict):
        got = {name: tuple(spec[key].shape) for name, key in keys.items()}
        want = {name: tuple(space[name].shape) for name in keys}
    elif isinstance(keys, str):
        got, want = tuple(spec[keys].shape), tuple(space.shape)
    else:
        got = (sum(int(np.prod(spec[k].shape)) for k in keys),)
        want = tuple(space.shape)
    if not _same_shapes(got, want):
        raise UsageError(f"the environment gives observations of shape {got}, the policy {want}")


def _same_shapes(got: Any, want: Any) -> bool:
    """``got`` (the environment's) is ``want`` (the policy's), where SB3 may
    hold an image channel-first ((3, H, W) for an (H, W, 3) camera)."""
    if isinstance(got, dict):
        return got.keys() == want.keys() and all(_same_shapes(got[k], want[k]) for k in got)
    return got == want or (len(got) == 3 and want == (got[2], got[0], got[1]))
