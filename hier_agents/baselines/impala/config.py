"""`TrainConfig`: everything an IMPALA training run depends on, in one typed
form from the command line (`hier_agents.train`) or a comparison spec's
``train`` table (`hier_agents.compare.spec`) to the learner and its actors.

`TrainConfig.from_options(env, options)` is the one way in: ``options`` maps
``python -m hier_agents.train`` flags, with ``_`` for ``-`` (``frames``,
``observations``, ``preset``, ``envs_per_actor``, ...), to values; a
``preset`` sets the defaults the other options override, ``observations``
becomes ``cameras`` and ``env_overrides``, and the result is checked once
(`TrainConfig.validate`). The argv parser hands its parsed flags to it, a
spec its table, so both give equal configs for the same options.
"""

from __future__ import annotations

import dataclasses

from physics_planning.cli import UsageError, choice, plural
from hier_agents.modular.options import T_ABS

#: ``observations`` values.
OBSERVATIONS = ("cameras", "main-camera", "proprio")
#: ``preset`` values: option defaults they replace (explicit options still win).
#: ``small-batches``: updates of 16 unrolls of 20 steps (320 frames) instead of
#: the paper's 128 (MuJoBan) or 64 (board games) of 100 steps, so a budget of a
#: few hundred thousand frames makes hundreds of updates, not a few dozen
#: (measured in docs/results/comparison.md, "Tuning the end-to-end agent").
PRESETS: dict[str, dict[str, object]] = {
    "cpu": {"observations": "main-camera", "image_size": 48, "envs_per_actor": 8},
    "small-batches": {"unroll_length": 20, "batch_size": 16},
}
#: ``optimizer`` values: the paper's RMSProp, or Adam (``adam_eps``, PyTorch's
#: betas), the optimiser of most PPO implementations.
OPTIMIZERS = ("rmsprop", "adam")
#: Options (flags with ``_`` for ``-``) -> (`TrainConfig` field, type); ``None``
#: for the options `from_options` turns into other fields.
OPTIONS = {
    "condition": ("condition", str),
    "frames": ("steps", int),
    "env_options": ("env_overrides", dict),
    "observations": (None, str),
    "image_size": ("image_size", int),
    "state": ("state", bool),
    "state_channels": ("state_channels", int),
    "preset": (None, str),
    "actors": ("actors", int),
    "envs_per_actor": ("envs_per_actor", int),
    "env_threads": ("env_threads", int),
    "backend": ("backend", str),
    "ray_address": ("ray_address", str),
    "logdir": ("logdir", str),
    "unroll_length": ("unroll_length", int),
    "action_repeat": ("action_repeat", int),
    "batch_size": ("batch_size", int),
    "passes": ("passes", int),
    "learning_rate": ("learning_rate", float),
    "optimizer": ("optimizer", str),
    "normalize_advantages": ("normalize_advantages", bool),
    "clip_ratio": ("clip_ratio", float),
    "entropy_cost": ("entropy_cost", float),
    "abs_reward": ("abs_reward", float),
    "seed": ("seed", int),
    "checkpoint_every": ("checkpoint_every_s", float),
    "keep_checkpoints": ("keep_checkpoints", bool),
    "save_at": ("save_at", tuple),
    "log_every": ("log_every_s", float),
    "no_progress": (None, bool),
}


