"""What cheaper solver settings could give the board games' physics: raw ``mj_step`` rates.

    python benchmarks/board_physics.py [--envs mujoxo/optimal mujogo/7x7]
        [--steps 5000] [--rounds 3] [--json results/board_physics.json]

For each board environment (cameras off, after one reset), copies its
compiled model and data and times raw ``mujoco.mj_step`` on the copy, from
the reset state, with random controls within the actuators' ranges held for
one control step (the task's substeps), under each setting of `SETTINGS`:

* ``default``: the model as the environment compiles it;
* ``noslip_iterations=0``: no noslip solver (MuJoBan's cheaper option);
* ``pyramidal cones``: pyramidal instead of elliptic friction cones;
* ``contacts off``: no collision detection or contact at all. Not a
  candidate (the arm must touch the board): the most that pruning collision
  pairs could give.

Settings alternate within each round, so every ratio to ``default`` compares
rates measured under the same machine load. Nothing here is checked against
the original's behaviour; a setting worth more than its bound would need the
touch rules' checks. Prints a table (median rate and the ratio's range over
rounds) and writes ``{"provenance", "steps", "rounds", "rows": [{"env",
"setting", "mj_steps_per_s", "x_default_rounds"}]}`` with --json.
"""

from __future__ import annotations

import copy
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import cli, env_cli, make_parser, prog, write_json  # noqa: E402

import envs  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

PROG = prog(__file__)


def _noslip_off(model) -> None:
    model.opt.noslip_iterations = 0


def _pyramidal(model) -> None:
    model.opt.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL


def _contacts_off(model) -> None:
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)


#: label -> a change of a copied model (None: the model as compiled).
SETTINGS = {
    "default": None,
    "noslip_iterations=0": _noslip_off,
    "pyramidal cones": _pyramidal,
    "contacts off (bound, not a candidate)": _contacts_off,
}


def rate(model, start, steps: int, hold: int, seed: int) -> float:
    """Raw ``mj_step`` calls per second on a copy of ``start`` (an MjData)."""
    data = copy.copy(start)
    rng = np.random.default_rng(seed)
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    began = time.perf_counter()
    for i in range(steps):
        if i % hold == 0:
            data.ctrl[:] = rng.uniform(low, high)
        mujoco.mj_step(model, data)
    return steps / (time.perf_counter() - began)


def measure(name: str, steps: int, rounds: int) -> list[dict]:
    """The rows of one environment (module docstring)."""
    env = envs.load(name, seed=0, **envs.no_cameras(name))
    try:
        env.reset()
        physics = env.physics
        hold = max(1, round(env.control_timestep / physics.model.opt.timestep))
        models = {}
        for label, change in SETTINGS.items():
            model = copy.copy(physics.model.ptr)
            if change is not None:
                change(model)
            models[label] = model
        start = physics.data.ptr
        rates: dict[str, list[float]] = {label: [] for label in SETTINGS}
        for r in range(rounds):
            for label, model in models.items():
                rates[label].append(rate(model, start, steps, hold, seed=r))
    finally:
        env.close()
    return [
        {
            "env": name,
            "setting": label,
            "mj_steps_per_s": round(statistics.median(values), 1),
            "x_default_rounds": [
                round(v / d, 3) for v, d in zip(values, rates["default"], strict=True)
            ],
        }
        for label, values in rates.items()
    ]


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    boards = [n for n in envs.names() if not n.startswith("mujoban/")]
    parser.add_argument(
        "--envs", nargs="+", default=["mujoxo/optimal", "mujogo/7x7"], metavar="NAME"
    )
    parser.add_argument("--steps", type=cli.positive_int, default=5000, help="mj_step calls")
    parser.add_argument("--rounds", type=cli.positive_int, default=3)
    parser.add_argument("--json", type=Path, help="write the rows here")
    args = parser.parse_args(argv)
    for name in args.envs:
        env_cli.environment(name, boards)
    cli.output_file(args.json, "--json")
    rows = []
    print(f"{'env':16} {'setting':40} {'mj_step/s':>10}  x default")
    for name in args.envs:
        for row in measure(name, args.steps, args.rounds):
            ratios = row["x_default_rounds"]
            print(
                f"{row['env']:16} {row['setting']:40} {row['mj_steps_per_s']:10.0f}  "
                f"{min(ratios):.2f}-{max(ratios):.2f}x",
                flush=True,
            )
            rows.append(row)
    if args.json:
        write_json(args.json, {"steps": args.steps, "rounds": args.rounds, "rows": rows})
    return 0


def main(argv=None) -> int:
    """Measures, prints the table, writes ``--json``; bad input: one line on
    stderr, exit status 2, before anything is measured."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
