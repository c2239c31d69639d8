"""`Sb3Config`: everything a Stable-Baselines3 training run depends on, in one
typed form from the command line (``python -m hier_agents.baselines.sb3``) or
a comparison spec's ``sb3`` table.

`Sb3Config.from_options(env, options)` is the one way in: ``options`` maps
the command's flags, with ``_`` for ``-`` (`OPTIONS`), to values; missing
ones take the defaults (``policy`` and ``env_options`` depend on ``obs``),
and the result is checked once (`Sb3Config.validate`) before anything is
built.
"""

from __future__ import annotations

import dataclasses
import inspect

from physics_planning.cli import UsageError, choice, close_hint, plural

__all__ = ["ALGORITHMS", "OBSERVATIONS", "OPTIONS", "POLICIES", "Sb3Config"]

#: ``algo`` values: SB3 class names; on-policy ones collect ``n_steps`` per
#: environment between updates, off-policy ones ``train_freq`` steps.
ALGORITHMS = {"PPO": "on", "A2C": "on", "SAC": "off", "TD3": "off"}
#: ``obs`` values (`envs.gymnasium_env.OBSERVATIONS`' choices SB3 policies take).
OBSERVATIONS = ("state", "sensors", "pixels")
#: The default policy of each ``obs``.
POLICIES = {"state": "MlpPolicy", "sensors": "MultiInputPolicy", "pixels": "CnnPolicy"}
#: Options (flags with ``_`` for ``-``) -> (type, its name in messages).
OPTIONS = {
    "algo": (str, "a string"),
    "policy": (str, "a string"),
    "obs": (str, "a string"),
    "n_envs": (int, "an integer"),
    "action_repeat": (int, "an integer"),
    "vec": (str, "a string"),
    "env_options": (dict, "a table"),
    "hyperparameters": (dict, "a table"),
    "frames": (int, "an integer"),
    "seed": (int, "an integer"),
    "logdir": (str, "a string"),
    "save_at": (tuple, "a list of integers"),
    "no_progress": (bool, "true or false"),
}
#: Constructor arguments `train` sets itself (not ``hyperparameters``).
_RESERVED = (
    "self",
    "policy",
    "env",
    "seed",
    "verbose",
    "device",
    "tensorboard_log",
    "_init_setup_model",
)


