"""Train the paper's end-to-end agent (IMPALA-style actor-critic, V-trace).

    python -m hier_agents.train mujoban/level1 --condition expert-planner --frames 2000000
    python -m hier_agents.train mujoban/level1 --frames 2000000 --logdir runs/vanilla
    python -m hier_agents.train mujoban/level1 --preset cpu --frames 200000 --logdir runs/cpu
    python -m hier_agents.train mujoban/level1 --observations proprio --state --preset small-batches
    python -m hier_agents.train mujoxo/mixture --condition random-planner --backend ray
    tensorboard --logdir runs                       # the curves
    python -m hier_agents.run mujoban/level1 --agent checkpoint:runs/impala   # evaluate

Conditions (``--condition``, the paper's): ``vanilla`` (environment reward,
one value head), ``random-planner`` and ``expert-planner`` (the planner's
current and target abstract states as inputs, an auxiliary reward when the
planner's transition is reached within ``T_abs`` = 50 steps, a second value
head with its own discount).

Observations: by default what the paper's agent sees, the camera views
(96x96 RGB, ``--image-size``; MuJoBan: top and egocentric, board games:
front) through the residual network, and proprioception.
``--observations main-camera`` keeps the main view only (MuJoBan's top
camera); ``--observations proprio`` renders nothing (fast, but the agent sees
neither the level nor the board and cannot solve them). The planner
conditions add the planner's planes. ``--state`` adds the current abstract
state at every step (MuJoBan: the entity grid; board games: the board, the
setting of the paper's board-game agents): it comes from the simulator, so
the agent is PRIVILEGED. The run's config.json records the observation keys
(``observations``) and ``privileged``; ``hier_agents.run --agent
checkpoint:DIR`` reports them.

``--preset cpu``, a lighter agent for CPU machines: the main camera only, at
48x48, and 8 environments per actor (explicit flags win over the preset).
On a 2-core, 23 GB machine (mujoban/level1, vanilla, 2 actors, batches of
128 unrolls of 100 steps) the preset trained 220 frames/s (its actors alone
stepped 358); the defaults, the paper's (sized for an accelerator), 22
frames/s (actors alone 68; 5 CPU minutes per update), and their actors held
9 GB of memory each (about 250 MB per environment that renders).

``--preset small-batches``: updates of 16 unrolls of 20 steps (320 frames)
instead of the paper's 128 (MuJoBan) or 64 (board games) unrolls of 100
steps, so a budget of a few hundred thousand frames makes hundreds of
updates rather than a few dozen; the comparison's end-to-end agents train
with it (experiments/mujoban.toml, docs/results/comparison.md).

Budget: ``--frames`` environment frames (control steps) in total, at least
one unroll (``--unroll-length``); met exactly when it is a multiple of the
unroll length (else overshot by less than one unroll): each update takes
``--batch-size`` unrolls, the last only those the budget still needs.

The learner's objective: the paper's V-trace policy gradient with RMSProp by
default; ``--optimizer adam``, ``--normalize-advantages`` and ``--clip-ratio``
(PPO's clipped surrogate, with ``--passes`` above 1) bring PPO's ingredients
in (docs/results/comparison.md, "Tuning the end-to-end agent", measures them).

Running the same command again with the same ``--logdir`` resumes from its
checkpoint (saved every ``--checkpoint-every`` seconds, at the end and on
Ctrl-C); a logdir holding another run (another environment, condition,
observations, or another trainer's) is refused. ``--backend ray`` runs the
actors as Ray actors (a local Ray instance, or ``--ray-address auto`` for a
cluster made with ``ray start``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys

from physics_planning.cli import Parser, non_negative_int, positive_float, positive_int, run_main
from hier_agents.baselines.impala.config import OBSERVATIONS, PRESETS  # noqa: F401 - re-exported

PROG = "python -m hier_agents.train"


def build_parser() -> Parser:
    """The command's parser; its defaults are `TrainConfig`'s."""
    from hier_agents.baselines.impala.config import TrainConfig

    default = {
        f.name: f.default
        for f in dataclasses.fields(TrainConfig)
        if f.default is not dataclasses.MISSING
    }
    parser = Parser(PROG, description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1])
    _add_task_args(parser, default)
    _add_observation_args(parser, default)
    _add_scale_args(parser, default)
    _add_batch_args(parser, default)
    _add_loss_args(parser, default)
    _add_logging_args(parser, default)
    return parser


def _add_task_args(parser: Parser, default: dict) -> None:
    """What to train: the environment, the condition, the frame budget."""
    from hier_agents.baselines.impala.agent_env import CONDITIONS

    add = parser.add_argument
    add("env", help="environment name, e.g. mujoban/level1 (python -m hier_agents.run --list)")
    add(
        "--condition",
        default=default["condition"],
        help=f"the training condition: {', '.join(CONDITIONS)}",
    )
    add(
        "--frames",
        type=positive_int,
        default=default["steps"],
        help="environment frames (control steps) to train for, in total",
    )
    from envs.cli import add_env_option

    add_env_option(parser, "time_limit=20.0", "the actors' environments")


def _add_observation_args(parser: Parser, default: dict) -> None:
    """What the agent observes, and the ``--preset`` of defaults."""
    add = parser.add_argument
    add(
        "--observations",
        default="cameras",
        help="cameras: every camera view + proprioception (the paper's); main-camera: the "
        "main view + proprioception; proprio: proprioception only",
    )
    add(
        "--image-size",
        type=positive_int,
        default=default["image_size"],
        help="side of the square camera images, in pixels (the paper's 96)",
    )
    add(
        "--state",
        action="store_true",
        help="also observe the current abstract state (MuJoBan's entity grid; the board "
        "games' board, the paper's board-game setting): PRIVILEGED",
    )
    add(
        "--preset",
        default=None,
        help="a set of defaults that explicit flags override: "
        + "; ".join(
            f"{name}: " + " ".join(f"--{k.replace('_', '-')} {v}" for k, v in flags.items())
            for name, flags in PRESETS.items()
        ),
    )


def _add_scale_args(parser: Parser, default: dict) -> None:
    """Where the actors run and where the run is kept."""
    add = parser.add_argument
    add(
        "--actors",
        type=positive_int,
        default=default["actors"],
        help="actor processes / Ray actors",
    )
    add(
        "--envs-per-actor",
        type=positive_int,
        default=default["envs_per_actor"],
        help="environments stepped together by one actor (one batched policy call)",
    )
    add(
        "--env-threads",
        type=positive_int,
        default=default["env_threads"],
        help="threads each actor advances its environments' physics on, all at once "
        "(envs.vector.PhysicsPool; the results are those of one thread)",
    )
    add("--backend", default=default["backend"], help="local or ray")
    add(
        "--ray-address",
        default=None,
        help="join a running Ray cluster (e.g. auto); default: start one",
    )
    add(
        "--logdir",
        default=default["logdir"],
        help="the run directory (the same one again resumes the run)",
    )


def _add_batch_args(parser: Parser, default: dict) -> None:
    """The learner's unrolls and batches, and how often each batch is used."""
    from hier_agents.modular.families import FAMILIES

    add = parser.add_argument
    add(
        "--unroll-length",
        type=positive_int,
        default=default["unroll_length"],
        help="agent steps per unroll",
    )
    add(
        "--action-repeat",
        type=positive_int,
        default=default["action_repeat"],
        help="control steps each action is held for; frames count control steps (the paper's 1)",
    )
    add(
        "--batch-size",
        type=positive_int,
        default=None,
        help="unrolls per update (default: the paper's, "
        + ", ".join(f"{a.paper_batch} {fam}" for fam, a in FAMILIES.items())
        + ")",
    )
    add(
        "--passes",
        type=positive_int,
        default=default["passes"],
        help="gradient steps on each batch (V-trace corrects the later ones for the "
        "policy's change; the paper's: 1)",
    )


