"""Control steps per second of batched environments (`envs.vector`) against
one environment and gymnasium's vector environments.

For each environment (cameras off, ``obs="state"``) this measures the
control steps per second summed over all environments of

* ``single``: one `envs.GymnasiumEnv` stepped in this process;
* ``processes``: N processes (``--processes``), each stepping its own
  environment as ``single`` does, all at once, nothing exchanged: what N
  cores give N independent environments on this machine, the ceiling of
  any way of spreading environments over them;
* ``async``: gymnasium's ``AsyncVectorEnv`` of N processes (``--async``);
* ``sync``: gymnasium's ``SyncVectorEnv`` of N (``--sync``), one after another;
* ``batched``: `envs.vector.BatchedVectorEnv` of N (``--sizes``) with each
  ``--threads`` count (the physics of the N in parallel threads).

Every setup steps random actions in [-1, 1] held for 10 steps, drawn from
``--seed``, for ``--seconds`` of wall time (resets included: episodes last
900 steps). The in-process setups share one set of built environments. A
round measures every other setup once, in the order above, with ``single``
measured for half as long before the first and after each: a setup's ratio
to ``single`` is to the mean of the two single measurements around it, so
that both saw the same machine load, and its ratio to ``async`` of 2 is the
quotient of the two's ratios to ``single``. A row reports the medians over
``--rounds`` rounds (``single``: over all its measurements).

    python benchmarks/vector_speed.py [--json PATH] [--envs NAME ...] [--sizes N ...]
        [--threads T ...] [--processes N ...] [--async N ...] [--sync N ...]
        [--seconds S] [--rounds R]
        [--seed SEED]

Prints a table and, with --json, writes ``{"provenance": {...}, "rows": [...]}``;
each row has env, setup, num_envs, threads (None but for batched),
steps_per_s (median), steps_per_s_rounds (each measurement), x_single and
x_async2 (medians of the per-round ratios; None without an ``async`` of 2).
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import env_cli, cli, make_parser, prog, write_json  # noqa: E402

import envs  # noqa: E402
import gymnasium  # noqa: E402
import numpy as np  # noqa: E402
from envs import GymnasiumEnv  # noqa: E402
from envs.vector import BatchedVectorEnv  # noqa: E402

PROG = prog(__file__)
HOLD = 10  # control steps each random action is held


class _Single:
    """One `GymnasiumEnv` with the vector API's shape: actions (1, A)."""

    num_envs = 1

    def __init__(self, env: GymnasiumEnv):
        self.env = env

    def reset(self, seed=None):
        return self.env.reset(seed=seed)

    def step(self, actions):
        out = self.env.step(actions[0])
        if out[2] or out[3]:
            self.env.reset()
        return out


def _process_worker(name: str, options: dict, conn, barrier) -> None:
    """A `_Processes` worker: builds its environment, then for each
    ``(actions, seconds)`` received sends back `_rate` of it, started with
    the others (``barrier``); None stops it. An exception is sent back as its
    text (and the barrier broken, so the others do not wait for this one)."""
    env = None
    try:
        env = _Single(GymnasiumEnv(name, **options))
        while (message := conn.recv()) is not None:
            actions, seconds = message
            barrier.wait(timeout=60)  # a sibling that died breaks it
            conn.send(_rate(env, actions, seconds))
    except Exception as exc:  # reported to the parent, which raises it
        barrier.abort()
        conn.send(f"{type(exc).__name__}: {exc}")
    finally:
        if env is not None:
            env.env.close()


