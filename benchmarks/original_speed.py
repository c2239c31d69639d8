"""This library's environments side by side with the original implementation's.

    PYTHONPATH=/tmp/peer python benchmarks/original_speed.py [--steps 600]
        [--rounds 2] [--json results/original_speed.json]

The original (DeepMind's physics_planning_games, built by
``../shared/peer/setup.sh`` into /tmp/peer with its Boxoban cache) and this
library run in one process on the same kind of task, the same physics
timestep (the original's: 1 ms MuJoBan, 2 ms board games) and the same
cameras, with random actions held for 10 control steps (one seeded
sequence for both). They alternate in chunks of 50 control steps, so both
see the same machine load, for ``--steps`` steps each per round; resets are
excluded. Pairs:

* MuJoBan on real Boxoban levels (10x10, 4 boxes; ``unfiltered-valid-000``:
  the original's cache, our shipped file), without and with grid pegs, no
  camera; and with the 96x96 top camera alone;
* MuJoXO (tic-tac-toe against the mixture opponent) and MuJoGo 7x7 without
  cameras (the original's camera observables disabled), and with the
  original code's two 84x84 views (``front_camera``, ``front_camera_2``):
  ours at its default looks and at the original's looks
  (``multisamples=4, shadows=True``; see README, "Looks of the board games").

``x_original`` is our control steps/s over the original's, per round.
Nothing else should run on the machine. Prints a table and, with --json,
writes ``{"provenance", "steps", "rounds", "rows": [...]}``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

import envs  # noqa: E402
import numpy as np  # noqa: E402
from envs.mujoban.levels import BOXOBAN_DIR  # noqa: E402

PROG = prog(__file__)
CHUNK = 50
BOXOBAN_FILE = BOXOBAN_DIR / "unfiltered-valid-000.txt"


def _original_mujoban(pegs: bool, camera: int):
    from dm_control import composer
    from dm_control.locomotion import walkers
    from physics_planning_games.mujoban.boxoban import boxoban_level_generator
    from physics_planning_games.mujoban.mujoban import Mujoban
    from physics_planning_games.mujoban.mujoban_level import MujobanLevel

    walker = walkers.JumpingBallWithHead(add_ears=True, camera_height=0.25)
    task = Mujoban(
        walker=walker,
        maze=MujobanLevel(boxoban_level_generator),
        control_timestep=0.05,
        top_camera_height=camera,
        top_camera_width=camera,
        with_grid_pegs=pegs,
    )
    return composer.Environment(time_limit=45, task=task, random_state=0)


def _original_board(name: str, cameras: bool = True):
    """The original board game ``name``; ``cameras=False`` disables its camera
    observables (nothing is rendered)."""
    from physics_planning_games import board_games

    env = board_games.load(environment_name=name, seed=0)
    if not cameras:
        for key, observable in env.task.observables.items():
            if "camera" in key:
                observable.enabled = False
    return env


#: (label, our environment and overrides, the original's builder).
PAIRS = [
    (
        "MuJoBan, Boxoban levels, no camera",
        ("mujoban/level5", dict(levels=str(BOXOBAN_FILE), top_camera=None, egocentric_camera=None)),
        lambda: _original_mujoban(False, 0),
    ),
    (
        "MuJoBan, Boxoban levels with pegs, no camera",
        (
            "mujoban/level5-pegs",
            dict(levels=str(BOXOBAN_FILE), top_camera=None, egocentric_camera=None),
        ),
        lambda: _original_mujoban(True, 0),
    ),
    (
        "MuJoBan, Boxoban levels, 96x96 top camera",
        (
            "mujoban/level5",
            dict(levels=str(BOXOBAN_FILE), top_camera=(96, 96), egocentric_camera=None),
        ),
        lambda: _original_mujoban(False, 96),
    ),
    (
        "MuJoXO, no camera",
        ("mujoxo/mixture", dict(front_camera=None)),
        lambda: _original_board("tic_tac_toe_mixture_opponent_markers_features", cameras=False),
    ),
    (
        "MuJoGo 7x7, no camera",
        ("mujogo/7x7", dict(front_camera=None)),
        lambda: _original_board("go_7x7", cameras=False),
    ),
    (
        "MuJoXO, two 84x84 views, our default looks",
        ("mujoxo/mixture", dict(front_camera=(84, 84), front_camera_2=(84, 84))),
        lambda: _original_board("tic_tac_toe_mixture_opponent_markers_features"),
    ),
    (
        "MuJoXO, two 84x84 views, the original's looks",
        (
            "mujoxo/mixture",
            dict(front_camera=(84, 84), front_camera_2=(84, 84), multisamples=4, shadows=True),
        ),
        lambda: _original_board("tic_tac_toe_mixture_opponent_markers_features"),
    ),
    (
        "MuJoGo 7x7, two 84x84 views, our default looks",
        ("mujogo/7x7", dict(front_camera=(84, 84), front_camera_2=(84, 84))),
        lambda: _original_board("go_7x7"),
    ),
    (
        "MuJoGo 7x7, two 84x84 views, the original's looks",
        (
            "mujogo/7x7",
            dict(front_camera=(84, 84), front_camera_2=(84, 84), multisamples=4, shadows=True),
        ),
        lambda: _original_board("go_7x7"),
    ),
]


class _Stepper:
    """Steps an environment with the shared held random actions, resetting
    (untimed) at episode ends; ``run(n)`` returns the seconds of n steps."""

    def __init__(self, env, actions):
        self.env, self.actions, self.i = env, actions, 0
        self.timestep = env.reset()

    def run(self, n: int) -> float:
        spent = 0.0
        for _ in range(n):
            if self.timestep.last():
                self.timestep = self.env.reset()
            action = self.actions[self.i % len(self.actions)]
            self.i += 1
            t = time.perf_counter()
            self.timestep = self.env.step(action)
            spent += time.perf_counter() - t
        return spent


def _actions(spec, steps: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    held = rng.uniform(spec.minimum, spec.maximum, size=(steps // 10 + 1,) + spec.shape)
    return np.repeat(held, 10, axis=0)[:steps]


def measure_pair(ours_spec, build_original, steps: int, seed: int) -> dict:
    """Control steps/s of ours and of the original, alternating chunks."""
    name, overrides = ours_spec
    ours = envs.load(name, seed=seed, **overrides)
    original = build_original()
    try:
        actions = _actions(ours.action_spec(), steps, seed)
        # The original's walker has a third actuator (the disabled jump): 0.
        extra = original.action_spec().shape[0] - actions.shape[1]
        padded = np.pad(actions, ((0, 0), (0, extra))) if extra > 0 else actions
        a, b = _Stepper(ours, actions), _Stepper(original, padded)
        a.run(5), b.run(5)  # first frames: GL contexts, caches
        t_ours = t_orig = 0.0
        done = 0
        while done < steps:
            n = min(CHUNK, steps - done)
            t_ours += a.run(n)
            t_orig += b.run(n)
            done += n
    finally:
        ours.close()
        original.close()
    return {
        "ours_steps_per_s": round(steps / t_ours, 1),
        "original_steps_per_s": round(steps / t_orig, 1),
        "x_original": round(t_orig / t_ours, 2),
    }


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--steps",
        type=cli.positive_int,
        default=600,
        help="control steps per pair, per side and round",
    )
    parser.add_argument("--rounds", type=cli.positive_int, default=2)
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    cli.output_file(args.json, "--json")
    try:
        import physics_planning_games  # noqa: F401  (the original, from PYTHONPATH)
    except ImportError:
        raise cli.UsageError(
            "the original (physics_planning_games) is not importable: build "
            "it with ../shared/peer/setup.sh and run with "
            "PYTHONPATH=/tmp/peer"
        ) from None
    rows = []
    print(f"{'pair':<50} {'round':>5} {'ours/s':>8} {'original/s':>10} {'x orig':>7}")
    for label, ours_spec, build_original in PAIRS:
        for r in range(args.rounds):
            m = measure_pair(ours_spec, build_original, args.steps, args.seed)
            rows.append(
                {
                    "pair": label,
                    "round": r + 1,
                    "env": ours_spec[0],
                    "overrides": {k: v for k, v in ours_spec[1].items() if k != "levels"},
                    "levels": Path(ours_spec[1]["levels"]).name
                    if "levels" in ours_spec[1]
                    else None,
                    **m,
                }
            )
            print(
                f"{label:<50} {r + 1:>5} {m['ours_steps_per_s']:>8.1f} "
                f"{m['original_steps_per_s']:>10.1f} {m['x_original']:>6.1f}x",
                flush=True,
            )
    if args.json:
        write_json(
            args.json, {"steps": args.steps, "rounds": args.rounds, "seed": args.seed, "rows": rows}
        )
    return 0


def main(argv=None) -> int:
    """Measures and prints; exit status 0, 2 with one line on stderr for bad input."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
