"""Parallel evaluation: ``hier_agents.run --workers N`` against one worker, same table.

    python benchmarks/parallel_eval.py [--workers 1 2] [--episodes 200]
        [--env mujoban/level5-pegs] [--levels FILE] [--json results/parallel_eval.json]

Runs the command ``python -m hier_agents.run ENV --levels FILE --episodes N
--workers W --json ...`` once per worker count, as a user would (the wall
time includes starting Python, the worker processes and their agents), and
reports per count: the wall seconds, episodes per second, the speed-up over
the first count, the success rate, and whether its per-episode rows equal
the first count's (everything but each episode's wall time). Nothing else
should run on the machine meanwhile: the speed-up is a share of its CPUs.
The default levels are the first ``--episodes`` of the shipped Boxoban
``unfiltered-valid-000.txt``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import env_cli, cli, make_parser, prog, write_json  # noqa: E402

PROG = prog(__file__)
ROOT = Path(__file__).resolve().parents[1]
LEVELS = ROOT / "envs" / "mujoban" / "data" / "boxoban" / "unfiltered-valid-000.txt"


def _rows(summary: dict) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in summary["rows"]]


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument("--env", default="mujoban/level5-pegs")
    parser.add_argument("--levels", type=cli.existing_file, default=str(LEVELS))
    parser.add_argument("--episodes", type=cli.positive_int, default=200)
    parser.add_argument("--workers", type=cli.positive_int, nargs="+", default=[1, 2])
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    env_cli.environment(args.env)
    env_cli.levels_file(args.env, args.levels)
    cli.output_file(args.json, "--json")
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p),
    }
    out, first = [], None
    with tempfile.TemporaryDirectory() as tmp:
        for workers in args.workers:
            path = Path(tmp) / f"w{workers}.json"
            command = [
                sys.executable,
                "-m",
                "hier_agents.run",
                args.env,
                "--levels",
                str(args.levels),
                "--episodes",
                str(args.episodes),
                "--seed",
                str(args.seed),
                "--workers",
                str(workers),
                "--json",
                str(path),
            ]
            print(f"{workers} worker(s): {' '.join(command[1:])}", file=sys.stderr, flush=True)
            start = time.perf_counter()
            subprocess.run(command, check=True, env=env, cwd=ROOT, stdout=subprocess.DEVNULL)
            wall = time.perf_counter() - start
            summary = json.loads(path.read_text())
            rows = _rows(summary)
            if first is None:
                first = {"wall_s": wall, "rows": rows}
            out.append(
                {
                    "workers": workers,
                    "episodes": summary["episodes"],
                    "wall_s": wall,
                    "episodes_per_s": summary["episodes"] / wall,
                    "speedup": first["wall_s"] / wall,
                    "success_rate": summary["success_rate"],
                    "rows_identical_to_first": rows == first["rows"],
                }
            )
    print(
        f"{'workers':>7} {'episodes':>8} {'wall s':>8} {'episodes/s':>10} {'speed-up':>8} "
        f"{'success %':>9}  same rows"
    )
    for r in out:
        print(
            f"{r['workers']:>7} {r['episodes']:>8} {r['wall_s']:>8.1f} "
            f"{r['episodes_per_s']:>10.3f} {r['speedup']:>8.2f} {100 * r['success_rate']:>9.1f}"
            f"  {'yes' if r['rows_identical_to_first'] else 'NO'}"
        )
    if args.json:
        write_json(
            args.json,
            {
                "env": args.env,
                "levels": str(Path(args.levels).name),
                "seed": args.seed,
                "cpus": os.cpu_count(),
                "rows": out,
            },
        )
    return 0 if all(r["rows_identical_to_first"] for r in out) else 1


def main(argv=None) -> int:
    """Runs the command per worker count, prints the table, writes ``--json``;
    exit status 1 when some count's rows differ from the first's."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
