"""Experiment specs: a TOML file naming environments, agents, budgets, seeds and
episodes, checked and planned into jobs (`hier_agents.compare.jobs.Job`).

A spec (all keys but ``name`` and ``agent`` optional)::

    name = "mujoban"                      # names the cache folder and outputs
    description = "modular against end-to-end on MuJoBan levels 1 and 2"
    cache = "../results/compare/mujoban"  # relative to the spec file
    envs = ["mujoban/level1", "mujoban/level2"]
    seeds = [0, 1, 2]
    episodes = 100                        # evaluation episodes per seed and point
    shard_episodes = 50                   # episodes per evaluation job
    env_options = { sleep = false }       # envs.load overrides of every environment

    [[agent]]
    label = "modular: scripted"           # short: the table's and the plot's
    modular = {}                          # planner/skill/estimator (NAME[:ARG])

    [[agent]]
    label = "e2e vanilla: state"
    train = { condition = "vanilla", observations = "proprio", state = true }
    budgets = [250_000, 500_000, 1_000_000]

    [[agent]]
    label = "sb3 PPO: state"
    sb3 = { algo = "PPO", policy = "MlpPolicy", obs = "state", n_envs = 8 }
    budgets = [250_000, 500_000]

    [[agent]]
    label = "random, held 10"
    random = 10

    [[agent]]
    label = "my agent"
    agent = "my-kind:3"                   # any registered agent kind, NAME[:ARG]
    options = { depth = 2 }               # the kind's options

An agent has exactly one of ``agent`` (``NAME[:ARG]`` of an agent kind,
`hier_agents.agents.resolve`, with its ``options``), ``modular`` (a table of
``planner``, ``skill``, ``estimator``: `hier_agents.modular.components.resolve`
names; the same as ``agent = "modular"`` with those options), a trainer's
table with ``budgets`` (frame counts, each evaluated at the checkpoint kept
exactly there, `hier_agents.compare.trainers`; a list for every environment,
or a table giving each environment its own list, e.g.
``budgets = { "mujoban/level1" = [1_000_000, 5_000_000], "mujoban/level2" =
[1_000_000] }``): ``train`` (IMPALA: flags
of ``python -m hier_agents.train`` with ``_`` for ``-``, e.g.
``condition``, ``observations``, ``image_size``, ``state``, ``preset``,
``actors``, ``envs_per_actor``, ``batch_size``, ``learning_rate``) or
``sb3`` (Stable-Baselines3: ``algo``, ``policy``, ``obs``, ``n_envs``, ``action_repeat``,
``hyperparameters``; `hier_agents.baselines.sb3.Sb3Config`), neither
giving ``frames``, ``seed``, ``logdir``, ``save_at``, which the plan
sets; or ``random`` (the hold, control steps per draw; the same as
``agent = "random:HOLD"``). ``envs``, ``seeds``,
``episodes`` and ``env_options`` may be overridden per agent (an agent's
``env_options`` update the spec's). ``env_options`` (`envs.load` overrides,
checked on each of the agent's environments) apply to every job of the
agent: its trainings and its evaluations; a job names them as the settings
that differ from the original implementation's (`envs.deviations`), so a
spec pinned to the original's settings (``sleep = false`` for MuJoBan)
keeps its jobs' keys when a default changes. Seed
``s`` is an end-to-end run's training seed and, for every agent, the
evaluation seed: episode ``e`` of seed ``s`` is seeded from ``(s, e)``
(`envs.episode_seed`), so all agents meet the same levels at a seed.

Every error is a `physics_planning.cli.UsageError` naming the file, the agent and the key.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from hier_agents.compare import trainers
from physics_planning import cli
from physics_planning.cli import UsageError

#: Keys of a spec's top level and of an agent table.
TOP_KEYS = (
    "name",
    "description",
    "cache",
    "envs",
    "seeds",
    "episodes",
    "shard_episodes",
    "env_options",
    "agent",
)
AGENT_KEYS = (
    "label",
    "agent",
    "options",
    "modular",
    "train",
    "sb3",
    "budgets",
    "random",
    "envs",
    "seeds",
    "episodes",
    "env_options",
    "stochastic",
)
#: The keys that say what an agent is (exactly one per agent).
KIND_KEYS = ("agent", "modular", "train", "sb3", "random")
MODULAR_KEYS = ("planner", "skill", "estimator")


@dataclass(frozen=True)
class Agent:
    """One agent (series) of a spec. ``kind`` is ``"train"`` (an end-to-end
    agent trained by the plan: ``trainer``, a `hier_agents.compare.trainers`
    name, its table ``train`` and ``budgets``) or the agent kind
    (`hier_agents.agents`) of ``agent`` (``NAME[:ARG]``) with its
    ``options``."""

    label: str
    kind: str
    envs: tuple
    seeds: tuple
    episodes: int
    agent: str = ""
    options: dict = field(default_factory=dict)
    train: dict = field(default_factory=dict)
    trainer: str = ""
    budgets: tuple = ()
    stochastic: bool = False
    env_budgets: dict = field(default_factory=dict)
    env_options: dict = field(default_factory=dict)

    def budgets_for(self, env: str) -> tuple:
        """A trained agent's budgets on ``env`` (ascending; ``budgets`` unless the
        spec gave that environment its own list); ``(None,)`` for an agent the
        plan does not train (one point per environment)."""
        if self.kind != "train":
            return (None,)
        return tuple(self.env_budgets.get(env, self.budgets))

    def deviations(self, env: str) -> dict:
        """The settings of ``env`` under the agent's ``env_options`` that
        differ from the original implementation's (`envs.deviations`): what
        its jobs on ``env`` name."""
        import envs

        return envs.deviations(env, self.env_options)

    @property
    def modular(self) -> dict:
        """A modular agent's parts (its options)."""
        return dict(self.options) if self.kind == "modular" else {}


