"""The agent contract and the agent kinds' base class.

Every agent, whatever its kind, keeps one contract (`Agent`): it is reset
with the task's public description and the episode's first timestep, acts on
timesteps, is shown the episode's last timestep, and is closed; it says
whether it is privileged and how many environment frames trained it. The one
episode runner (`hier_agents.agents.runner`) plays any of them.

An **agent kind** (`AgentKind`) names a way of building agents, as a
planner, skill or estimator name does a component: ``NAME`` or ``NAME:ARG``
(`hier_agents.agents.registry.resolve`), the same grammar in ``python -m
hier_agents.run --agent``, in comparison specs (``agent = "NAME:ARG"``) and
in code. The kinds shipped are ``modular``, ``checkpoint:PATH``,
``sb3:PATH`` and ``random[:HOLD]``
(`hier_agents.agents.kinds`); `hier_agents.agents.registry.register` adds
another without touching the runner, ``hier_agents.run`` or
``hier_agents.compare``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from physics_planning.cli import UsageError

__all__ = ["Agent", "AgentKind", "AgentSetup", "ACCESS", "HeldAction", "TrainedKind"]


class Agent(Protocol):
    """What the episode runner asks of an agent.

    Attributes:
      privileged: True when it reads more than a robot observes (the simulator).
      training_frames: environment frames spent training it (0: none).
      estimates: True when ``scene`` holds its estimate of the abstract state,
        which the harness judges against the referee (board games).
      scene: its last estimate (None: none yet, or it keeps none).
      gave_up: why it gave up on the episode (the runner ends the episode
        there, a failure with that reason), or None.
      episode_stats: the episode's subgoal counters
        (`hier_agents.modular.agent.OptionStats`; zeros for agents without
        subgoals).
    """

    privileged: bool
    training_frames: int
    estimates: bool
    scene: object
    gave_up: str | None
    episode_stats: object

    def reset(self, description, timestep, seed: int | None = None) -> None:
        """Starts an episode: the task's public ``description``, its first
        ``timestep`` and the episode's seed."""

    def act(self, timestep) -> np.ndarray:
        """The action for ``env.step`` after ``timestep``."""

    def end_episode(self, timestep) -> None:
        """Shows the agent the episode's last ``timestep`` (no action follows)."""

    def close(self) -> None:
        """Frees what the agent holds (GNU Go processes, ...). Idempotent."""


#: How much of an environment an agent sees: ``"simulator"`` (the whole
#: environment: privileged), ``"record"`` (the observations but the
#: simulator's ground truth: a board game's record is kept) or
#: ``"observations"`` (what a robot has: every privileged observation
#: removed, `hier_agents.boundary.BoundaryEnv`).
ACCESS = ("simulator", "record", "observations")

#: A privileged access in words, the one vocabulary of run lines, ``--list``
#: and comparison tables: ``READS[access]`` is what the agent reads ("the
#: referee's record"), ``SOURCE[access]`` the source a table's column names
#: ("game record"). An ``"observations"`` agent has neither.
READS = {"simulator": "the simulator", "record": "the referee's record"}
SOURCE = {"simulator": "simulator", "record": "game record"}


@dataclass
class AgentSetup:
    """An agent kind's plan for one environment, made before anything is built.

    Attributes:
      env_overrides: `envs.load` overrides the agent needs (its cameras).
      access: one of `ACCESS`.
      summary: the run summary's keys describing the agent (``agent``,
        ``planner``, ``skill``, ``privileged``, ...).
      build: ``build(view, seed, simulator)`` -> `Agent`: ``view`` is the
        environment as the agent may see it (its specs and ``description()``;
        `hier_agents.boundary.BoundaryEnv` unless privileged), ``simulator``
        the environment itself for ``access == "simulator"``, else None.
    """

    env_overrides: dict
    access: str
    summary: dict
    build: Callable[..., Agent]
    #: Environment overrides that must not change (a checkpoint's inputs):
    #: `hier_agents.run` refuses ``env_options`` naming them.
    fixed: frozenset = field(default_factory=frozenset)


def trained_setup(overrides: dict, summary: dict, build: Callable[..., Agent]) -> AgentSetup:
    """The `AgentSetup` of a trained model (`TrainedKind`): it reads the
    simulator when ``summary["privileged"]``, else observations only, and its
    cameras (the ``*_camera`` names of ``overrides``, its inputs) are fixed."""
    return AgentSetup(
        overrides,
        "simulator" if summary.get("privileged") else "observations",
        summary,
        build,
        fixed=frozenset(name for name in overrides if name.endswith("_camera")),
    )


