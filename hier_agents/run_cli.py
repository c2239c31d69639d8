"""The command line of `hier_agents.run` (``python -m hier_agents.run``): its
argument parser (`build_parser`), ``--list`` (`print_components`) and the
checks that turn bad arguments into usage errors before anything is played
(`check_args`).
"""

from __future__ import annotations

import argparse
import ast

import envs
from hier_agents.modular.components import ESTIMATORS, PLANNERS, SKILLS, family
from hier_agents.modular.families import adapter

__all__ = ["DEFAULT_ENV", "DEFAULT_EPISODES", "build_parser", "print_components", "check_args"]

DEFAULT_ENV = "mujoban/level3"
DEFAULT_EPISODES = 5


def build_parser(description: str) -> argparse.ArgumentParser:
    """The ``python -m hier_agents.run`` argument parser."""
    parser = argparse.ArgumentParser(prog="python -m hier_agents.run",
                                     description=description)
    parser.add_argument("env", nargs="?", default=None,
                        help=f"environment name (default: {DEFAULT_ENV}, "
                             f"{DEFAULT_EPISODES} episodes)")
    parser.add_argument("--episodes", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--agent", default="modular",
                        help="modular (default), checkpoint:PATH (a hier_agents.train run "
                             "directory or checkpoint file), random or random:HOLD (uniform random "
                             "actions, each held HOLD control steps)")
    parser.add_argument("--stochastic", action="store_true",
                        help="checkpoint agents: sample actions from the policy instead of "
                             "taking its mean")
    parser.add_argument("--planner", help="planner name (see --list)")
    parser.add_argument("--skill", help="skill name (see --list)")
    parser.add_argument("--estimator", help="estimator name (see --list)")
    parser.add_argument("--levels", help="MuJoBan: a Boxoban file to play in order")
    parser.add_argument("--env-option", action="append", default=[], metavar="KEY=VALUE",
                        help="an envs.load override for the modular agent's environment, e.g. "
                             "physics_timestep=0.005 or sleep=True (repeatable; VALUE is a "
                             "Python literal)")
    parser.add_argument("--video", help="write an MP4 of the first episode here")
    parser.add_argument("--json", help="write the summary here")
    parser.add_argument("--list", action="store_true", help="list planners and skills and exit")
    return parser


def print_components() -> None:
    """``--list``: per game family, its planners, skills and estimators
    (privileged ones marked)."""
    for fam in PLANNERS:
        names = [f"{name} (privileged)" if getattr(factory, "privileged", False) else name
                 for name, factory in ESTIMATORS[fam].items()]
        planners = list(PLANNERS[fam]) + (["learned:PATH"] if adapter(fam).level_files else [])
        print(f"{fam}: planners {planners}, skills {list(SKILLS[fam])}, "
              f"estimators {names}")


def check_args(parser: argparse.ArgumentParser, args) -> tuple:
    """(env name, episodes, env options dict) from parsed ``args``; every
    invalid combination exits through ``parser.error`` (status 2): unknown
    environment, planner, skill or estimator, a learned planner file that
    does not load, ``--levels`` outside MuJoBan, a bad ``--env-option``,
    modular-agent flags given with another agent."""
    env_name = args.env or DEFAULT_ENV
    episodes = args.episodes if args.episodes is not None else (
        DEFAULT_EPISODES if args.env is None else 10)
    if env_name not in envs.names():
        parser.error(f"unknown environment {env_name!r}; known: {', '.join(envs.names())}")
    if episodes < 1:
        parser.error("--episodes must be >= 1")
    try:
        fam = family(env_name)
    except ValueError as exc:
        parser.error(str(exc))
    for kind, table, name in (("planner", PLANNERS, args.planner), ("skill", SKILLS, args.skill),
                              ("estimator", ESTIMATORS, args.estimator)):
        if name is not None and name not in table[fam]:
            extra = (" or learned:PATH" if kind == "planner" and adapter(fam).level_files
                     else "")
            parser.error(f"unknown {kind} {name!r} for {fam}; valid: {sorted(table[fam])}{extra}")
    if args.planner and args.planner.startswith("learned:") and adapter(fam).level_files:
        from abstract_planners.learned_options import load_option_policy
        try:  # a missing or foreign checkpoint fails here, with a usage error
            load_option_policy(args.planner[len("learned:"):])
        except (FileNotFoundError, ValueError) as exc:
            parser.error(f"--planner {args.planner}: {exc}")
    if args.levels is not None and not adapter(fam).level_files:
        parser.error("--levels only applies to mujoban environments")
    env_options = {}
    for item in args.env_option:
        key, sep, text = item.partition("=")
        if not sep or key not in envs.overrides(env_name) or key.endswith("_camera"):
            valid = [k for k in envs.overrides(env_name) if not k.endswith("_camera")]
            parser.error(f"--env-option must be KEY=VALUE with KEY one of {valid}, got {item!r}")
        try:
            env_options[key] = ast.literal_eval(text)
        except (ValueError, SyntaxError):
            env_options[key] = text
    if env_options:
        try:  # a bad value fails here, with the environment's own message
            envs.load(env_name, **envs.no_cameras(env_name), **env_options).close()
        except (TypeError, ValueError) as exc:
            parser.error(f"--env-option: {exc}")
    if args.stochastic and not args.agent.startswith("checkpoint:"):
        parser.error("--stochastic applies to checkpoint:PATH agents")
    if args.agent != "modular":
        if args.agent.startswith("random"):
            from hier_agents.baselines.impala.evaluate import parse_random
            try:
                parse_random(args.agent)
            except ValueError as exc:
                parser.error(str(exc))
        elif not args.agent.startswith("checkpoint:") or args.agent == "checkpoint:":
            parser.error(f"--agent must be modular, random[:HOLD] or checkpoint:PATH, "
                         f"got {args.agent!r}")
        for flag, value in (("--planner", args.planner), ("--skill", args.skill),
                            ("--estimator", args.estimator), ("--levels", args.levels),
                            ("--env-option", args.env_option or None)):
            if value is not None:
                parser.error(f"{flag} applies to the modular agent, not to {args.agent}")
    return env_name, episodes, env_options
