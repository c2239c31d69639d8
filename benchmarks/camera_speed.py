"""Control steps/s with the paper's cameras, this code beside an earlier commit's.

    python benchmarks/camera_speed.py --baseline REF [--steps 1500] [--rounds 2]
        [--json results/camera_speed.json]

Settings (each environment at its default looks and physics timestep):
MuJoBan level 5 with the 96x96 top camera (the paper's view of the whole
level), MuJoXO and MuJoGo 7x7 with the original code's two 84x84 views.
Per round and setting, ``benchmarks/env_speed.py`` runs once from this
checkout and once from a git worktree of commit REF (made in a temporary
folder, removed after), one after the other, so both see the same machine
load; ``x_baseline`` is this code's steps/s over the baseline's, per round.
Before the second board view existed as a camera, env_speed rendered the
first view twice per step for the same count of frames; against such a
baseline that setting is used. Nothing else should run on the machine.

Prints a table and, with --json, writes ``{"provenance", "baseline",
"steps", "rows": [...]}``.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import (
    baseline_worktree,
    cli,
    make_parser,
    prog,
    remove_worktree,  # noqa: E402
    run_in_tree,
    write_json,
)

PROG = prog(__file__)
SETTINGS = [
    ("mujoban/level5", "top_camera"),
    ("mujoxo/mixture", "front_camera+front_camera_2"),
    ("mujogo/7x7", "front_camera+front_camera_2"),
]
#: The same frames per step in an env_speed.py without ``front_camera_2``.
OLDER_NAME = {"front_camera+front_camera_2": "front_camera+second_view"}


def _setting_in(tree: Path, setting: str) -> str:
    text = (tree / "benchmarks" / "env_speed.py").read_text()
    return setting if f'"{setting}"' in text else OLDER_NAME.get(setting, setting)


def measure(tree: Path, env_name: str, setting: str, steps: int, tmp: Path) -> float:
    """Control steps/s of ``env_name`` with camera ``setting``, run from ``tree``."""
    out = tmp / "speed.json"
    run_in_tree(
        tree,
        [
            sys.executable,
            "benchmarks/env_speed.py",
            "--envs",
            env_name,
            "--cameras",
            _setting_in(tree, setting),
            "--steps",
            str(steps),
            "--json",
            str(out),
        ],
        timeout=3600,
    )
    return float(json.loads(out.read_text())["rows"][0]["steps_per_s"])


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--baseline",
        metavar="REF",
        required=True,
        help="the git commit to measure beside this checkout",
    )
    parser.add_argument("--steps", type=cli.positive_int, default=1500)
    parser.add_argument("--rounds", type=cli.positive_int, default=2)
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    cli.output_file(args.json, "--json")
    root = Path(__file__).resolve().parents[1]
    rows = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        baseline = baseline_worktree(args.baseline, tmp)
        try:
            print(
                f"{'environment':<16} {'cameras':<28} {'round':>5} {'this':>8} "
                f"{'baseline':>9} {'x':>6}"
            )
            for env_name, setting in SETTINGS:
                for r in range(args.rounds):
                    ours = measure(root, env_name, setting, args.steps, tmp)
                    theirs = measure(baseline, env_name, setting, args.steps, tmp)
                    rows.append(
                        {
                            "env": env_name,
                            "cameras": setting,
                            "round": r + 1,
                            "steps_per_s": ours,
                            "baseline_steps_per_s": theirs,
                            "baseline_cameras": _setting_in(baseline, setting),
                            "x_baseline": round(ours / theirs, 3),
                        }
                    )
                    print(
                        f"{env_name:<16} {setting:<28} {r + 1:>5} {ours:>8.1f} "
                        f"{theirs:>9.1f} {ours / theirs:>5.2f}x",
                        flush=True,
                    )
        finally:
            remove_worktree(baseline)
    if args.json:
        write_json(
            args.json,
            {"baseline": args.baseline, "steps": args.steps, "rounds": args.rounds, "rows": rows},
        )
    return 0


def main(argv=None) -> int:
    """Measures and prints; exit status 0, 2 with one line on stderr for bad input."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