class HeldAction:
    """An action held for ``repeat`` control steps: a trained agent whose
    learner decided every ``repeat`` steps (``action_repeat``) plays the
    same way.

    `next` gives the held action while the hold lasts, else None: the agent
    then decides and passes its new action to `hold`. `release` ends the hold
    early (the next step decides); `reset` starts each episode without one.

    Raises:
      ValueError: ``repeat`` below 1.
    """

    def __init__(self, repeat: int = 1):
        if int(repeat) < 1:
            raise ValueError(f"action_repeat must be >= 1 control steps, got {repeat!r}")
        self.repeat = int(repeat)
        self.reset()

    def reset(self) -> None:
        self._action: np.ndarray | None = None
        self._left = 0

    def release(self) -> None:
        self._left = 0

    def next(self) -> np.ndarray | None:
        """The held action, counting one step of the hold; None when the hold is over."""
        if self._action is None or self._left <= 0:
            return None
        self._left -= 1
        return self._action

    def hold(self, action: np.ndarray) -> np.ndarray:
        """Holds ``action`` for this step and the ``repeat - 1`` next ones; returns it."""
        self._action, self._left = action, self.repeat - 1
        return action


class AgentKind:
    """A kind of agent, named ``NAME`` or ``NAME:ARG`` (module docstring).

    Subclasses set ``name``, ``help`` and, when they take an argument,
    ``metavar``, ``arg_required`` and `parse`; ``options`` names the keyword
    options they take (``python -m hier_agents.run`` flags of the same name,
    keys of a comparison spec's agent table), ``env_flags`` whether
    ``--levels``, ``--env-option`` and ``--video`` apply.
    """

    name = ""
    help = ""
    metavar: str | None = None
    arg_required = False
    options: tuple[str, ...] = ()
    env_flags = True

    def parse(self, text: str):
        """The argument of ``NAME:text`` (UsageError when it is not allowed)."""
        raise UsageError(f"the agent kind {self.name!r} takes no argument, got {text!r}")

    def default(self):
        """The argument of a bare ``NAME``."""
        return None

    def check(self, env_name: str, arg, options: dict) -> None:
        """Refuses what cannot be played, before anything is built (a missing
        checkpoint, a bad component name): `UsageError`."""

    def setup(self, env_name: str, arg, options: dict) -> AgentSetup:
        """The `AgentSetup` of this kind for ``env_name``."""
        raise NotImplementedError

    def describe(self, summary: dict) -> str:
        """Who played, for the results table (from the run summary)."""
        return str(summary.get("agent", self.name))

    def job_inputs(self, env_name: str, arg, options: dict) -> dict:
        """What decides an evaluation job's result on ``env_name`` (`hier_agents.compare`
        hashes it into the job's key), JSON-able: ``{"kind": NAME, ...}``."""
        return {
            "kind": self.name,
            **({"arg": self.form(arg)} if arg is not None else {}),
            **options,
        }

    def from_job_inputs(self, inputs: dict) -> tuple[object, dict]:
        """(arg, options) of `job_inputs`'s dict."""
        arg = inputs.get("arg")
        options = {k: v for k, v in inputs.items() if k not in ("kind", "arg")}
        return (None if arg is None else self.parse(str(arg).partition(":")[2])), options

    def form(self, arg) -> str:
        """The ``NAME[:ARG]`` text of ``arg``."""
        return self.name if arg is None else f"{self.name}:{arg}"

    def forms(self) -> list[str]:
        """The accepted forms, for listings (``NAME``, ``NAME:METAVAR``)."""
        bare = [] if self.arg_required else [self.name]
        return bare + ([f"{self.name}:{self.metavar}"] if self.metavar else [])


class TrainedKind(AgentKind):
    """The shape shared by the kinds that play a trained model from a file
    (``NAME:PATH``, the ``stochastic`` option to sample its policy): they
    need a path, and describe a run's summary alike.

    ``describe`` reads the summary's ``condition``, ``training_frames``,
    ``trained_env``, ``observations`` and ``privileged``; a summary without
    ``condition`` (interrupted before a worker reported) is just its agent.
    """

    metavar = "PATH"
    arg_required = True
    options: tuple = ("stochastic",)

    def parse(self, text: str) -> str:
        if not text:
            raise UsageError(f"--agent {self.name}:PATH needs a path")
        return text

    def describe(self, summary: dict) -> str:
        from physics_planning.cli import plural

        if "condition" not in summary:
            return str(summary["agent"])
        who = (
            f"{summary['agent']} ({summary['condition']}, trained "
            f"{plural(summary['training_frames'], 'frame', spec=',')} on "
            f"{summary['trained_env']}"
        )
        if summary.get("observations"):
            who += f"; reads {', '.join(summary['observations'])}"
        who += ")"
        if summary.get("privileged"):
            who += f" (PRIVILEGED: reads {READS['simulator']})"
        return who
