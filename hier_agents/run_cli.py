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

__all__ = ["DEFAULT_ENV", "DEFAULT_EPISODES", "PROG", "Checked", "build_parser",
           "print_components", "check_args"]

PROG = "python -m hier_agents.run"
DEFAULT_ENV = "mujoban/level3"
DEFAULT_EPISODES = 5
#: Episodes when an environment is named but ``--episodes`` is not.
NAMED_ENV_EPISODES = 10

_AGENTS = "modular, checkpoint:PATH or random[:HOLD]"


def build_parser(description: str, epilog: str | None = None) -> argparse.ArgumentParser:
    """The ``python -m hier_agents.run`` argument parser (`physics_planning.cli.Parser`)."""
    parser = cli.Parser(PROG, description=description, epilog=epilog)
    parser.add_argument("env", nargs="?", default=None,
                        help=f"environment name, see python -m envs --list (default: "
                             f"{DEFAULT_ENV})")
    parser.add_argument("--episodes", type=cli.positive_int, default=None,
                        help=f"episodes to play (default: {DEFAULT_EPISODES} with the default "
                             f"environment, {NAMED_ENV_EPISODES} with a named one)")
    parser.add_argument("--seed", type=cli.non_negative_int, default=0,
                        help="seed of the environment and the agent")
    parser.add_argument("--agent", default="modular",
                        help="modular (estimator + planner + skill), checkpoint:PATH (a "
                             "hier_agents.train run directory or checkpoint file), random or "
                             "random:HOLD (uniform random actions, each held HOLD control steps)")
    parser.add_argument("--stochastic", action="store_true",
                        help="checkpoint agents: sample actions from the policy instead of "
                             "taking its mean")
    parser.add_argument("--planner", metavar="NAME[:ARG]",
                        help="modular agent: the planner, e.g. mcts:3000 or learned:PATH "
                             "(see --list; default: the family's first)")
    parser.add_argument("--skill", metavar="NAME[:ARG]",
                        help="modular agent: the skill, e.g. learned-ball:PATH (see --list; "
                             "default: the family's first)")
    parser.add_argument("--estimator", metavar="NAME",
                        help="modular agent: the estimator (see --list; default: the "
                             "family's first, observation-only)")
    parser.add_argument("--levels", metavar="FILE",
                        help="MuJoBan, modular and checkpoint agents: a Boxoban level file to "
                             "play in order")
    parser.add_argument("--env-option", action="append", default=[], metavar="KEY=VALUE",
                        help="an envs.load override of the played environment, e.g. "
                             "physics_timestep=0.005 or time_limit=5 (repeatable; VALUE is a "
                             "Python literal; modular and checkpoint agents)")
    parser.add_argument("--video", metavar="MP4",
                        help="write an MP4 of the first episode here (its folder is created)")
    parser.add_argument("--json", metavar="FILE",
                        help="write the summary here, rewritten after every episode "
                             "(\"finished\": false until the run ends; its folder is created)")
    parser.add_argument("--first-episode", type=cli.non_negative_int, default=0,
                        help="index of the first episode (episode e is seeded from (seed, e) "
                             "and plays the e-th level of --levels)")
    parser.add_argument("--workers", type=cli.positive_int, default=1,
                        help="processes playing episodes at once; the rows are the same for "
                             "any count")
    parser.add_argument("--ray-address", metavar="ADDRESS",
                        help="play on a Ray cluster (auto: the one `ray start` made; local: "
                             "start one here), --workers tasks at a time")
    parser.add_argument("--profile", action="store_true",
                        help="report the share of time spent in physics, rendering, the "
                             "estimator, the planner and the skill (table and JSON)")
    parser.add_argument("--list", action="store_true",
                        help="list each family's planners, skills and estimators and exit")
    return parser


def print_components() -> None:
    """``--list``: per game family, its planners, skills and estimators in
    the form the flags take them (``NAME``, ``NAME:ARG``; the first is the
    default; privileged estimators marked)."""
    for fam in PLANNERS:
        estimators = [f"{name} (privileged)" if getattr(factory, "privileged", False) else name
                      for name, factory in ESTIMATORS[fam].items()]
        print(f"{fam}:")
        print(f"  planners    {', '.join(components.forms('planner', fam))}")
        print(f"  skills      {', '.join(components.forms('skill', fam))}")
        print(f"  estimators  {', '.join(estimators)}")
    print("ARG: learned*:PATH a checkpoint file or run directory; mcts:N tree simulations "
          "per move; gnugo:LEVEL 1..10")


