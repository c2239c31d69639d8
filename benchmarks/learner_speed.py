"""Actor-learner throughput against the bare environment, same configuration.

    python benchmarks/learner_speed.py [--env mujoban/level1] [--condition expert-planner]
                                      [--frames 200000] [--actors 2] [--envs-per-actor 32]
                                      [--env-threads T] [--batch-size N] [--backend local|ray]
                                      [--train-option KEY=VALUE ...] [--json PATH]

1. **Bare environment**: ``envs.load(ENV)`` with the run's cameras (off by
   default), uniform random actions, one process: control steps per second
   (the best of three runs).
2. **Actor-learner**: `hier_agents.baselines.impala.learner.train` for ``--frames``
   environment frames into a temporary log directory (any other training
   option with ``--train-option KEY=VALUE``: a `TrainConfig.from_options`
   key, e.g. ``action_repeat=4`` or ``preset="small-batches"``, VALUE a
   Python literal); its throughput is the
   frames the learner consumed per wall-clock second between its first and
   last log lines (start-up -- process spawn, imports -- excluded), as
   written in ``scalars.jsonl``.
3. **The comparison**: the bare environment in as many processes as the run
   has actors (``--actors``), stepping at the same time on the same machine,
   their summed steps/s. The learner's frames/s divided by that is the
   honest ratio (``ratio_to_parallel``): the actors are that many processes
   too, so dividing by one process (``ratio``, kept for reference) counts
   the second core as the learner's merit. On the shared 2-core machines we
   measure on, two processes have reached anything from ~1.1x to 2x one
   process, from one hour to the next.
4. **The batch** (with ``--env-threads`` above 1: each actor advances its
   environments' physics on that many threads, `envs.vector.PhysicsPool`):
   all the run's environments in one `envs.vector.BatchedVectorEnv` on as
   many threads, stepping alone; ``ratio_to_batched`` is the learner's
   frames/s over that: how much of what the batched environments produce
   the learner consumes.

Prints a table and, with ``--json``, writes {"env", "agent",
"learner_frames_per_s", "parallel_env_steps_per_s", "ratio_to_parallel",
"batched_env_steps_per_s", "ratio_to_batched" (None without ``--env-threads``),
"compared_with", "env_steps_per_s", "ratio", ..., "provenance"}.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import env_cli, cli, make_parser, prog, write_json  # noqa: E402

import numpy as np  # noqa: E402

import envs  # noqa: E402
from hier_agents.learning.rundir import SCALARS  # noqa: E402

PROG = prog(__file__)


def _make_env(name: str, cameras: bool, seed: int):
    return envs.load(name, seed=seed, **({} if cameras else envs.no_cameras(name)))


def _random_steps(env, steps: int, rng) -> float:
    """Steps/s of ``steps`` uniform random actions (resets included)."""
    spec = env.action_spec()
    env.reset()
    start = time.perf_counter()
    for _ in range(steps):
        if env.step(rng.uniform(spec.minimum, spec.maximum)).last():
            env.reset()
    return steps / (time.perf_counter() - start)


def bare_env_steps_per_s(
    name: str, cameras: bool, steps: int, seed: int = 0, repeats: int = 3
) -> float:
    """Best of ``repeats`` runs of ``steps`` random steps (resets included):
    the highest rate, so the ratio against it is the conservative one."""
    env = _make_env(name, cameras, seed)
    rng = np.random.default_rng(seed)
    rates = [_random_steps(env, steps, rng) for _ in range(repeats)]
    env.close()
    return max(rates)


def _parallel_worker(name, cameras, steps, seed, barrier, out) -> None:
    env = _make_env(name, cameras, seed)
    rng = np.random.default_rng(seed)
    barrier.wait()  # all processes step at the same time
    out.put(_random_steps(env, steps, rng))
    env.close()


def parallel_env_steps_per_s(
    name: str, cameras: bool, steps: int, processes: int, seed: int = 0
) -> float:
    """Summed steps/s of ``processes`` bare environments stepping at the same time."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    out, barrier = ctx.Queue(), ctx.Barrier(processes)
    procs = [
        ctx.Process(target=_parallel_worker, args=(name, cameras, steps, seed + i, barrier, out))
        for i in range(processes)
    ]
    for p in procs:
        p.start()
    rates = [out.get(timeout=600) for _ in procs]
    for p in procs:
        p.join()
    return float(sum(rates))