@dataclass(frozen=True)
class Spec:
    """A checked experiment spec (`load`)."""

    name: str
    description: str
    path: Path
    cache: Path
    shard_episodes: int
    agents: tuple
    raw: dict

    @property
    def envs(self) -> list[str]:
        """Every environment of the spec, in first-mention order."""
        out: list[str] = []
        for agent in self.agents:
            out.extend(e for e in agent.envs if e not in out)
        return out


def _where(path, agent=None) -> str:
    return f"{path}" + (f", agent {agent!r}" if agent else "")


def _unknown(keys, allowed, where: str) -> None:
    for key in keys:
        if key not in allowed:
            raise UsageError(
                f"{where}: unknown key {key!r}{cli.close_hint(key, allowed)}; "
                f"allowed: {', '.join(allowed)}"
            )


def _ints(value, what: str, where: str, minimum: int) -> tuple:
    values = value if isinstance(value, list) else [value]
    if not values or any(
        isinstance(v, bool) or not isinstance(v, int) or v < minimum for v in values
    ):
        raise UsageError(f"{where}: {what} must be integers >= {minimum} (a list), got {value!r}")
    if len(set(values)) != len(values):
        raise UsageError(f"{where}: {what} repeats a value: {value!r}")
    return tuple(values)


def _int(value, what: str, where: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise UsageError(f"{where}: {what} must be an integer >= {minimum}, got {value!r}")
    return value


def _table(value, what: str, where: str) -> dict:
    if not isinstance(value, dict):
        raise UsageError(f"{where}: {what} must be a table, got {value!r}")
    return dict(value)


def _env_options(options: dict, envs: tuple, at: str) -> dict:
    """``options`` checked as `envs.load` overrides of each of ``envs``."""
    from envs.cli import checked_options

    for env in envs:
        checked_options(env, options, f"{at}: env_options on {env}")
    return options


def _envs(value, where: str) -> tuple:
    import envs as registry

    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not value:
        raise UsageError(f"{where}: envs must be a list of environment names, got {value!r}")
    for name in value:
        try:
            cli.choice("environment", name, registry.names())
        except UsageError as exc:
            raise UsageError(f"{where}: {exc}") from None
    return tuple(value)


def train_argv(
    env: str,
    train: dict,
    *,
    frames: int | None = None,
    seed: int | None = None,
    logdir: str | None = None,
    save_at=(),
    env_options=None,
) -> list[str]:
    """The ``python -m hier_agents.train`` arguments of a ``train`` table
    (``True`` values become bare flags, ``False`` ones are left out), plus the
    planned ``frames``, ``seed``, ``logdir``, ``save_at`` and ``env_options``
    (``--env-option KEY=VALUE``, VALUE a Python literal)."""
    argv = [env]
    for key in sorted(train):
        value = train[key]
        flag = "--" + key.replace("_", "-")
        if value is True:
            argv.append(flag)
        elif value is not False:
            argv += [flag, str(value)]
    if frames is not None:
        argv += ["--frames", str(frames)]
    if seed is not None:
        argv += ["--seed", str(seed)]
    if logdir is not None:
        argv += ["--logdir", str(logdir)]
    if save_at:
        argv += ["--save-at", *map(str, save_at)]
    for key, value in sorted((env_options or {}).items()):
        argv += ["--env-option", f"{key}={value!r}"]
    return argv


def load(path: str | Path) -> Spec:
    """Reads and checks a spec file.

    Raises:
      UsageError: the file is missing or not TOML, a key is unknown, a value
        is out of range, an agent, component, environment or train flag is
        invalid, or two agents share a label.
    """
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise UsageError(f"no spec file at {path}") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise UsageError(f"{path}: not a readable TOML spec: {exc}") from None
    where = _where(path)
    _unknown(raw, TOP_KEYS, where)
    name = raw.get("name")
    if not isinstance(name, str) or not name or "/" in name:
        raise UsageError(f"{where}: name must be a non-empty string without '/', got {name!r}")
    defaults = {
        "envs": _envs(raw["envs"], where) if "envs" in raw else None,
        "seeds": _ints(raw.get("seeds", [0]), "seeds", where, 0),
        "episodes": _int(raw.get("episodes", 100), "episodes", where, 1),
        "env_options": _table(raw.get("env_options", {}), "env_options", where),
    }
    shard = _int(raw.get("shard_episodes", 50), "shard_episodes", where, 1)
    tables = raw.get("agent")
    if not isinstance(tables, list) or not tables:
        raise UsageError(f"{where}: give at least one [[agent]] table")
    agents, labels = [], set()
    for i, table in enumerate(tables):
        agent = _agent(path, i, table, defaults)
        if agent.label in labels:
            raise UsageError(f"{where}: two agents are labelled {agent.label!r}")
        labels.add(agent.label)
        agents.append(agent)
    cache = raw.get("cache")
    if cache is not None and not isinstance(cache, str):
        raise UsageError(f"{where}: cache must be a path (a string)")
    cache_path = (path.parent / cache) if cache else Path("runs") / "compare" / name
    return Spec(
        name=name,
        description=str(raw.get("description", "")),
        path=path,
        cache=cache_path,
        shard_episodes=shard,
        agents=tuple(agents),
        raw=raw,
    )


def _agent(path: Path, i: int, table, defaults: dict) -> Agent:
    """The `Agent` of the ``i``-th ``[[agent]]`` table (``defaults``: the
    spec's envs, seeds and episodes)."""
    where = _where(path)
    if not isinstance(table, dict):
        raise UsageError(f"{where}: agent {i + 1} is not a table")
    label = table.get("label")
    if not isinstance(label, str) or not label.strip():
        raise UsageError(f"{where}: agent {i + 1} needs a label (a short name)")
    at = _where(path, label)
    _unknown(table, AGENT_KEYS, at)
    kinds = [k for k in KIND_KEYS if k in table]
    if len(kinds) != 1:
        raise UsageError(
            f"{at}: give exactly one of {', '.join(KIND_KEYS)}; got {', '.join(kinds) or 'none'}"
        )
    envs = _envs(table["envs"], at) if "envs" in table else defaults["envs"]
    if envs is None:
        raise UsageError(f"{at}: no envs (give envs at the top or in the agent)")
    common = dict(
        label=label,
        envs=envs,
        seeds=_ints(table["seeds"], "seeds", at, 0) if "seeds" in table else defaults["seeds"],
        episodes=(
            _int(table["episodes"], "episodes", at, 1)
            if "episodes" in table
            else defaults["episodes"]
        ),
    )
    options = {**defaults["env_options"], **_table(table.get("env_options", {}), "env_options", at)}
    common["env_options"] = _env_options(options, envs, at)
    trainer = trainers.by_table(kinds[0])
    for key in ("budgets", "stochastic"):
        if key in table and trainer is None:
            raise UsageError(
                f"{at}: {key} applies to trained agents only "
                f"({', '.join(t.table for t in trainers.TRAINERS.values())})"
            )
    if trainer is not None:
        return _train_agent(trainer, table, at, common)
    if "options" in table and kinds[0] != "agent":
        raise UsageError(f'{at}: options go with agent = "NAME[:ARG]"')
    if kinds[0] == "modular":
        if not isinstance(table["modular"], dict):
            raise UsageError(f"{at}: modular must be a table of planner/skill/estimator")
        _unknown(table["modular"], MODULAR_KEYS, f"{at}, modular")
        name, options = "modular", dict(table["modular"])
    elif kinds[0] == "random":
        name, options = f"random:{_int(table['random'], 'random (the hold)', at, 1)}", {}
    else:
        name, options = table["agent"], table.get("options", {})
        if not isinstance(name, str) or not isinstance(options, dict):
            raise UsageError(f"{at}: agent must be a string NAME[:ARG] and options a table")
    return _named_agent(name, dict(options), at, common)


def _named_agent(name: str, options: dict, at: str, common: dict) -> Agent:
    """An agent of a registered kind, checked on every environment of the series."""
    from hier_agents.agents import resolve

    try:
        kind, arg = resolve(name)
    except UsageError as exc:
        raise UsageError(f"{at}: {exc}") from None
    _unknown(options, kind.options, f"{at}, options")
    for env in common["envs"]:
        try:
            kind.check(env, arg, options)
        except (UsageError, ValueError, FileNotFoundError) as exc:
            raise UsageError(f"{at}: {env}: {exc}") from None
    return Agent(kind=kind.name, agent=name, options=options, **common)


def _train_agent(trainer, table: dict, at: str, common: dict) -> Agent:
    """An end-to-end agent the plan trains with ``trainer`` (its table and
    ``budgets``), the table checked on every environment of the series."""
    options = table[trainer.table]
    if "budgets" not in table:
        raise UsageError(f"{at}: a trained agent needs budgets (frame counts to evaluate at)")
    budgets, env_budgets = _budgets(table["budgets"], common["envs"], at)
    for env in common["envs"]:
        trainer.check_table(env, options, env_budgets.get(env, budgets), at, common["env_options"])
    stochastic = table.get("stochastic", False)
    if not isinstance(stochastic, bool):
        raise UsageError(f"{at}: stochastic must be true or false")
    return Agent(
        kind="train",
        trainer=trainer.name,
        train=dict(options),
        budgets=budgets,
        stochastic=stochastic,
        env_budgets=env_budgets,
        **common,
    )


def _budgets(value, envs: tuple, at: str) -> tuple[tuple, dict]:
    """``(budgets, env_budgets)`` of a ``budgets`` value: a list of frame
    counts for every environment, or a table giving each of the agent's
    environments its own list (``budgets`` is then the union)."""
    if not isinstance(value, dict):
        return tuple(sorted(_ints(value, "budgets", at, 1))), {}
    _unknown(value, envs, f"{at}, budgets")
    missing = [env for env in envs if env not in value]
    if missing:
        raise UsageError(f"{at}: budgets gives no list for {', '.join(missing)}")
    per_env = {env: tuple(sorted(_ints(value[env], f"budgets of {env}", at, 1))) for env in envs}
    return tuple(sorted({b for bs in per_env.values() for b in bs})), per_env