class _Processes:
    """``num_envs`` processes, each stepping its own environment; `rate` is
    their summed steps/s, all stepping at once.

    `rate` raises `RuntimeError` naming the worker and its error (or exit
    code) when a worker fails or dies; `close` then stops the others."""

    def __init__(self, name: str, options: dict, num_envs: int):
        import multiprocessing as mp

        self.num_envs = num_envs
        # Kept: freed here, its shared memory could be reused under the workers.
        self._barrier = barrier = mp.Barrier(num_envs)
        self._conns, self._procs = [], []
        for _ in range(num_envs):
            mine, theirs = mp.Pipe()
            proc = mp.Process(target=_process_worker, args=(name, options, theirs, barrier))
            proc.start()
            self._conns.append(mine)
            self._procs.append(proc)

    def rate(self, actions: np.ndarray, seconds: float) -> float:
        """Summed steps/s; process i steps column i of ``actions`` (steps, N, A)."""
        sent = []
        for i, conn in enumerate(self._conns):
            try:
                conn.send((actions[:, i : i + 1], seconds))
                sent.append(True)
            except OSError:  # the worker is gone
                sent.append(False)
        replies = [self._reply(conn) if ok else None for conn, ok in zip(self._conns, sent)]
        failed = [i for i, reply in enumerate(replies) if not isinstance(reply, float)]
        if failed:
            # The worker that failed first, not the others its broken barrier stopped.
            i = min(failed, key=lambda k: "BrokenBarrierError" in str(replies[k]))
            self._procs[i].join(timeout=5)
            why = replies[i] if replies[i] else f"exit code {self._procs[i].exitcode}"
            raise RuntimeError(f"benchmark worker process {i} of {self.num_envs} failed: {why}")
        return float(sum(replies))

    @staticmethod
    def _reply(conn) -> float | str | None:
        """The worker's reply: its rate, its error's text, or None if it died."""
        try:
            return conn.recv()
        except (EOFError, OSError):
            return None

    def close(self) -> None:
        for conn, proc in zip(self._conns, self._procs):
            try:
                conn.send(None)
            except OSError:  # a worker already gone
                pass
            proc.join(timeout=10)
            if proc.is_alive():
                proc.terminate()
                proc.join()


