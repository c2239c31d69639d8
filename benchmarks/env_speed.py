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

    python benchmarks/env_speed.py [--json PATH] [--steps N] [--envs NAME ...]

Prints a table and, with --json, writes a list of rows with keys env, cameras,
steps_per_s, physics_limit_steps_per_s, ratio, reset_s (plus first_reset_s,
steps, build_s).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import write_json  # noqa: E402

import envs  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

MUJOBAN = [f"mujoban/level{d}{p}" for p in ("", "-pegs") for d in range(1, 6)]
BOARDS = ["mujoxo/mixture", "mujoxo/optimal", "mujoxo/random", "mujogo/7x7",
          "mujogo/7x7-mixture", "mujogo/9x9"]
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
    },
}


def _family(name: str) -> str:
    return "mujoban" if name.startswith("mujoban/") else "boards"


def _actions(n: int, dim: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    held = rng.uniform(-1, 1, size=(n // 10 + 1, dim))
    return np.repeat(held, 10, axis=0)[:n]


def measure(name: str, cameras: str, steps: int, seed: int = 0) -> dict:
    t0 = time.perf_counter()
    env = envs.load(name, seed=seed, **CAMERA_SETTINGS[_family(name)][cameras])
    build_s = time.perf_counter() - t0
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
        "cameras": ([] if cameras == "none"
                    else cameras.replace("egocentric", "walker/egocentric_camera").split("+")),
        "steps_per_s": round(steps_per_s, 1),
        "physics_limit_steps_per_s": round(limit_per_s, 1),
        "ratio": round(steps_per_s / limit_per_s, 3),
        "reset_s": round(float(np.mean(reset_times)), 5),
        "first_reset_s": round(first_reset_s, 4),
        "build_s": round(build_s, 3),
        "steps": steps,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, help="write the rows here")
    parser.add_argument("--steps", type=int, default=2000, help="control steps per row")
    parser.add_argument("--envs", nargs="*", default=MUJOBAN + BOARDS,
                        help="environment names")
    all_settings = sorted({k for family in CAMERA_SETTINGS.values() for k in family})
    parser.add_argument("--cameras", nargs="*", default=["none", "top_camera", "front_camera"],
                        choices=all_settings)
    args = parser.parse_args(argv)
    unknown = [n for n in args.envs if n not in envs.names()]
    if unknown:
        parser.error(f"unknown environments {unknown}; known: {envs.names()}")

    header = f"{'env':<24} {'cameras':<22} {'steps/s':>9} {'limit/s':>9} {'ratio':>6} {'reset ms':>9}"
    print(header)
    print("-" * len(header))
    rows = []
    for name in args.envs:
        for cameras in args.cameras:
            if cameras not in CAMERA_SETTINGS[_family(name)]:
                continue
            row = measure(name, cameras, args.steps)
            rows.append(row)
            print(f"{name:<24} {cameras:<22} {row['steps_per_s']:>9.1f} "
                  f"{row['physics_limit_steps_per_s']:>9.1f} {row['ratio']:>6.2f} "
                  f"{row['reset_s'] * 1e3:>9.2f}", flush=True)
    if args.json:
        write_json(args.json, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
