"""Environment speed against the physics limit of the same compiled model.

For each environment and camera setting this measures

* ``steps_per_s``: control steps per second through ``env.step`` with a
  seeded random policy (actions held for 10 steps), resets excluded;
* ``physics_limit_steps_per_s``: the same actions replayed with raw
  ``mujoco.mj_step(model, data, n_substeps)`` on the environment's own
  compiled model from the same states (only ``data.ctrl`` is set from Python
  between calls), converted to control steps per second. Environment and raw
  stepping alternate in chunks of 50 steps so both see the same machine load;
* ``ratio`` = steps_per_s / physics_limit_steps_per_s;
* ``reset_s``: mean wall time of ``env.reset()`` after the first one (the
  first also creates the GL contexts and is reported as ``first_reset_s``).

Environments run at their defaults, which are the original's physics
timesteps (MuJoBan's sleeps resting bodies: ``--env-option sleep=False`` is the
original's physics); ``--physics-timestep`` measures another (e.g. 0.005) on purpose.
The board games observe one 84x84 front camera (the paper's); the original
code observes two, which the ``front_camera+front_camera_2`` setting
renders (the second at the original's ``front_camera_2`` pose). Figures
against the original implementation are measured side by side with it by
``benchmarks/original_speed.py``, not here.

    python benchmarks/env_speed.py [--json PATH] [--steps N] [--envs NAME ...]
        [--cameras SETTING ...] [--physics-timestep S] [--env-option KEY=VALUE ...]

Prints a table and, with --json, writes ``{"provenance": {...}, "rows": [...]}``;
each row has env, cameras, physics_timestep, env_options, steps_per_s,
physics_limit_steps_per_s, ratio, reset_s (plus first_reset_s, steps,
build_s).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import env_cli, cli, make_parser, prog, write_json  # noqa: E402

import envs  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

PROG = prog(__file__)
MUJOBAN = [f"mujoban/level{d}{p}" for p in ("", "-pegs") for d in range(1, 6)]
BOARDS = [
    "mujoxo/mixture",
    "mujoxo/optimal",
    "mujoxo/random",
    "mujogo/7x7",
    "mujogo/7x7-mixture",
    "mujogo/9x9",
]
#: Camera settings per environment family; a row is measured for each
#: requested setting its family has.
CAMERA_SETTINGS = {
    "mujoban": {
        "none": dict(top_camera=None, egocentric_camera=None),
        "top_camera": dict(top_camera=(96, 96), egocentric_camera=None),
        # The default observation set: both 96x96 cameras.
        "top_camera+egocentric": dict(top_camera=(96, 96), egocentric_camera=(96, 96)),
    },
    "boards": {
        "none": dict(front_camera=None),
        "front_camera": dict(front_camera=(84, 84)),
        # The original code's observation set: two 84x84 views.
        "front_camera+front_camera_2": dict(front_camera=(84, 84), front_camera_2=(84, 84)),
    },
}


def _family(name: str) -> str:
    return "mujoban" if name.startswith("mujoban/") else "boards"


def _actions(n: int, dim: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    held = rng.uniform(-1, 1, size=(n // 10 + 1, dim))
    return np.repeat(held, 10, axis=0)[:n]


def measure(
    name: str,
    cameras: str,
    steps: int,
    seed: int = 0,
    physics_timestep: float | None = None,
    env_options: dict | None = None,
) -> dict:
    family = _family(name)
    env_options = dict(env_options or {})
    overrides = {**CAMERA_SETTINGS[family][cameras], **env_options}
    if physics_timestep is not None:
        overrides["physics_timestep"] = physics_timestep
    t0 = time.perf_counter()
    env = envs.load(name, seed=seed, **overrides)
    build_s = time.perf_counter() - t0
    timestep_s = float(env.task.physics_timestep)
    actions = _actions(steps, env.action_spec().shape[0], seed)
    model, data = env.physics.model.ptr, env.physics.data.ptr
    n_sub = env.task.physics_steps_per_control_step

    t = time.perf_counter()
    env.reset()
    first_reset_s = time.perf_counter() - t
    reset_times = []
    env_time = raw_time = 0.0
    before, after = mujoco.MjData(model), mujoco.MjData(model)
    done, chunk = 0, 50
    timestep = None
    while done < steps:
        if timestep is None or timestep.last():
            t = time.perf_counter()
            env.reset()
            reset_times.append(time.perf_counter() - t)
        # Interleave: the environment runs a chunk, then raw mj_step replays
        # the same actions from the same state, so that both see the same
        # machine load and the same contacts.
        n = min(chunk, steps - done)
        mujoco.mj_copyData(before, model, data)
        t = time.perf_counter()
        for i in range(done, done + n):
            timestep = env.step(actions[i])
            if timestep.last():
                n = i - done + 1
                break
        env_time += time.perf_counter() - t
        mujoco.mj_copyData(after, model, data)
        mujoco.mj_copyData(data, model, before)
        ctrl = data.ctrl
        t = time.perf_counter()
        for i in range(done, done + n):
            ctrl[:] = actions[i]
            mujoco.mj_step(model, data, n_sub)
        raw_time += time.perf_counter() - t
        mujoco.mj_copyData(data, model, after)
        done += n
    env.close()
    steps_per_s = steps / env_time
    limit_per_s = steps / raw_time
    return {
        "env": name,
        "cameras": (
            []
            if cameras == "none"
            else cameras.replace("egocentric", "walker/egocentric_camera").split("+")
        ),
        "physics_timestep": timestep_s,
        "env_options": env_options,
        "steps_per_s": round(steps_per_s, 1),
        "physics_limit_steps_per_s": round(limit_per_s, 1),
        "ratio": round(steps_per_s / limit_per_s, 3),
        "reset_s": round(float(np.mean(reset_times)), 5),
        "first_reset_s": round(first_reset_s, 4),
        "build_s": round(build_s, 3),
        "steps": steps,
    }


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument("--json", type=Path, help="write the rows here")
    parser.add_argument(
        "--steps", type=cli.positive_int, default=2000, help="control steps per row"
    )
    parser.add_argument(
        "--envs", nargs="+", default=MUJOBAN + BOARDS, metavar="NAME", help="environment names"
    )
    all_settings = sorted({k for family in CAMERA_SETTINGS.values() for k in family})
    parser.add_argument(
        "--cameras",
        nargs="+",
        metavar="SETTING",
        default=["none", "top_camera", "front_camera", "front_camera+front_camera_2"],
        help=f"camera settings, of {', '.join(all_settings)} (each measured "
        f"where the environment has it)",
    )
    parser.add_argument(
        "--physics-timestep",
        type=cli.positive_float,
        default=None,
        help="physics timestep in seconds (default: each environment's own, the original's)",
    )
    env_cli.add_env_option(parser, "noslip_iterations=0 or sleep=False")
    args = parser.parse_args(argv)
    for setting in args.cameras:
        cli.choice("camera setting", setting, all_settings)
    env_options = {}
    for name in args.envs:
        env_cli.environment(name)
        env_options = env_cli.env_options(
            name, args.env_option, exclude=lambda key: key.endswith("_camera")
        )
        if args.physics_timestep is not None:
            env_cli.env_options(
                name, [f"physics_timestep={args.physics_timestep!r}"], flag="--physics-timestep"
            )
    cli.output_file(args.json, "--json")

    header = (
        f"{'env':<22} {'cameras':<28} {'dt ms':>5} {'steps/s':>9} {'limit/s':>9} "
        f"{'ratio':>6} {'reset ms':>9}"
    )
    print(header)
    print("-" * len(header))
    rows = []
    for name in args.envs:
        for cameras in args.cameras:
            if cameras not in CAMERA_SETTINGS[_family(name)]:
                continue
            row = measure(
                name,
                cameras,
                args.steps,
                physics_timestep=args.physics_timestep,
                env_options=env_options,
            )
            rows.append(row)
            print(
                f"{name:<22} {cameras:<28} {row['physics_timestep'] * 1e3:>5.1f} "
                f"{row['steps_per_s']:>9.1f} {row['physics_limit_steps_per_s']:>9.1f} "
                f"{row['ratio']:>6.2f} {row['reset_s'] * 1e3:>9.2f}",
                flush=True,
            )
    if args.json:
        write_json(args.json, rows)
    return 0


def main(argv=None) -> int:
    """Measures, prints the table, writes ``--json``; bad input: one line on
    stderr, exit status 2, before anything is measured."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