def _actions(rng: np.random.Generator, n: int, dim: int, steps: int = 400) -> np.ndarray:
    """(steps, n, dim) float32 actions in [-1, 1], each held `HOLD` steps."""
    held = rng.uniform(-1, 1, size=(steps // HOLD + 1, n, dim)).astype(np.float32)
    return np.repeat(held, HOLD, axis=0)[:steps]


def _rate(setup, actions: np.ndarray, seconds: float) -> float:
    """Control steps per second (all environments) of ``setup`` stepping
    ``actions`` (cycled) for ``seconds``, after a reset and a warm-up step."""
    if isinstance(setup, _Processes):
        return setup.rate(actions, seconds)
    setup.reset(seed=0)
    setup.step(actions[0])
    steps, start = 0, time.perf_counter()
    while True:
        setup.step(actions[steps % len(actions)])
        steps += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return steps * setup.num_envs / elapsed


def _setups(name: str, args) -> tuple[dict, list]:
    """``{(setup, num_envs, threads): vector env}`` for ``name`` (the
    processes of ``processes`` and ``async`` forked first, before any thread
    starts) and everything to close."""
    options = {"obs": "state", **envs.no_cameras(name)}

    def thunk():
        return GymnasiumEnv(name, **options)

    setups: dict = {}
    for n in args.process_counts:
        setups[("processes", n, None)] = _Processes(name, options, n)
    for n in args.async_sizes:
        setups[("async", n, None)] = gymnasium.vector.AsyncVectorEnv([thunk] * n)
    built = [thunk() for _ in range(max([1, *args.sizes, *args.sync_sizes]))]
    setups[("single", 1, None)] = _Single(built[0])
    for n in args.sync_sizes:
        # SyncVectorEnv takes thunks; these return the environments built above.
        setups[("sync", n, None)] = gymnasium.vector.SyncVectorEnv(
            [lambda env=env: env for env in built[:n]]
        )
    for n in args.sizes:
        for threads in args.threads:
            setups[("batched", n, threads)] = BatchedVectorEnv(built[:n], threads=threads)
    order = ["single", "processes", "async", "sync", "batched"]
    setups = dict(sorted(setups.items(), key=lambda kv: order.index(kv[0][0])))
    closers = [s for key, s in setups.items() if key[0] != "single"] + built
    return setups, closers


SINGLE = ("single", 1, None)
ASYNC2 = ("async", 2, None)


def measure(name: str, args) -> list[dict]:
    """The rows of environment ``name``: one per setup, over ``args.rounds`` rounds."""
    setups, closers = _setups(name, args)
    try:
        dim = setups[SINGLE].env.action_space.shape[0]
        rng = np.random.default_rng(args.seed)
        actions = {key: _actions(rng, key[1], dim) for key in setups}
        rates: dict = {key: [] for key in setups}
        x_single: dict = {key: [] for key in setups}

        def single() -> float:
            rates[SINGLE].append(_rate(setups[SINGLE], actions[SINGLE], args.seconds / 2))
            return rates[SINGLE][-1]

        for _ in range(args.rounds):
            before = single()
            for key, setup in setups.items():
                if key == SINGLE:
                    continue
                rates[key].append(_rate(setup, actions[key], args.seconds))
                after = single()
                x_single[key].append(rates[key][-1] / ((before + after) / 2))
                before = after
    finally:
        for setup in closers:
            setup.close()
    x_single[SINGLE] = [1.0] * args.rounds
    return [_row(name, key, rates[key], x_single) for key in setups]


def _row(name: str, key: tuple, rates: list[float], x_single: dict) -> dict:
    """A setup's row: its steps/s, and its ratios to `SINGLE` (each to the
    mean of the single measurements just before and after it) and to
    `ASYNC2` (the quotient of the two's ratios to single, per round)."""
    setup, n, threads = key
    mine = x_single[key]
    x_async2 = None
    if ASYNC2 in x_single:
        x_async2 = round(statistics.median(a / b for a, b in zip(mine, x_single[ASYNC2])), 3)
    return {
        "env": name,
        "setup": setup,
        "num_envs": n,
        "threads": threads,
        "steps_per_s": round(statistics.median(rates), 1),
        "steps_per_s_rounds": [round(r, 1) for r in rates],
        "x_single": round(statistics.median(mine), 3),
        "x_async2": x_async2,
    }


def _print_header() -> None:
    header = (
        f"{'env':<16} {'setup':<9} {'N':>3} {'threads':>7} {'steps/s':>9} "
        f"{'x single':>8} {'x async2':>8}"
    )
    print(header)
    print("-" * len(header), flush=True)


def _print_row(row: dict) -> None:
    threads = "" if row["threads"] is None else row["threads"]
    x_async = "" if row["x_async2"] is None else f"{row['x_async2']:.2f}"
    print(
        f"{row['env']:<16} {row['setup']:<9} {row['num_envs']:>3} {threads:>7} "
        f"{row['steps_per_s']:>9.1f} {row['x_single']:>8.2f} {x_async:>8}",
        flush=True,
    )


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument("--json", type=Path, help="write the rows here")
    parser.add_argument(
        "--envs",
        nargs="+",
        default=["mujoban/level1", "mujoban/level5"],
        metavar="NAME",
        help="environment names",
    )
    counts = {"type": cli.positive_int, "nargs": "+", "metavar": "N"}
    parser.add_argument("--sizes", default=[1, 2, 4, 8, 16, 32], help="batched N", **counts)
    parser.add_argument("--threads", default=[1, 2], help="batched threads", **counts)
    parser.add_argument(
        "--processes",
        dest="process_counts",
        default=[2],
        help="independent environment processes at once",
        **counts,
    )
    parser.add_argument(
        "--async", dest="async_sizes", default=[2, 16], help="AsyncVectorEnv N", **counts
    )
    parser.add_argument("--sync", dest="sync_sizes", default=[16], help="SyncVectorEnv N", **counts)
    parser.add_argument(
        "--seconds", type=cli.positive_float, default=1.0, help="wall seconds per measurement"
    )
    parser.add_argument(
        "--rounds", type=cli.positive_int, default=3, help="rounds over every setup"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the actions")
    args = parser.parse_args(argv)
    for name in args.envs:
        env_cli.environment(name)
    cli.output_file(args.json, "--json")
    _print_header()
    rows = []
    for name in args.envs:
        rows += measure(name, args)
        for row in rows:
            if row["env"] == name:
                _print_row(row)
    if args.json:
        write_json(args.json, rows)
    return 0


def main(argv=None) -> int:
    """Measures, prints the table, writes ``--json``; bad input: one line on
    stderr, exit status 2, before anything is measured."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
