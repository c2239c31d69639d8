"""Abstract Go matches (no physics) between planners, scored by OpenSpiel.

Each game is played on OpenSpiel's go with the given board size and komi
until it ends (two passes in a row, or OpenSpiel's move cap of 2*N*N), and
scored with ``state.returns()`` (Tromp-Taylor area scoring, no dead-stone
removal). Games are seeded: game ``i`` resets Black with seed ``S + 2i`` and
White with ``S + 2i + 1`` (``S = --seed``).

    python benchmarks/go_planners.py [--games N] [--board-size 7] [--komi 5.5]
        [--black SPEC ...] [--white gnugo:10] [--mcts-sweep 100,300,1000]
        [--seed 0] [--json PATH]

Planner specs: ``random``; ``gnugo[:LEVEL]`` (GNU Go, level 1..10, default
10); ``mcts[:SIMULATIONS[:ROLLOUTS]]`` (OpenSpiel MCTS with random rollouts,
default 1000 simulations, 1 rollout). ``--no-cleanup`` makes GNU Go use plain
``genmove`` instead of ``kgs-genmove_cleanup``.

For every Black spec (against the one White spec) it prints a row: games,
Black wins, Black's win rate with a 95% Wilson interval, mean game length in
moves, the median and 95th-percentile wall time of GNU Go's genmove (ms, over
both colours' GNU Go moves) and the median and mean of Black's moves (ms, what
an agent planning with it waits per move). ``--json``
writes ``{"provenance", "rows"}`` with these rows (keys: black, white,
board_size, komi, games, black_wins, win_rate, ci_low, ci_high, mean_moves,
gnugo_ms_median, gnugo_ms_p95, black_ms_median, black_ms_mean, seconds).

``--mcts-sweep 100,300,1000,...`` adds Black specs ``mcts:N`` for each N
(against ``--white``, GNU Go level 10 by default) and then reports the
smallest N reaching a win rate >= 50% and >= 90% (or that none did).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from abstract_planners.board_random import RandomMovePlanner  # noqa: E402
from abstract_planners.go import GnuGoPlanner, MCTSPlanner, go_game  # noqa: E402

PROG = prog(__file__)


def parse_spec(spec: str) -> tuple[str, tuple[int, ...]]:
    """(name, integer arguments) of a planner spec (module docstring).

    Raises:
      physics_planning.cli.UsageError: an unknown planner, too many arguments, or an
        argument out of range (GNU Go level 1..10, simulations and rollouts >= 1).
    """
    name, *texts = spec.strip().lower().split(":")
    forms = {"random": 0, "gnugo": 1, "mcts": 2}
    if name not in forms or len(texts) > forms[name]:
        raise cli.UsageError(
            f"bad planner spec {spec!r}"
            f"{cli.close_hint(name, forms) if name not in forms else ''}; "
            f"use random, gnugo[:LEVEL] or mcts[:SIMULATIONS[:ROLLOUTS]]"
        )
    limits = {"gnugo": [(1, 10)], "mcts": [(1, None), (1, None)]}.get(name, [])
    args = []
    for text, (low, high) in zip(texts, limits):
        value = int(text) if text.strip().lstrip("-").isdigit() else None
        if value is None or value < low or (high is not None and value > high):
            allowed = f"{low}..{high}" if high is not None else f">= {low}"
            raise cli.UsageError(f"bad planner spec {spec!r}: {text!r} is not an integer {allowed}")
        args.append(value)
    return name, tuple(args)


def make_planner(spec: str, *, board_size: int, komi: float, cleanup: bool = True):
    """A planner from a spec string (see the module docstring; `parse_spec`)."""
    name, args = parse_spec(spec)
    if name == "random":
        return RandomMovePlanner()
    if name == "gnugo":
        level = args[0] if args else 10
        return GnuGoPlanner(level, board_size=board_size, komi=komi, cleanup=cleanup)
    simulations = args[0] if args else 1000
    rollouts = args[1] if len(args) > 1 else 1
    return MCTSPlanner(simulations, rollouts=rollouts)


def wilson_interval(wins: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """The 95% Wilson score interval of a binomial proportion."""
    if n == 0:
        return (0.0, 1.0)
    p = wins / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


def play_game(game, black, white, seed: int) -> tuple[float, int, list[float], list[float]]:
    """One seeded game; returns (Black's return, moves, GNU Go's genmove ms, Black's ms)."""
    black.reset(seed)
    white.reset(seed + 1)
    state = game.new_initial_state()
    gnugo_ms, black_ms = [], []
    while not state.is_terminal():
        mover = black if state.current_player() == 0 else white
        start = time.perf_counter()
        subgoal = mover.plan(state)
        ms = (time.perf_counter() - start) * 1e3
        if isinstance(mover, GnuGoPlanner):
            gnugo_ms.append(subgoal.info["ms"])
        if mover is black:
            black_ms.append(ms)
        state = subgoal.state
    return state.returns()[0], len(state.history()), gnugo_ms, black_ms


def _fmt(value, digits=0):
    return "-" if value is None else f"{value:.{digits}f}"


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument("--games", type=cli.positive_int, default=10, help="games per Black spec")
    parser.add_argument("--board-size", type=cli.positive_int, default=7)
    parser.add_argument("--komi", type=float, default=5.5)
    parser.add_argument(
        "--black",
        nargs="+",
        default=None,
        metavar="SPEC",
        help="Black planner specs (default: random, unless --mcts-sweep)",
    )
    parser.add_argument(
        "--white", default="gnugo:10", metavar="SPEC", help="the White planner spec"
    )
    parser.add_argument(
        "--mcts-sweep",
        default=None,
        metavar="N,N,...",
        help="comma-separated MCTS simulation counts to play as Black",
    )
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument(
        "--no-cleanup",
        action="store_true",
        help="GNU Go uses genmove instead of kgs-genmove_cleanup",
    )
    parser.add_argument("--json", type=Path, default=None, help="write the rows here")
    args = parser.parse_args(argv)
    try:
        game = go_game(args.board_size, args.komi)
    except ValueError as exc:
        raise cli.UsageError(str(exc)) from None

    sweep = []
    if args.mcts_sweep:
        try:
            sweep = [cli.positive_int(x) for x in args.mcts_sweep.split(",") if x.strip()]
        except argparse.ArgumentTypeError:
            raise cli.UsageError(
                f"--mcts-sweep takes comma-separated integers >= 1, got {args.mcts_sweep!r}"
            ) from None
    blacks = list(args.black) if args.black is not None else ([] if sweep else ["random"])
    blacks += [f"mcts:{n}" for n in sweep]
    if not blacks:
        raise cli.UsageError("no Black planner: give --black or --mcts-sweep")
    for spec in blacks + [args.white]:
        parse_spec(spec)
    cli.output_file(args.json, "--json")

    kwargs = dict(board_size=args.board_size, komi=args.komi, cleanup=not args.no_cleanup)
    white = make_planner(args.white, **kwargs)
    rows = []
    bar = tqdm(total=args.games * len(blacks), unit="game", file=sys.stderr)
    try:
        for spec in blacks:
            black = make_planner(spec, **kwargs)
            wins, moves, gnugo_ms, black_ms = 0, [], [], []
            start = time.perf_counter()
            bar.set_description(f"{spec} vs {args.white}")
            try:
                for index in range(args.games):
                    seed = args.seed + 2 * index
                    result, n_moves, g_ms, b_ms = play_game(game, black, white, seed)
                    wins += result > 0
                    moves.append(n_moves)
                    gnugo_ms += g_ms
                    black_ms += b_ms
                    bar.update()
            finally:
                black.close()
            low, high = wilson_interval(wins, args.games)
            rows.append(
                dict(
                    black=spec,
                    white=args.white,
                    board_size=args.board_size,
                    komi=args.komi,
                    games=args.games,
                    black_wins=int(wins),
                    win_rate=wins / args.games,
                    ci_low=round(low, 4),
                    ci_high=round(high, 4),
                    mean_moves=float(np.mean(moves)),
                    gnugo_ms_median=float(np.median(gnugo_ms)) if gnugo_ms else None,
                    gnugo_ms_p95=float(np.percentile(gnugo_ms, 95)) if gnugo_ms else None,
                    black_ms_median=float(np.median(black_ms)) if black_ms else None,
                    black_ms_mean=float(np.mean(black_ms)) if black_ms else None,
                    seconds=time.perf_counter() - start,
                )
            )
    finally:
        bar.close()
        white.close()

    print(
        f"\nGo {args.board_size}x{args.board_size}, komi {args.komi:g}, White = {args.white}, "
        f"{args.games} games per row, OpenSpiel (Tromp-Taylor) scoring"
    )
    header = (
        f"{'black':<14}{'games':>6}{'wins':>6}{'win rate':>10}{'95% CI':>15}"
        f"{'moves':>7}{'gnugo ms med':>14}{'p95':>8}{'black ms med':>14}{'mean':>8}"
    )
    print(header)
    print("-" * len(header))
    for row in rows:
        ci = f"[{row['ci_low']:.2f}, {row['ci_high']:.2f}]"
        print(
            f"{row['black']:<14}{row['games']:>6}{row['black_wins']:>6}{row['win_rate']:>10.2f}"
            f"{ci:>15}{row['mean_moves']:>7.1f}{_fmt(row['gnugo_ms_median'], 1):>14}"
            f"{_fmt(row['gnugo_ms_p95'], 0):>8}{_fmt(row['black_ms_median'], 1):>14}"
            f"{_fmt(row['black_ms_mean'], 0):>8}"
        )
    if sweep:
        sweep_rows = [row for row in rows if row["black"] in {f"mcts:{n}" for n in sweep}]
        for target in (0.5, 0.9):
            hit = next((row for row in sweep_rows if row["win_rate"] >= target), None)
            if hit:
                print(
                    f"MCTS reaches >= {target:.0%} wins vs {args.white} at {hit['black']} "
                    f"({hit['black_wins']}/{hit['games']})"
                )
            else:
                print(
                    f"MCTS does not reach >= {target:.0%} wins vs {args.white} up to "
                    f"{max(sweep)} simulations (best: "
                    f"{max(row['win_rate'] for row in sweep_rows):.0%})"
                )
    if args.json:
        write_json(args.json, rows)
    return 0


def main(argv=None) -> int:
    """Plays the matches, prints the table, writes ``--json``; bad input: one
    line on stderr, exit status 2, before any game."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
