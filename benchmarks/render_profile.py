"""What one camera frame costs, part by part, for every camera the environments offer.

    python benchmarks/render_profile.py [--frames N] [--rounds R] [--json PATH]

For each environment and camera observation (with the looks it is drawn
with: the environments' defaults, the camera estimator's own 199x199 top
camera, and the board games with the original's shadows and 4x
multisampling) the environment is reset and stepped a few times, then the
same frame is drawn ``--frames`` times in each of these ways:

* ``update_ms``: `mujoco.Renderer.update_scene` (the abstract scene from the
  simulation state);
* ``render_ms``: ``mjr_render`` and ``mjr_readPixels`` (every render pass:
  shadow maps, the reflection, the geometry, the skybox, the multisample
  resolve; then the image into host memory: ``mjr_render`` only queues the
  drawing, and reading the pixels waits for it);
* ``readback_ms``: ``mjr_readPixels`` of a finished image alone;
  ``draw_ms`` = ``render_ms`` - ``readback_ms``;
* ``flip_ms``: the copy that turns it upright;
* ``frame_ms``: the environment's own path, `envs.rendering.Cameras.render`
  (all of the above, the small-frame tessellation and the GL context
  switches);
* ``no_reflection_ms``, ``no_shadow_ms``, ``no_skybox_ms``: ``update`` and
  ``render`` with that pass switched off in the scene (``mjtRndFlag``), so
  the pass costs ``update_ms + render_ms`` minus it.

Timings are medians over ``--rounds`` rounds (each the mean of ``--frames``
frames), in milliseconds, on this machine's OpenGL (``MUJOCO_GL``, EGL by
default: Mesa's llvmpipe on a machine without a GPU). Run it on an
otherwise idle machine. It prints a table and writes ``--json``
``{"provenance", "rows"}``.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import envs  # noqa: E402
from envs.rendering import _KeepCurrentContext  # noqa: E402

PROG = prog(__file__)

#: (label, environment, envs.load options, observation keys to profile).
CASES = (
    ("MuJoBan, default looks", "mujoban/level5", {}, None),
    (
        "MuJoBan, the camera estimator's camera",
        "mujoban/level5",
        {"top_camera": (199, 199), "multisamples": 0},
        None,
    ),
    ("MuJoXO, default looks", "mujoxo/optimal", {"front_camera_2": (84, 84)}, None),
    (
        "MuJoXO, the original's looks",
        "mujoxo/optimal",
        {"front_camera_2": (84, 84), "shadows": True, "multisamples": 4},
        None,
    ),
    ("MuJoGo, default looks", "mujogo/7x7", {"front_camera_2": (84, 84)}, None),
)
PASSES = (
    ("no_reflection_ms", mujoco.mjtRndFlag.mjRND_REFLECTION),
    ("no_shadow_ms", mujoco.mjtRndFlag.mjRND_SHADOW),
    ("no_skybox_ms", mujoco.mjtRndFlag.mjRND_SKYBOX),
)


def _timed(fn, frames: int, rounds: int) -> float:
    """Median over ``rounds`` of the mean milliseconds of ``frames`` calls."""
    fn()  # warm
    means = []
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(frames):
            fn()
        means.append((time.perf_counter() - start) * 1000.0 / frames)
    return statistics.median(means)


def profile_camera(env, key: str, frames: int, rounds: int) -> dict:
    """The row of one camera observation ``key`` of ``env`` (a built,
    stepped `envs` environment)."""
    cameras, data = env._cameras, env._data
    cam_id, height, width = env._camera_ids[key]
    renderer = cameras._renderer(height, width)
    quality = cameras._quality[(height, width)]
    scene, context = renderer.scene, renderer._mjr_context
    viewport = mujoco.MjrRect(0, 0, width, height)
    pixels = np.empty((height, width, 3), np.uint8)
    row = {
        "camera": key,
        "height": height,
        "width": width,
        "multisamples": int(env._model.vis.quality.offsamples),
    }
    with quality, _KeepCurrentContext():
        renderer._gl_context.make_current()

        def update():
            renderer.update_scene(data, camera=cam_id, scene_option=cameras._option)

        def draw():
            mujoco.mjr_render(viewport, scene, context)

        def read():
            mujoco.mjr_readPixels(pixels, None, viewport, context)

        update()
        row["update_ms"] = _timed(update, frames, rounds)
        # mjr_render only queues the drawing: reading the pixels waits for it.
        row["render_ms"] = _timed(lambda: (draw(), read()), frames, rounds)
        row["readback_ms"] = _timed(read, frames, rounds)
        row["draw_ms"] = max(row["render_ms"] - row["readback_ms"], 0.0)
        row["flip_ms"] = _timed(lambda: np.flipud(pixels).copy(), frames, rounds)
        for name, flag in PASSES:
            was = scene.flags[flag]  # update_scene leaves the render flags alone

            def without(flag=flag):
                update()
                scene.flags[flag] = 0
                draw()
                read()

            try:
                row[name] = _timed(without, frames, rounds)
            finally:
                scene.flags[flag] = was
    row["frame_ms"] = _timed(lambda: cameras.render(data, cam_id, height, width), frames, rounds)
    return row


def run(frames: int, rounds: int, progress=print) -> list[dict]:
    rows = []
    for label, name, options, keys in CASES:
        env = envs.load(name, seed=0, **options)
        try:
            env.reset()
            spec = env.action_spec()
            rng = np.random.default_rng(0)
            for _ in range(5):
                env.step(rng.uniform(spec.minimum, spec.maximum).astype(spec.dtype))
            for key in keys or sorted(env._camera_ids):
                row = {
                    "case": label,
                    "env": name,
                    "options": {
                        k: list(v) if isinstance(v, tuple) else v for k, v in options.items()
                    },
                    **profile_camera(env, key, frames, rounds),
                }
                rows.append(row)
                progress(format_row(row))
        finally:
            env.close()
    return rows


COLUMNS = (
    "update_ms",
    "draw_ms",
    "readback_ms",
    "flip_ms",
    "frame_ms",
    "no_reflection_ms",
    "no_shadow_ms",
    "no_skybox_ms",
)  # the table's; the JSON also has render_ms


def format_row(row: dict) -> str:
    head = (
        f"{row['case']:<40} {row['camera']:<16} {row['height']}x{row['width']:<4} "
        f"ms{row['multisamples']} "
    )
    return head + " ".join(f"{row[c]:>8.3f}" for c in COLUMNS)


def header() -> str:
    return (
        f"{'case':<40} {'camera':<16} {'size':<8} {'ms':<3} "
        + " ".join(f"{c.removesuffix('_ms'):>8}" for c in COLUMNS)
        + "   (ms per frame)"
    )


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--frames", type=cli.positive_int, default=50, help="frames per timed round (default: 50)"
    )
    parser.add_argument(
        "--rounds",
        type=cli.positive_int,
        default=5,
        help="timed rounds per measurement; the median is kept (default: 5)",
    )
    parser.add_argument("--json", type=Path, help="write the rows here")
    args = parser.parse_args(argv)
    cli.output_file(args.json, "--json")
    print(header())
    rows = run(args.frames, args.rounds)
    if args.json:
        write_json(args.json, {"frames": args.frames, "rounds": args.rounds, "rows": rows})
    return 0


def main(argv=None) -> int:
    """Profiles every camera, prints the table, writes ``--json``; bad input:
    one line on stderr, exit status 2."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