def _add_loss_args(parser: Parser, default: dict) -> None:
    """The optimiser, the losses and their weights, the state encoder, and the seed."""
    from hier_agents.baselines.impala.config import OPTIMIZERS
    from physics_planning.cli import non_negative_float

    add = parser.add_argument
    add(
        "--learning-rate",
        type=positive_float,
        default=default["learning_rate"],
        help="the optimiser's learning rate",
    )
    add(
        "--optimizer",
        choices=OPTIMIZERS,
        default=default["optimizer"],
        help="rmsprop (the paper's) or adam",
    )
    add(
        "--normalize-advantages",
        action="store_true",
        help="shift and scale the policy gradient's advantages to mean 0, std 1 per batch",
    )
    add(
        "--clip-ratio",
        type=non_negative_float,
        default=default["clip_ratio"],
        help="PPO's clipped surrogate with this epsilon, e.g. 0.2, for --passes > 1 "
        "(0: off, the paper's policy gradient)",
    )
    add(
        "--entropy-cost",
        type=non_negative_float,
        default=default["entropy_cost"],
        help="weight of the policy's entropy bonus",
    )
    add(
        "--state-channels",
        type=positive_int,
        default=default["state_channels"],
        help="convolution channels of the --state encoder (the planner encoder's 100; "
        "fewer make its linear layer smaller)",
    )
    add(
        "--abs-reward",
        type=non_negative_float,
        default=default["abs_reward"],
        help="auxiliary reward for reaching the planner's target",
    )
    add(
        "--seed",
        type=non_negative_int,
        default=default["seed"],
        help="seed of the network and the actors' environments",
    )