def batched_env_steps_per_s(
    name: str, cameras: bool, steps: int, num_envs: int, threads: int, seed: int = 0
) -> float:
    """Steps/s of ``num_envs`` environments in one `envs.vector.BatchedVectorEnv`
    on ``threads`` physics threads (random actions, about ``steps`` control
    steps in all, autoresets included): what the actors' batches produce."""
    import envs.vector

    vec = envs.vector.make(
        name,
        num_envs=num_envs,
        obs="sensors" if cameras else "state",
        seed=seed,
        threads=threads,
        **({} if cameras else envs.no_cameras(name)),
    )
    try:
        vec.reset()
        vec.action_space.seed(seed)
        start = time.perf_counter()
        for _ in range(max(1, steps // num_envs)):
            vec.step(vec.action_space.sample())
        return max(1, steps // num_envs) * num_envs / (time.perf_counter() - start)
    finally:
        vec.close()


def train_options(items: list[str]) -> dict:
    """``--train-option KEY=VALUE`` items as `TrainConfig.from_options`
    options (VALUE a Python literal, else the text); `UsageError` for a
    malformed item or an unknown key, with the closest one."""
    from hier_agents.baselines.impala.config import OPTIONS

    return cli.key_values(items, "--train-option", OPTIONS)


def learner_config(args, logdir: str):
    """The checked `TrainConfig` of the run (`UsageError` for what it refuses)."""
    from hier_agents.baselines.impala.learner import TrainConfig

    options = {
        "condition": args.condition,
        "frames": args.frames,
        "actors": args.actors,
        "envs_per_actor": args.envs_per_actor,
        "env_threads": args.env_threads,
        "backend": args.backend,
        "batch_size": args.batch_size,
        "observations": "cameras" if args.cameras else "proprio",
        "state": args.state,
        "seed": args.seed,
        **args.train_options,
        "logdir": logdir,
        "log_every": 2.0,
        "checkpoint_every": 1e9,
        "no_progress": True,
    }
    return TrainConfig.from_options(args.env, options)


def learner_frames_per_s(args) -> dict:
    from hier_agents.baselines.impala.learner import train

    with tempfile.TemporaryDirectory() as logdir:
        config = learner_config(args, logdir)
        start = time.perf_counter()
        counters = train(config)
        total_s = time.perf_counter() - start
        lines = [json.loads(line) for line in open(Path(logdir) / SCALARS)]
    if len(lines) < 2:
        raise SystemExit(f"only {len(lines)} log lines: raise --frames for a steady-state rate")
    first, last = lines[0], lines[-1]
    steady = (last["frames"] - first["frames"]) / (last["wall_s"] - first["wall_s"])
    return {
        "learner_frames_per_s": steady,
        "frames": counters["frames"],
        "updates": counters["updates"],
        "total_s": total_s,
        "overall_frames_per_s": counters["frames"] / total_s,
        "policy_lag_updates": last.get("perf/policy_lag"),
    }


def _main(argv=None) -> int:
    from hier_agents.baselines.impala.agent_env_spec import CONDITIONS

    parser = make_parser(__file__, __doc__)
    parser.add_argument("--env", default="mujoban/level1", help="environment name")
    parser.add_argument(
        "--condition",
        default="expert-planner",
        help=f"the training condition (hier_agents.train --condition: {', '.join(CONDITIONS)})",
    )
    parser.add_argument(
        "--frames", type=cli.positive_int, default=200_000, help="frames the learner trains on"
    )
    parser.add_argument("--actors", type=cli.positive_int, default=2)
    parser.add_argument("--envs-per-actor", type=cli.positive_int, default=32)
    parser.add_argument(
        "--env-threads",
        type=cli.positive_int,
        default=1,
        help="physics threads per actor; above 1 the learner is also compared with "
        "the same batch of environments stepping alone on as many threads",
    )
    parser.add_argument("--batch-size", type=cli.positive_int, default=None)
    parser.add_argument("--backend", default="local", help="local or ray")
    parser.add_argument("--cameras", action="store_true")
    parser.add_argument(
        "--state",
        action="store_true",
        help="the agent also observes the abstract state (PRIVILEGED), as the "
        "shipped comparison's state series",
    )
    parser.add_argument(
        "--bare-steps",
        type=cli.positive_int,
        default=10_000,
        help="control steps of the bare-environment measurement",
    )
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument(
        "--train-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="any other training option (a TrainConfig.from_options key, VALUE a Python "
        "literal; repeatable), e.g. action_repeat=4",
    )
    parser.add_argument("--json", type=Path, help="write the row here")
    args = parser.parse_args(argv)
    args.train_options = train_options(args.train_option)
    learner_config(args, tempfile.gettempdir())  # refused here, before anything is measured
    env_cli.environment(args.env)
    cli.choice("condition", args.condition, CONDITIONS)
    cli.choice("backend", args.backend, ("local", "ray"))
    cli.output_file(args.json, "--json")

    bare = bare_env_steps_per_s(args.env, args.cameras, args.bare_steps, args.seed)
    print(
        f"bare {args.env} (cameras {'on' if args.cameras else 'off'}): {bare:,.0f} steps/s",
        flush=True,
    )
    parallel = parallel_env_steps_per_s(
        args.env, args.cameras, 2 * args.bare_steps, max(1, args.actors), args.seed
    )
    print(
        f"bare {args.env} in {max(1, args.actors)} processes at once: {parallel:,.0f} "
        f"steps/s in total",
        flush=True,
    )
    batched = None
    if args.env_threads > 1:
        batched = batched_env_steps_per_s(
            args.env,
            args.cameras,
            2 * args.bare_steps,
            args.actors * args.envs_per_actor,
            args.env_threads,
            args.seed,
        )
        print(
            f"bare {args.env}, {args.actors * args.envs_per_actor} environments batched on "
            f"{args.env_threads} threads: {batched:,.0f} steps/s in total",
            flush=True,
        )
    learner = learner_frames_per_s(args)
    row = {
        "env": args.env,
        "agent": args.condition,
        "cameras": args.cameras,
        "state": args.state,
        "actors": args.actors,
        "envs_per_actor": args.envs_per_actor,
        "env_threads": args.env_threads,
        "backend": args.backend,
        "train_options": args.train_options,
        "env_steps_per_s": bare,
        **learner,
        "ratio": learner["learner_frames_per_s"] / bare,
        "parallel_env_steps_per_s": parallel,
        "ratio_to_parallel": learner["learner_frames_per_s"] / parallel,
        "batched_env_steps_per_s": batched,
        "ratio_to_batched": None if batched is None else learner["learner_frames_per_s"] / batched,
        "compared_with": (
            f"{max(1, args.actors)} bare environment processes stepping at "
            f"once on the same machine (ratio_to_parallel); ratio is against "
            f"one process, for reference"
        ),
    }
    n = max(1, args.actors)
    print(
        f"{'env':<18} {'agent':<15} {'learner frames/s':>16} "
        f"{f'{n} bare procs steps/s':>20} {'ratio to them':>13} {'1 proc steps/s':>14} "
        f"{'ratio to 1':>10} {'updates':>7}"
    )
    print(
        f"{row['env']:<18} {row['agent']:<15} {row['learner_frames_per_s']:>16,.0f} "
        f"{parallel:>20,.0f} {row['ratio_to_parallel']:>13.2f} {bare:>14,.0f} "
        f"{row['ratio']:>10.2f} {row['updates']:>7}"
    )
    print(
        f"learner frames/s are compared with {n} bare environment processes stepping at once "
        f"(as many as the actors): {row['ratio_to_parallel']:.2f}"
    )
    if batched is not None:
        print(
            f"and with the same batch stepping alone on {args.env_threads} threads: "
            f"{row['ratio_to_batched']:.2f}"
        )
    if args.json:
        write_json(args.json, row)
    return 0


def main(argv=None) -> int:
    """Measures, prints the table, writes ``--json``; bad input: one line on
    stderr, exit status 2, before anything is measured."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