@dataclass
class Checked:
    """Arguments that passed `check_args`.

    Attributes:
      env: the environment's name.
      episodes: episodes to play (>= 1).
      env_options: `envs.load` overrides from ``--env-option`` (checked).
      levels: ``--levels`` (checked: it exists and parses) or None.
      json, video: output paths (folders created) or None.
    """

    env: str
    episodes: int
    env_options: dict = field(default_factory=dict)
    levels: str | None = None
    json: Path | None = None
    video: Path | None = None


def check_args(args) -> Checked:
    """Checks parsed ``args`` before anything is played; raises `UsageError`
    (one line: what is wrong, what is allowed, the closest name) for an
    unknown environment, planner, skill or estimator, a bad ``NAME:ARG`` or a
    checkpoint that does not load, ``--levels`` that is missing, malformed or
    outside MuJoBan, a bad ``--env-option``, an output path that cannot be
    written, an unknown ``--agent``, or a flag that does not apply to the
    agent. Creates the output folders."""
    env_name = env_cli.environment(args.env or DEFAULT_ENV)
    episodes = args.episodes if args.episodes is not None else (
        DEFAULT_EPISODES if args.env is None else NAMED_ENV_EPISODES)
    fam = family(env_name)
    agent = args.agent
    random_agent = agent == "random" or agent.startswith("random:")
    checkpoint_agent = agent.startswith("checkpoint:")
    if agent != "modular" and not random_agent and not checkpoint_agent:
        hint = cli.close_hint(agent, ("modular", "random", "checkpoint:"))
        raise UsageError(f"unknown --agent {agent!r}{hint}; valid: {_AGENTS}")
    if checkpoint_agent:
        path = Path(agent[len("checkpoint:"):])
        if not path.exists():
            raise UsageError(f"--agent {agent}: no checkpoint or run directory at "
                             f"{str(path) or '(empty path)'!r}")
    if random_agent:
        from hier_agents.baselines.impala.evaluate import parse_random
        parse_random(agent)  # UsageError for a bad HOLD
    if args.stochastic and not checkpoint_agent:
        raise UsageError("--stochastic applies to --agent checkpoint:PATH only")
    if agent != "modular":
        for flag, value in (("--planner", args.planner), ("--skill", args.skill),
                            ("--estimator", args.estimator)):
            if value is not None:
                raise UsageError(f"{flag} applies to the modular agent, not to --agent {agent}")
    if random_agent:
        for flag, value in (("--levels", args.levels), ("--env-option", args.env_option or None),
                            ("--video", args.video)):
            if value is not None:
                raise UsageError(f"{flag} applies to the modular and checkpoint agents, not to "
                                 f"--agent {agent}")
    for kind, spec in (("planner", args.planner), ("skill", args.skill),
                       ("estimator", args.estimator)):
        if spec is not None:
            components.check(kind, fam, spec)
    levels = None
    if args.levels is not None:
        if not adapter(fam).level_files:
            raise UsageError(f"--levels only applies to mujoban environments, not {env_name}")
        levels = env_cli.levels_file(env_name, args.levels)
    for item in args.env_option:
        key = item.partition("=")[0]
        if key == "levels" or key.endswith("_camera"):
            why = ("give a level file with --levels FILE" if key == "levels"
                   else "the cameras are the estimator's (or the checkpoint's)")
            raise UsageError(f"--env-option {item!r}: {why}")
    if args.ray_address is not None and args.video is not None:
        raise UsageError("--video is written by the process that plays the first episode: "
                         "not with --ray-address")
    options = env_cli.env_options(env_name, args.env_option,
                              exclude=lambda key: key.endswith("_camera") or key == "levels")
    return Checked(env_name, episodes, options, levels,
                   cli.output_file(args.json, "--json"), cli.output_file(args.video, "--video"))
