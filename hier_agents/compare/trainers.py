"""The trainers a comparison trains end-to-end agents with: one table, `TRAINERS`.

A spec's trained agent has one trainer's table (its key names the trainer)
and ``budgets``::

    [[agent]]
    label = "e2e vanilla: state"
    train = { condition = "vanilla", observations = "proprio", state = true }   # IMPALA
    budgets = [250_000, 500_000, 1_000_000]

    [[agent]]
    label = "sb3 PPO: state"
    sb3 = { algo = "PPO", policy = "MlpPolicy", obs = "state", n_envs = 8 }  # Stable-Baselines3
    budgets = [250_000, 500_000]

A `Trainer` says, for its name, everything the plan and the jobs need:
which spec key holds its table, how a table becomes its checked config (the
trainer's ``from_options(env, options)`` with the planned keys ``frames``,
``seed``, ``logdir``, ``save_at``, ``no_progress``, ``env_options`` (the
environment's `envs.load` overrides) and the trainer's own ``fixed`` ones
added), how to train a config (``train(config) -> dict`` with
at least ``frames``), where its run directory keeps the checkpoint at a
budget (``checkpoints/frames-B`` + ``suffix``) and its latest, resumable
checkpoint, which agent kind plays a kept checkpoint
(``KIND:PATH``, `hier_agents.agents`), how many CPUs a training takes, and
whether the CPU seconds ``train`` returns span every resumed part of a run.
Nothing here imports a trainer until it is used.
"""

from __future__ import annotations

import importlib
import json
from dataclasses import dataclass, field
from pathlib import Path

from physics_planning import cli
from physics_planning.cli import UsageError

#: Option keys every trainer's plan sets itself (never a spec's table's:
#: ``env_options`` come from the spec's or the agent's ``env_options``).
PLANNED = ("frames", "seed", "logdir", "save_at", "no_progress", "env_options")


def _attr(path: str):
    """The object at ``"module:attribute"``."""
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


@dataclass(frozen=True)
class Trainer:
    """One trainer of `TRAINERS` (module docstring). Import paths are
    ``"module:attribute"`` strings, imported on use."""

    name: str
    table: str  # the spec agent's key holding the trainer's options
    config: str  # the config class, with ``from_options(env, options)``
    train_fn: str  # ``train(config) -> dict``
    suffix: str  # a kept checkpoint's file suffix
    latest: str  # the run directory's resumable checkpoint
    agent_kind: str  # the agent kind that plays a kept checkpoint (``KIND:PATH``)
    help: str
    options: str | None = None  # the allowed option keys (a mapping or sequence), if known
    planned: tuple = PLANNED  # keys the plan sets (refused in a spec)
    fixed: dict = field(default_factory=dict)  # planned options besides PLANNED
    cpus_key: str | None = None  # the option naming the CPUs a training takes
    cpus_default: int = 1
    serial: tuple = ()  # (option, value) pairs with which a training takes one CPU
    cpu_spans_resumes: bool = False  # train()'s ``cpu_s`` counts every resumed part
    #: ``(env, table, frames=, seed=, logdir=, save_at=, env_options=) -> argv``
    command: str | None = None

    def keys(self) -> tuple | None:
        """The option keys a spec may give (planned ones aside), or None when
        the trainer checks its own options only."""
        if self.options is None:
            return None
        return tuple(k for k in _attr(self.options) if k not in self.planned)

    def check_table(
        self, env: str, table: dict, budgets, where: str, env_options: dict | None = None
    ) -> None:
        """Checks a spec's table as the plan will use it (the largest budget,
        seed 0, every budget kept, the environment's ``env_options``).

        Raises:
          UsageError: one line, ``where``-prefixed, naming the key: a planned
            key, an unknown key (with the closest one), or anything the
            trainer's ``from_options`` refuses.
        """
        if not isinstance(table, dict):
            raise UsageError(f"{where}: {self.table} must be a table of {self.help} options")
        valid = self.keys()
        for key in table:
            if key == "env_options":
                raise UsageError(
                    f"{where}: {self.table}.env_options: give env_options beside "
                    f"{self.table} (the agent's) or at the spec's top (every agent's)"
                )
            if key in self.planned or key in self.fixed:
                raise UsageError(
                    f"{where}: {self.table}.{key} is set by the plan (budgets, seeds, "
                    f"the cache), not by the spec"
                )
            if valid is not None and key not in valid:
                raise UsageError(
                    f"{where}: {self.table}: unknown key {key!r}{cli.close_hint(key, valid)}; "
                    f"valid {self.help} options: {', '.join(sorted(valid))}"
                )
        try:
            self.make_config(
                env, table, frames=max(budgets), seed=0, save_at=budgets, env_options=env_options
            )
        except UsageError as exc:
            raise UsageError(f"{where}: {self.table}: {exc}") from None

    def make_config(
        self, env: str, table: dict, *, frames, seed, save_at, logdir=None, env_options=None
    ):
        """The trainer's checked config of ``table`` plus the planned keys
        (``env_options``: `envs.load` overrides of the trained environment).

        Raises:
          UsageError: the trainer refuses the options.
        """
        planned = {"frames": int(frames), "seed": int(seed), "save_at": sorted(save_at)}
        planned["no_progress"] = True
        if env_options:
            planned["env_options"] = dict(env_options)
        if logdir is not None:
            planned["logdir"] = str(logdir)
        return _attr(self.config).from_options(env, {**table, **self.fixed, **planned})

    def train(self, config) -> dict:
        """Trains (or resumes) ``config``'s run; the trainer's counters."""
        return dict(_attr(self.train_fn)(config))

    def checkpoint(self, run_dir: Path, budget: int) -> Path:
        """The kept checkpoint at ``budget`` frames of the run in ``run_dir``."""
        return Path(run_dir) / "checkpoints" / f"frames-{int(budget)}{self.suffix}"

    def kept_budgets(self, run_dir: Path) -> list[int]:
        """The budgets whose kept checkpoint is in ``run_dir``, ascending."""
        out = []
        for path in (Path(run_dir) / "checkpoints").glob(f"frames-*{self.suffix}"):
            digits = path.name[len("frames-") : -len(self.suffix)]
            if digits.isdigit():
                out.append(int(digits))
        return sorted(out)

    def frames_done(self, run_dir: Path) -> int:
        """How far the run in ``run_dir`` got: its last logged step
        (``scalars.jsonl``) or its largest kept budget, whichever is larger
        (0 without either)."""
        kept = self.kept_budgets(run_dir)
        return max([_last_step(Path(run_dir) / "scalars.jsonl")] + kept[-1:])

    def cpus(self, table: dict, available: int) -> int:
        """CPUs a training of ``table`` takes on a machine of ``available``."""
        serial = any(table.get(key) == value for key, value in self.serial)
        wanted = table.get(self.cpus_key, self.cpus_default) if self.cpus_key else 1
        wanted = 1 if serial else wanted
        return max(1, min(available, int(wanted)))

    def argv(self, env: str, table: dict, **planned) -> list[str] | None:
        """The command line that trains the same run, for a reader of a job's
        record (None when the trainer has no command of its own)."""
        if self.command is None:
            return None
        argv = list(_attr(self.command)(env, table, **planned)) + ["--no-progress"]
        for key, value in sorted(self.fixed.items()):
            text = f"{value:g}" if isinstance(value, float) else str(value)
            argv += [f"--{key.replace('_', '-')}", text]
        return argv

    def agent(self, path: Path) -> str:
        """The ``KIND:PATH`` agent that plays a kept checkpoint."""
        return f"{self.agent_kind}:{path}"