@dataclasses.dataclass
class Sb3Config:
    """A Stable-Baselines3 training run (saved in its ``config.json``).

    Attributes:
      env: an `envs.names()` environment.
      algo: one of `ALGORITHMS`.
      policy: an SB3 policy name (default: `POLICIES` of ``obs``).
      obs: the gymnasium observation (`envs.gymnasium_env.OBSERVATIONS`);
        ``"state"`` reads the task's privileged abstract state.
      n_envs: environments stepped together; vec: ``"subproc"`` (one
        process each) or ``"dummy"`` (in this process).
      action_repeat: control steps each of the algorithm's steps holds its
        action for (`envs.gymnasium_env.ActionRepeat`; 1: none). SB3's
        ``num_timesteps`` counts the algorithm's steps; frames are that
        times ``action_repeat``, as for the IMPALA agent.
      env_options: `envs.load` overrides (default for ``obs="state"``: every
        camera off; ``"pixels"``: every camera but the main one off).
      hyperparameters: keyword arguments of the algorithm's constructor.
      frames: the budget, environment frames (control steps summed over the
        environments); met exactly when a multiple of `granularity`, else
        overshot by less than one collection.
      seed: seeds the algorithm and the environments (environment ``i`` of a
        run part starting at frame ``F`` gets a seed drawn from (seed, F) plus i).
      logdir: the run directory; save_at: frame counts with a kept
        checkpoint ``checkpoints/frames-B.zip`` each (multiples of
        `granularity`, at most ``frames``).
      progress: a stderr line every ~30 s.
    """

    env: str
    algo: str = "PPO"
    policy: str = ""
    obs: str = "state"
    n_envs: int = 8
    action_repeat: int = 1
    vec: str = "subproc"
    env_options: dict = dataclasses.field(default_factory=dict)
    hyperparameters: dict = dataclasses.field(default_factory=dict)
    frames: int = 1_000_000
    seed: int = 0
    logdir: str = "runs/sb3"
    save_at: tuple = ()
    progress: bool = True

    @classmethod
    def from_options(cls, env: str, options: dict) -> Sb3Config:
        """The checked config of ``options`` (`OPTIONS` keys; None values
        and missing keys take the defaults).

        Raises:
          UsageError: an unknown option (naming the closest), a value of the
            wrong type, or anything `validate` refuses.
        """
        options = {k: v for k, v in options.items() if v is not None}
        for key, value in options.items():
            choice("option", key, OPTIONS)
            _check_type(key, value)
        fields = {k: v for k, v in options.items() if k != "no_progress"}
        if "save_at" in fields:
            fields["save_at"] = tuple(sorted({int(b) for b in fields["save_at"]}))
        config = cls(env=env, progress=not options.get("no_progress", False), **fields)
        config.env_options = dict(config.env_options)
        config.hyperparameters = dict(config.hyperparameters)
        config.validate()
        return config

    def algorithm(self):
        """The SB3 algorithm class of ``algo``."""
        import stable_baselines3

        return getattr(stable_baselines3, self.algo)

    def granularity(self) -> int:
        """Frames between two points where training can stop: one rollout
        (``n_steps`` x ``n_envs`` x ``action_repeat``) on-policy, one
        collection (``train_freq`` x ``n_envs`` x ``action_repeat``)
        off-policy."""
        defaults = _constructor_defaults(self.algorithm())
        name = "n_steps" if ALGORITHMS[self.algo] == "on" else "train_freq"
        steps = self.hyperparameters.get(name, defaults[name])
        return int(steps) * self.n_envs * self.action_repeat

    def validate(self) -> None:
        """Checks the configuration without building anything.

        Raises:
          UsageError: an unknown environment, algorithm, obs, policy, vec,
            hyperparameter or environment option (naming the closest valid
            one); a policy that cannot read ``obs``; a count below 1; a
            budget below one collection; a ``save_at`` budget that training
            cannot stop at (not a multiple of `granularity`, or beyond
            ``frames``).
        """
        import envs

        choice("environment", self.env, envs.names())
        choice("algo", self.algo, ALGORITHMS)
        choice("obs", self.obs, OBSERVATIONS)
        choice("vec", self.vec, ("subproc", "dummy"))
        self.policy = choice("policy", self.policy or POLICIES[self.obs], POLICIES.values())
        if (self.obs == "sensors") != (self.policy == "MultiInputPolicy"):
            raise UsageError(
                f"policy {self.policy!r} cannot read obs={self.obs!r} "
                f"({'a Dict' if self.obs == 'sensors' else 'an array'}); "
                f"use {POLICIES[self.obs]!r}"
            )
        for name in ("n_envs", "action_repeat", "frames"):
            if int(getattr(self, name)) < 1:
                raise UsageError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        if self.seed < 0:
            raise UsageError(f"seed must be >= 0, got {self.seed!r}")
        self._check_hyperparameters()
        self._check_env_options()
        self._check_budgets()

    def _check_hyperparameters(self) -> None:
        """Every ``hyperparameters`` name is the constructor's (UsageError naming the closest)."""
        valid = _constructor_defaults(self.algorithm())
        for name in self.hyperparameters:
            if name not in valid:
                raise UsageError(
                    f"{self.algo} has no hyperparameter {name!r}{close_hint(name, valid)}; "
                    f"valid: {', '.join(valid)}"
                )
        if ALGORITHMS[self.algo] == "off":
            freq = self.hyperparameters.get("train_freq", 1)
            if not isinstance(freq, int) or isinstance(freq, bool) or freq < 1:
                raise UsageError(
                    f"train_freq must be an integer >= 1 (control steps per collection), "
                    f"got {freq!r}"
                )
        elif "n_steps" in self.hyperparameters:
            steps = self.hyperparameters["n_steps"]
            if not isinstance(steps, int) or isinstance(steps, bool) or steps < 1:
                raise UsageError(f"n_steps must be an integer >= 1, got {steps!r}")

    def _check_env_options(self) -> None:
        """Fills the per-``obs`` camera defaults and checks the options (`envs.check`)."""
        import envs
        from envs.cli import checked_options

        defaults: dict = {}
        if self.obs == "state":
            defaults = dict(envs.no_cameras(self.env))
        elif self.obs == "pixels":
            from hier_agents.baselines.impala.agent_env import main_camera_only

            defaults = dict(main_camera_only(self.env))
        self.env_options = checked_options(
            self.env, {**defaults, **self.env_options}, "env_options"
        )

    def _check_budgets(self) -> None:
        """``frames`` is at least one collection; each ``save_at`` a reachable stop."""
        step = self.granularity()
        unit = "one rollout" if ALGORITHMS[self.algo] == "on" else "one collection"
        if self.frames < step:
            raise UsageError(
                f"a budget of {plural(self.frames, 'frame')} is less than {unit} of "
                f"{plural(step, 'frame')} ({self.n_envs} envs): give frames >= {step} "
                f"or fewer steps per collection"
            )
        for budget in self.save_at:
            if int(budget) < 1 or int(budget) > self.frames or int(budget) % step:
                raise UsageError(
                    f"save_at {budget!r}: each must be a multiple of {unit} "
                    f"({plural(step, 'frame')}) within the budget ({self.frames} frames)"
                )


def _constructor_defaults(algorithm) -> dict:
    """The algorithm constructor's keyword arguments -> defaults, but `_RESERVED`."""
    params = inspect.signature(algorithm.__init__).parameters
    return {n: p.default for n, p in params.items() if n not in _RESERVED}


def _check_type(key: str, value) -> None:
    kind, name = OPTIONS[key]
    if kind is tuple:
        ok = isinstance(value, (list, tuple)) and all(
            isinstance(v, int) and not isinstance(v, bool) for v in value
        )
    elif kind is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    else:
        ok = isinstance(value, kind)
    if not ok:
        raise UsageError(f"{key} must be {name}, got {value!r}")
