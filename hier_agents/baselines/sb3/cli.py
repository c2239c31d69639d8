"""Train a Stable-Baselines3 algorithm on an environment (gymnasium interface).

    python -m hier_agents.baselines.sb3 mujoban/level1 --algo PPO --frames 1000000
    python -m hier_agents.baselines.sb3 mujoban/level1 --algo SAC --frames 200000 \\
        --hyperparameters '{"buffer_size": 100000, "learning_starts": 1000}'
    python -m hier_agents.baselines.sb3 mujoxo/mixture --algo PPO --n-envs 4 \\
        --hyperparameters '{n_steps = 256, policy_kwargs = {net_arch = [64, 64]}}' \\
        --save-at 102400 204800 --frames 204800 --logdir runs/sb3-xo
    python -m hier_agents.run mujoban/level1 --agent sb3:runs/sb3      # evaluate

Algorithms (``--algo``): PPO (default) and A2C (on-policy: a rollout of
``n_steps`` per environment between updates), SAC and TD3 (off-policy: a
collection of ``train_freq`` steps per environment). ``--hyperparameters``
is a JSON object or a TOML inline table of the algorithm's constructor
arguments; an unknown name fails at once, naming the closest.

Observations (``--obs``, `envs.gymnasium_env.OBSERVATIONS`): ``state``
(default; MlpPolicy) is the proprioception and the task's abstract state
(MuJoBan's entity grid, the board games' board): it comes from the
simulator, so the agent is PRIVILEGED (config.json says so); ``sensors``
(MultiInputPolicy) is what the paper's agents see, the cameras and the
proprioception; ``pixels`` (CnnPolicy) the main camera alone.

Budget: ``--frames`` environment frames (control steps over all
``--n-envs`` environments; with ``--action-repeat K`` each of the
algorithm's steps is K frames), met exactly when a multiple of one
collection (else overshot by less than one); ``--save-at`` budgets (multiples of one
collection) keep LOGDIR/checkpoints/frames-B.zip exactly at B. Running the
same command again with the same ``--logdir`` continues the run from
LOGDIR/model.zip; a larger ``--frames`` extends it.
"""

from __future__ import annotations

import argparse
import json
import sys

from envs.cli import add_env_option
from physics_planning.cli import (
    Parser,
    UsageError,
    add_save_at,
    non_negative_int,
    positive_int,
    run_main,
)

PROG = "python -m hier_agents.baselines.sb3"


def inline_table(text: str) -> dict:
    """A JSON object or a TOML inline table (``{a = 1, b = "x"}``) as a dict.

    Raises:
      argparse.ArgumentTypeError: neither (the message shows the text).
    """
    import tomllib

    try:
        value = json.loads(text)
    except json.JSONDecodeError:
        try:
            value = tomllib.loads(f"table = {text}")["table"]
        except tomllib.TOMLDecodeError:
            value = None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(
            f"expected a JSON object or a TOML inline table, e.g. '{{\"n_steps\": 256}}' "
            f"or '{{n_steps = 256}}', got {text!r}"
        )
    return value


def build_parser() -> Parser:
    """The command's parser; its defaults are `Sb3Config`'s."""
    from hier_agents.baselines.sb3.config import ALGORITHMS, OBSERVATIONS, POLICIES, Sb3Config

    default = Sb3Config(env="")
    parser = Parser(PROG, description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1])
    add = parser.add_argument
    add("env", help="environment name, e.g. mujoban/level1 (python -m hier_agents.run --list)")
    add("--algo", default=default.algo, help=f"the algorithm: {', '.join(ALGORITHMS)}")
    add(
        "--policy",
        default=None,
        help="the SB3 policy (default by --obs: "
        + ", ".join(f"{k}: {v}" for k, v in POLICIES.items())
        + ")",
    )
    add("--obs", default=default.obs, help=f"the observation: {', '.join(OBSERVATIONS)}")
    add("--n-envs", type=positive_int, default=default.n_envs, help="environments stepped together")
    add(
        "--action-repeat",
        type=positive_int,
        default=default.action_repeat,
        metavar="K",
        help="hold each action for K control steps (frames still count control steps)",
    )
    add("--vec", default=default.vec, help="subproc (a process per environment) or dummy")
    add_env_option(parser, "time_limit=10.0 or top_camera=(48,48)")
    add(
        "--hyperparameters",
        type=inline_table,
        default=None,
        metavar="TABLE",
        help="the algorithm's constructor arguments, a JSON object or TOML inline table",
    )
    add("--frames", type=positive_int, default=default.frames, help="the frame budget, in total")
    add_save_at(parser, "LOGDIR/checkpoints/frames-N.zip")
    add("--seed", type=non_negative_int, default=default.seed, help="the run's seed")
    add("--logdir", default=default.logdir, help="the run directory (the same one continues it)")
    add("--no-progress", action="store_true", help="no progress lines on stderr")
    return parser


def config_from_args(argv=None):
    """The checked `Sb3Config` of ``argv`` (`Sb3Config.from_options`: UsageError)."""
    from envs.cli import env_options
    from hier_agents.baselines.sb3.config import Sb3Config

    args = build_parser().parse_args(argv)
    options = {k: v for k, v in vars(args).items() if k not in ("env", "env_option")}
    try:
        options["env_options"] = env_options(args.env, args.env_option)
    except KeyError:  # an unknown environment: from_options names the closest
        options["env_options"] = {}
    options["save_at"] = options["save_at"] or None
    return Sb3Config.from_options(args.env, options)


def _main(argv) -> int:
    from hier_agents.baselines.sb3.trainer import train

    config = config_from_args(argv)
    print(json.dumps(train(config), indent=2))
    return 0


def main(argv=None) -> int:
    """``python -m hier_agents.baselines.sb3``: trains, prints the final
    counters as JSON; exit status 0, 2 with one line on stderr for a bad
    input, 130 on a second Ctrl-C (`physics_planning.cli.run_main`)."""
    return run_main(PROG, _main, argv)


__all__ = ["PROG", "UsageError", "build_parser", "config_from_args", "inline_table", "main"]

if __name__ == "__main__":
    sys.exit(main())