@dataclasses.dataclass
class TrainConfig:
    """Everything a training run depends on (saved in ``config.json`` and its checkpoint).

    Observations: proprioception always; ``cameras`` the paper's camera views
    (``image_size`` squared); ``env_overrides`` (``env_options`` of
    `from_options`, ``--env-option``) are the actors' `envs.load` overrides
    and may turn views off (`main_camera_only`); ``state`` the current
    abstract state (privileged);
    the planner conditions add the planner's planes (see `AgentEnv`).
    ``steps`` is the frame budget (`hier_agents.baselines.impala.learner`):
    control steps, ``frames_per_unroll`` per unroll (an action held
    ``action_repeat`` times counts that many frames, also when an episode's
    end cuts the hold short).
    The actors get it as it is, with ``seed`` their own (`actor_config`).
    """

    env: str
    condition: str = "vanilla"
    steps: int = 1_000_000
    actors: int = 2
    envs_per_actor: int = 32  # 2 x 32 beat 2 x 16 and 1 x 32 in benchmarks/learner_speed.py
    env_threads: int = 1  # threads an actor advances its environments' physics on (envs.vector)
    backend: str = "local"
    ray_address: str | None = None
    logdir: str = "runs/impala"
    unroll_length: int = 100  # agent steps per unroll
    action_repeat: int = 1  # control steps each action is held for (the paper's 1)
    batch_size: int | None = None  # None: the paper's (64 board games, 128 MuJoBan)
    passes: int = 1  # gradient steps on each batch (the paper's: 1)
    learning_rate: float = 3e-4
    optimizer: str = "rmsprop"  # one of `OPTIMIZERS` (the paper's: RMSProp)
    normalize_advantages: bool = False  # advantages to mean 0, std 1 per batch
    clip_ratio: float = 0.0  # > 0: the clipped surrogate with this epsilon (0: off)
    adam_eps: float = 1e-5
    rmsprop_alpha: float = 0.99
    rmsprop_eps: float = 1e-5
    rmsprop_momentum: float = 0.0
    grad_clip: float = 40.0
    baseline_cost: float = 0.5
    entropy_cost: float = 1e-3
    cameras: bool = True
    image_size: int = 96
    state: bool = False  # observe the current abstract state (AgentEnv(state=True))
    state_channels: int = 100  # the state encoder's conv channels (the planner encoder's)
    t_abs: int = T_ABS
    abs_reward: float = 1.0
    seed: int = 0
    checkpoint_every_s: float = 300.0
    keep_checkpoints: bool = False
    save_at: tuple = ()  # frame counts at which a kept checkpoint frames-N.pt is saved
    log_every_s: float = 10.0
    progress: bool = True
    env_overrides: dict = dataclasses.field(default_factory=dict)

    @classmethod
    def from_options(cls, env: str, options: dict) -> TrainConfig:
        """The checked config of ``options`` (`OPTIONS` keys; missing ones
        take the preset's, then the defaults).

        Raises:
          UsageError: an unknown option (with the closest one), a value of
            the wrong type, an unknown preset or observations value, or
            anything `validate` refuses.
        """
        options = {k: v for k, v in options.items() if v is not None}
        for key, value in options.items():
            choice("option", key, OPTIONS)
            _check_type(key, value, OPTIONS[key][1])
        if "preset" in options:
            options = {**PRESETS[choice("preset", options["preset"], PRESETS)], **options}
        observations = choice(
            "observations value", options.get("observations", "cameras"), OBSERVATIONS
        )
        fields = {attr: v for k, v in options.items() if (attr := OPTIONS[k][0]) is not None}
        fields["save_at"] = tuple(sorted({int(b) for b in fields.get("save_at", ())}))
        fields["env_overrides"] = dict(fields.get("env_overrides", {}))
        config = cls(
            env=env,
            cameras=observations != "proprio",
            progress=not options.get("no_progress", False),
            **fields,
        )
        config.validate()
        if observations == "main-camera":
            from hier_agents.baselines.impala.agent_env import main_camera_only

            config.env_overrides.update(main_camera_only(env))
        return config

    def validate(self) -> None:
        """Checks the configuration without building anything.

        Raises:
          UsageError: an unknown environment, condition or backend (with the
            closest valid name), a count below 1, a seed below 0, a rate or
            period out of range, a clip ratio of 1 or more, a budget
            (``steps``) below one unroll, or an environment override
            (``env_overrides``) the environment refuses.
        """
        import envs
        from envs.cli import checked_options
        from hier_agents.baselines.impala.agent_env import CONDITIONS

        choice("environment", self.env, envs.names())
        checked_options(self.env, self.env_overrides, "env_options")
        choice("condition", self.condition, CONDITIONS)
        choice("backend", self.backend, ("local", "ray"))
        choice("optimizer", self.optimizer, OPTIMIZERS)
        for name in (
            "steps",
            "actors",
            "envs_per_actor",
            "env_threads",
            "unroll_length",
            "image_size",
            "t_abs",
            "passes",
            "state_channels",
            "action_repeat",
        ):
            if int(getattr(self, name)) < 1:
                raise UsageError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        if self.batch_size is not None and self.batch_size < 1:
            raise UsageError(f"batch_size must be >= 1, got {self.batch_size!r}")
        for name, low, strict in (
            ("seed", 0, False),
            ("learning_rate", 0, True),
            ("entropy_cost", 0, False),
            ("clip_ratio", 0, False),
            ("abs_reward", 0, False),
            ("checkpoint_every_s", 0, False),  # 0: a checkpoint after every update
            ("log_every_s", 0, False),
        ):
            value = getattr(self, name)
            if value < low or (strict and value == low):
                raise UsageError(f"{name} must be {'>' if strict else '>='} {low}, got {value!r}")
        if self.clip_ratio >= 1:
            raise UsageError(f"clip_ratio must be < 1 (0: off), got {self.clip_ratio!r}")
        unroll = self.frames_per_unroll
        for budget in self.save_at:
            if int(budget) < 1 or int(budget) > self.steps or int(budget) % unroll:
                raise UsageError(
                    f"save_at {budget!r}: each must be a multiple of the frames "
                    f"of one unroll ({unroll}) within the budget "
                    f"({self.steps} frames)"
                )
        if self.steps < unroll:
            raise UsageError(
                f"a budget of {plural(self.steps, 'frame')} is less than one unroll "
                f"of {plural(unroll, 'frame')}: give --frames >= "
                f"{unroll} or a shorter --unroll-length"
            )

    @property
    def frames_per_unroll(self) -> int:
        """Control steps one unroll counts: ``unroll_length * action_repeat``."""
        return int(self.unroll_length) * int(self.action_repeat)

    def resolved_batch(self) -> int:
        """Unrolls per update: ``batch_size``, or the paper's for the
        environment's family (its adapter's ``paper_batch``)."""
        from hier_agents.modular.families import adapter

        return int(self.batch_size or adapter(self.env).paper_batch)

    def actor_config(self, updates: int) -> TrainConfig:
        """The config the actors get after ``updates`` updates: this one with
        ``seed`` ``seed * 1000 + updates`` (a resumed run's actors meet new
        episodes)."""
        return dataclasses.replace(
            self, seed=self.seed * 1000 + updates, env_overrides=dict(self.env_overrides)
        )


def _check_type(key: str, value, kind) -> None:
    if kind is tuple:
        ok = isinstance(value, (list, tuple)) and all(
            isinstance(v, int) and not isinstance(v, bool) for v in value
        )
    elif kind is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    elif kind is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    else:
        ok = isinstance(value, kind)
    if not ok:
        names = {
            str: "a string",
            int: "an integer",
            float: "a number",
            bool: "true or false",
            tuple: "a list of integers",
            dict: "a table",
        }
        raise UsageError(f"{key} must be {names[kind]}, got {value!r}")