def _add_logging_args(parser: Parser, default: dict) -> None:
    """Checkpoints, logging and the progress bar."""
    from physics_planning.cli import add_save_at, non_negative_float

    add = parser.add_argument
    add(
        "--checkpoint-every",
        type=non_negative_float,
        default=default["checkpoint_every_s"],
        help="seconds between checkpoints (0: after every update)",
    )
    add(
        "--keep-checkpoints",
        action="store_true",
        help="also keep every checkpoint as LOGDIR/checkpoints/frames-N.pt "
        "(for benchmarks/learning_curve.py)",
    )
    add_save_at(
        parser,
        "a checkpoint LOGDIR/checkpoints/frames-N.pt",
        "multiples of the frames of one unroll: --unroll-length x --action-repeat",
    )
    add(
        "--log-every",
        type=non_negative_float,
        default=default["log_every_s"],
        help="seconds between TensorBoard / scalars.jsonl rows (0: every update)",
    )
    add("--no-progress", action="store_true", help="no progress bar")


def parse_args(argv=None) -> argparse.Namespace:
    """Parses ``argv``: the flags given, the others None (their defaults,
    and the ``--preset``'s, are `TrainConfig.from_options`'s to apply)."""
    parser = build_parser()
    parser.parse_args(argv)  # --help shows, and errors name, the documented defaults
    parser.set_defaults(
        **{action.dest: None for action in parser._actions if action.dest not in ("help", "env")}
    )
    return parser.parse_args(argv)


def config_from_args(args):
    """The `TrainConfig` of parsed arguments (`TrainConfig.from_options`:
    checked, `UsageError`), before anything is built but the main-camera
    look-up."""
    from hier_agents.baselines.impala.config import TrainConfig

    from envs.cli import env_options

    options = {key: value for key, value in vars(args).items() if key not in ("env", "env_option")}
    try:
        options["env_options"] = env_options(args.env, args.env_option or ())
    except KeyError:  # an unknown environment: from_options names the closest
        options["env_options"] = {}
    return TrainConfig.from_options(args.env, options)


def _main(argv) -> int:
    from hier_agents.baselines.impala.learner import train

    counters = train(config_from_args(parse_args(argv)))
    counters.pop("last_stats", None)
    print(json.dumps(counters, indent=2))
    return 0


def main(argv=None) -> int:
    """``python -m hier_agents.train``: trains, prints the final counters as
    JSON; exit status 0, 2 with one line on stderr for a bad input, 130 on a
    second Ctrl-C (`physics_planning.cli.run_main`)."""
    return run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
