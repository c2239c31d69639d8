"""MuJoBan's physical behaviour and speed for candidate physics settings, beside the original's.

    PYTHONPATH=/tmp/peer python benchmarks/physics_behaviour.py [--steps 600]
        [--rounds 1] [--json results/physics_behaviour.json]

For the original implementation (DeepMind's physics_planning_games, built by
``../shared/peer/setup.sh`` into /tmp/peer; without it only our rows are
measured) and for this library at its defaults and at each candidate
setting of `CANDIDATES` (options that make a control step cheaper), it prints:

* the behaviour quantities of `envs.mujoban.behaviour` (how far the walker
  rolls and coasts, how far it pushes a box, how far 10, 20 and 40 N slide a
  box; metres, from the same scripted scenarios on the same level), and the
  largest deviation of each setting's quantities from the original's,
  relative (or absolute, for a quantity under 0.2 m), with whether every
  quantity is within `envs.mujoban.behaviour.within_tolerance` of the original's;
* speed side by side with the original (`original_speed.measure_pair`:
  control steps/s of both in one process, alternating chunks of 50 steps,
  the same held random actions, real Boxoban levels, cameras off), without
  and with grid pegs, as ``x_original`` per round.

``--steps 0`` skips the speed rounds. Writes ``{"provenance", "steps",
"rounds", "original": {...}, "rows": [...]}`` with --json.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

import envs  # noqa: E402
from envs.mujoban import behaviour  # noqa: E402

PROG = prog(__file__)
#: Candidate settings (label -> `envs.load` overrides of MuJoBan), each
#: naming ``sleep`` so that a row means the same whatever the default;
#: ``default`` is the library's default (``sleep=True``).
CANDIDATES: dict[str, dict] = {
    "default": {},
    "sleep=False (the original's)": {"sleep": False},
    "sleep=False, noslip_iterations=0": {"sleep": False, "noslip_iterations": 0},
    "sleep=True, noslip_iterations=0": {"sleep": True, "noslip_iterations": 0},
}


def _original_env():
    """The original MuJoBan on `behaviour.LEVEL` (cameras off), reset; None if
    the original is not importable."""
    try:
        from dm_control import composer
        from dm_control.locomotion import walkers
        from physics_planning_games.mujoban.mujoban import Mujoban
        from physics_planning_games.mujoban.mujoban_level import (
            MujobanLevel,
            single_level_generator,
        )
    except ImportError:
        return None
    level = "\n".join(behaviour.LEVEL)
    task = Mujoban(
        walker=walkers.JumpingBallWithHead(add_ears=True, camera_height=0.25),
        maze=MujobanLevel(lambda: single_level_generator(level)),
        control_timestep=0.05,
        top_camera_height=0,
        top_camera_width=0,
    )
    env = composer.Environment(time_limit=45, task=task, random_state=0)
    env.reset()
    return env


def ours_env(overrides: dict, level_file: Path):
    """This library's MuJoBan on ``level_file`` (cameras off) with ``overrides``, reset."""
    env = envs.load(
        "mujoban/level1",
        seed=0,
        levels=str(level_file),
        top_camera=None,
        egocentric_camera=None,
        **overrides,
    )
    env.reset()
    return env


def measure_ours(overrides: dict, level_file: Path) -> dict[str, float]:
    """`behaviour.measure` of `ours_env`."""
    env = ours_env(overrides, level_file)
    try:
        return behaviour.measure(env.physics)
    finally:
        env.close()


def deviation(values: dict, reference: dict) -> float:
    """The largest deviation of ``values`` from ``reference``: relative, or in
    metres/0.2 m for reference values under 0.2 m (so that a box held by
    friction, which moves well under a millimetre, is not divided by ~0)."""
    return max(abs(values[q] - reference[q]) / max(abs(reference[q]), 0.2) for q in reference)


def _speed(overrides: dict, steps: int, rounds: int) -> list[dict]:
    import original_speed

    base = dict(levels=str(original_speed.BOXOBAN_FILE), top_camera=None, egocentric_camera=None)
    out = []
    for pegs in (False, True):
        name = "mujoban/level5" + ("-pegs" if pegs else "")
        for r in range(rounds):
            m = original_speed.measure_pair(
                (name, {**base, **overrides}),
                lambda pegs=pegs: original_speed._original_mujoban(pegs, 0),
                steps,
                0,
            )
            out.append({"pegs": pegs, "round": r + 1, **m})
    return out


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--steps",
        type=cli.non_negative_int,
        default=600,
        help="control steps per speed pair, per side and round (0: no speed rounds)",
    )
    parser.add_argument("--rounds", type=cli.positive_int, default=1)
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    cli.output_file(args.json, "--json")
    original_env = _original_env()
    original = behaviour.measure(original_env.physics) if original_env is not None else None
    if original_env is None:
        print("the original (physics_planning_games) is not importable: our rows only")
    elif args.steps:
        print("speed side by side with the original: Boxoban levels, cameras off")
    names = behaviour.QUANTITIES
    print(f"{'setting':<34} " + " ".join(f"{q[:-2]:>10}" for q in names) + "  max dev  x orig")
    if original:
        print(f"{'the original':<34} " + " ".join(f"{original[q]:>10.4f}" for q in names))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        level_file = Path(tmp) / "level.txt"
        level_file.write_text(behaviour.level_text())
        for label, overrides in CANDIDATES.items():
            values = measure_ours(overrides, level_file)
            row: dict = {"setting": label, "overrides": overrides, "behaviour": values}
            text = ""
            if original:
                row["max_deviation"] = round(deviation(values, original), 5)
                row["within_tolerance"] = all(
                    behaviour.within_tolerance(values[q], original[q]) for q in names
                )
                text = f"  {row['max_deviation']:>6.2%}{'' if row['within_tolerance'] else '!'}"
                if args.steps:
                    row["speed"] = _speed(overrides, args.steps, args.rounds)
                    x = [s["x_original"] for s in row["speed"]]
                    text += f"  {min(x):.1f}-{max(x):.1f}x"
            rows.append(row)
            print(f"{label:<34} " + " ".join(f"{values[q]:>10.4f}" for q in names) + text)
    if args.json:
        write_json(
            args.json,
            {
                "steps": args.steps,
                "rounds": args.rounds,
                "level": list(behaviour.LEVEL),
                "tolerance": {
                    "relative": behaviour.REL_TOLERANCE,
                    "absolute_m": behaviour.ABS_TOLERANCE_M,
                },
                "original": original,
                "rows": rows,
            },
        )
    return 0


def main(argv=None) -> int:
    """Measures and prints; exit status 0, 2 with one line on stderr for bad input."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