def _last_step(path: Path) -> int:
    """The ``step`` of a JSON-lines file's last complete line (0 without one)."""
    try:
        with open(path, "rb") as f:
            f.seek(0, 2)
            f.seek(max(0, f.tell() - 4096))
            lines = f.read().decode(errors="replace").splitlines()
    except OSError:
        return 0
    for line in reversed(lines):
        try:
            return int(json.loads(line).get("step", 0))
        except (ValueError, AttributeError):
            continue
    return 0


#: name -> trainer. The spec key of each is its ``table``.
TRAINERS = {
    t.name: t
    for t in (
        Trainer(
            name="impala",
            table="train",
            config="hier_agents.baselines.impala.config:TrainConfig",
            train_fn="hier_agents.baselines.impala.learner:train",
            suffix=".pt",
            latest="checkpoint.pt",
            agent_kind="checkpoint",
            help="python -m hier_agents.train",
            options="hier_agents.baselines.impala.config:OPTIONS",
            planned=PLANNED + ("backend", "ray_address", "keep_checkpoints"),
            fixed={"log_every": 30.0, "checkpoint_every": 120.0},
            cpus_key="actors",
            cpus_default=2,
            cpu_spans_resumes=True,
            command="hier_agents.compare.spec:train_argv",
        ),
        Trainer(
            name="sb3",
            table="sb3",
            config="hier_agents.baselines.sb3.config:Sb3Config",
            train_fn="hier_agents.baselines.sb3.trainer:train",
            suffix=".zip",  # with frames-B.json, its counters, beside it
            latest="model.zip",
            agent_kind="sb3",
            help="python -m hier_agents.baselines.sb3",
            options="hier_agents.baselines.sb3.config:OPTIONS",
            cpus_key="n_envs",
            cpus_default=8,
            serial=(("vec", "dummy"),),
            cpu_spans_resumes=True,
        ),
    )
}


def by_table(key: str) -> Trainer | None:
    """The trainer whose spec key is ``key``, or None."""
    return next((t for t in TRAINERS.values() if t.table == key), None)


def get(name: str) -> Trainer:
    """The trainer called ``name``.

    Raises:
      UsageError: no such trainer (the message lists them).
    """
    return TRAINERS[cli.choice("trainer", name, TRAINERS)]
