"""The command line of `hier_agents.run` (``python -m hier_agents.run``): its
argument parser (`build_parser`), ``--list`` (`print_components`) and the
checks that turn bad arguments into one-line usage errors before anything is
played (`check_args`). Conventions: `physics_planning.cli`; component names:
`hier_agents.modular.components.resolve`.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

from envs import cli as env_cli
from physics_planning import cli
from physics_planning.cli import UsageError
from hier_agents.modular import components
from hier_agents.modular.components import ESTIMATORS, PLANNERS, family
from hier_agents.modular.families import adapter

__all__ = [
    "DEFAULT_ENV",
    "DEFAULT_EPISODES",
    "PROG",
    "Checked",
    "build_parser",
    "print_components",
    "check_args",
]

PROG = "python -m hier_agents.run"
DEFAULT_ENV = "mujoban/level3"
DEFAULT_EPISODES = 5
#: Episodes when an environment is named but ``--episodes`` is not.
NAMED_ENV_EPISODES = 10


def build_parser(description: str, epilog: str | None = None) -> argparse.ArgumentParser:
    """The ``python -m hier_agents.run`` argument parser (`physics_planning.cli.Parser`)."""
    parser = cli.Parser(PROG, description=description, epilog=epilog)
    _add_play_args(parser)
    _add_agent_args(parser)
    _add_output_args(parser)
    _add_run_args(parser)
    parser.add_argument(
        "--profile",
        action="store_true",
        help="report the share of time spent in physics, rendering, the "
        "estimator, the planner and the skill (table and JSON)",
    )
    parser.add_argument(
        "--list",
        action="store_true",
        help="list the agent kinds and each family's planners, skills and estimators and exit",
    )
    return parser


def _add_play_args(parser: argparse.ArgumentParser) -> None:
    """What to play: the environment, the episodes, the seed."""
    parser.add_argument(
        "env",
        nargs="?",
        default=None,
        help=f"environment name, see python -m envs --list (default: {DEFAULT_ENV})",
    )
    parser.add_argument(
        "--episodes",
        type=cli.positive_int,
        default=None,
        help=f"episodes to play (default: {DEFAULT_EPISODES} with the default "
        f"environment, {NAMED_ENV_EPISODES} with a named one)",
    )
    parser.add_argument(
        "--seed", type=cli.non_negative_int, default=0, help="seed of the environment and the agent"
    )


def _add_agent_args(parser: argparse.ArgumentParser) -> None:
    """The agent: its kind and its parts, the levels and environment overrides it plays."""
    parser.add_argument(
        "--agent",
        default="modular",
        metavar="NAME[:ARG]",
        help="the agent kind: modular (estimator + planner + skill), "
        "checkpoint:PATH (a hier_agents.train run directory or checkpoint "
        "file), random or random:HOLD (uniform random actions, each held "
        "HOLD control steps), or a registered kind (see --list)",
    )
    parser.add_argument(
        "--stochastic",
        action="store_true",
        help="checkpoint agents: sample actions from the policy instead of taking its mean",
    )
    parser.add_argument(
        "--planner",
        metavar="NAME[:ARG]",
        help="modular agent: the planner, e.g. mcts:3000 or learned:PATH "
        "(see --list; default: the family's first)",
    )
    parser.add_argument(
        "--skill",
        metavar="NAME[:ARG]",
        help="modular agent: the skill, e.g. learned-ball:PATH (see --list; "
        "default: the family's first)",
    )
    parser.add_argument(
        "--estimator",
        metavar="NAME",
        help="modular agent: the estimator (see --list; default: the "
        "family's first, observation-only)",
    )
    parser.add_argument(
        "--levels",
        metavar="FILE",
        help="MuJoBan, modular and checkpoint agents: a Boxoban level file to play in order",
    )
    env_cli.add_env_option(parser, "physics_timestep=0.005 or time_limit=5")


def _add_output_args(parser: argparse.ArgumentParser) -> None:
    """The outputs: the video and the JSON summary."""
    parser.add_argument(
        "--video",
        metavar="MP4",
        help="write an MP4 of the first episode here (its folder is created)",
    )
    parser.add_argument(
        "--json",
        metavar="FILE",
        help="write the summary here, rewritten after every episode "
        '("finished": false until the run ends; its folder is created)',
    )


def _add_run_args(parser: argparse.ArgumentParser) -> None:
    """Where and how the episodes run: the first episode, the workers, Ray."""
    parser.add_argument(
        "--first-episode",
        type=cli.non_negative_int,
        default=0,
        help="index of the first episode (episode e is seeded from (seed, e) "
        "and plays the e-th level of --levels)",
    )
    parser.add_argument(
        "--workers",
        type=cli.positive_int,
        default=1,
        help="processes playing episodes at once; the rows are the same for any count",
    )
    parser.add_argument(
        "--ray-address",
        metavar="ADDRESS",
        help="play on a Ray cluster (auto: the one `ray start` made; local: "
        "start one here), --workers tasks at a time",
    )


def print_components() -> None:
    """``--list``: the agent kinds, then per game family its planners,
    skills and estimators in the form the flags take them (``NAME``,
    ``NAME:ARG``; the first is the default; privileged estimators marked)."""
    from hier_agents.agents import KINDS, forms
    from hier_agents.agents.base import READS

    forms()  # registers the shipped kinds
    print("agents:")
    for kind in KINDS.values():
        print(f"  {' | '.join(kind.forms()):<28} {kind.help}")
    for fam in PLANNERS:
        estimators = []
        for name in ESTIMATORS[fam]:
            access = components.access(fam, name)
            estimators.append(f"{name} (privileged: {READS[access]})" if access in READS else name)
        print(f"{fam}:")
        print(f"  planners    {', '.join(components.forms('planner', fam))}")
        print(f"  skills      {', '.join(components.forms('skill', fam))}")
        print(f"  estimators  {', '.join(estimators)}")
    print(
        "ARG: learned*:PATH a checkpoint file or run directory; mcts:N tree simulations "
        "per move; gnugo:LEVEL 1..10"
    )


@dataclass
class Checked:
    """Arguments that passed `check_args`.

    Attributes:
      env: the environment's name.
      episodes: episodes to play (>= 1).
      options: the agent kind's options given (``planner``, ``skill``,
        ``estimator``, ``stochastic``).
      env_options: `envs.load` overrides from ``--env-option`` (checked).
      levels: ``--levels`` (checked: it exists and parses) or None.
      json, video: output paths (folders created) or None.
    """

    env: str
    episodes: int
    options: dict = field(default_factory=dict)
    env_options: dict = field(default_factory=dict)
    levels: str | None = None
    json: Path | None = None
    video: Path | None = None


#: The flags of agent kinds' options (`hier_agents.agents.AgentKind.options`).
_OPTION_FLAGS = {
    "planner": "--planner",
    "skill": "--skill",
    "estimator": "--estimator",
    "stochastic": "--stochastic",
}


def _agent_options(args) -> dict:
    """The agent kind's options given on the command line, checked against
    the kind (`UsageError` for a flag it does not take or a bad value)."""
    from hier_agents.agents import resolve

    env_name = cli_env(args)
    kind, arg = resolve(args.agent)
    given = {
        key: getattr(args, key) for key in _OPTION_FLAGS if getattr(args, key) not in (None, False)
    }
    for key in given:
        if key not in kind.options:
            raise UsageError(
                f"{_OPTION_FLAGS[key]} applies to the agents that take it "
                f"({', '.join(_takers(key))}), not to --agent {args.agent}"
            )
    if not kind.env_flags:
        for flag, value in (
            ("--levels", args.levels),
            ("--env-option", args.env_option or None),
            ("--video", args.video),
        ):
            if value is not None:
                raise UsageError(f"{flag} does not apply to --agent {args.agent}")
    kind.check(env_name, arg, given)
    return given


def _takers(key: str) -> list[str]:
    from hier_agents.agents import KINDS

    return [name for name, kind in KINDS.items() if key in kind.options]


def cli_env(args) -> str:
    """The checked environment name of ``args`` (the default when none is given)."""
    return env_cli.environment(args.env or DEFAULT_ENV)


def check_args(args) -> Checked:
    """Checks parsed ``args`` before anything is played; raises `UsageError`
    (one line: what is wrong, what is allowed, the closest name) for an
    unknown environment, agent, planner, skill or estimator, a bad
    ``NAME:ARG`` or a checkpoint that does not load, ``--levels`` that is
    missing, malformed or outside MuJoBan, a bad ``--env-option``, an output
    path that cannot be written, or a flag that does not apply to the agent.
    Creates the output folders."""
    env_name = cli_env(args)
    episodes = (
        args.episodes
        if args.episodes is not None
        else (DEFAULT_EPISODES if args.env is None else NAMED_ENV_EPISODES)
    )
    fam = family(env_name)
    options = _agent_options(args)
    levels = None
    if args.levels is not None:
        if not adapter(fam).level_files:
            raise UsageError(f"--levels only applies to mujoban environments, not {env_name}")
        levels = env_cli.levels_file(env_name, args.levels)
    for item in args.env_option:
        key = item.partition("=")[0]
        if key == "levels" or key.endswith("_camera"):
            why = (
                "give a level file with --levels FILE"
                if key == "levels"
                else "the cameras are the agent's (its estimator's or checkpoint's)"
            )
            raise UsageError(f"--env-option {item!r}: {why}")
    if args.ray_address is not None and args.video is not None:
        raise UsageError(
            "--video is written by the process that plays the first episode: not with --ray-address"
        )
    env_options = env_cli.env_options(
        env_name, args.env_option, exclude=lambda key: key.endswith("_camera") or key == "levels"
    )
    return Checked(
        env_name,
        episodes,
        options,
        env_options,
        levels,
        cli.output_file(args.json, "--json"),
        cli.output_file(args.video, "--video"),
    )
