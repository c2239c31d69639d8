"""What the board games' looks cost per frame, and how they compare with the original's.

    PYTHONPATH=/tmp/peer python benchmarks/board_looks.py [--frames 100]
        [--shadow-maps 512 2048] [--picture results/board_looks.png]
        [--json results/board_looks.json]

The original code (DeepMind's physics_planning_games) draws its board-game
frames with 4 samples per pixel and a light that casts shadows (MuJoCo's
4096-texel shadow map); this library's default draws neither. Per look, on
`mujoxo/mixture` and `mujogo/7x7` (84x84 ``front_camera``, the same seeded
state for every look): milliseconds per frame (``Cameras.render``, the
median of ``--frames`` frames after 10 warm-up frames) and the difference of
its image from the default look's (mean absolute difference per channel,
share of pixels off by more than 8). Looks: the default, ``multisamples=4``,
``shadows=True``, both (``original``: the original's), and both with the
original's 4096-texel map (``SHADOW_MAP_SIZE`` is the library's: its image
difference from that is reported as ``shadow_map_vs_4096``). Each size of
``--shadow-maps`` adds a row of the original's looks drawn with that map,
its cost and its difference from the 4096-texel frame (``vs_4096``); so does
the original's looks without the floor's reflection (its reflectance 0: one
render pass less).

With the original importable (``../shared/peer/setup.sh`` builds it into
/tmp/peer; put it on PYTHONPATH) the picture also shows the original's own
first frame of tic-tac-toe and 7x7 Go; its arm starts in another random
pose, so the comparison is by eye (light, shadows, edges), not by pixels.

Prints a table and, with --json, writes ``{"provenance", "frames", "rows",
"picture"}``.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

import envs  # noqa: E402
import numpy as np  # noqa: E402
from envs.boards import arena as arena_lib  # noqa: E402
from envs.rendering import Cameras  # noqa: E402

PROG = prog(__file__)
ENVS = ("mujoxo/mixture", "mujogo/7x7")
ORIGINAL_NAMES = {
    "mujoxo/mixture": "tic_tac_toe_mixture_opponent_markers_features",
    "mujogo/7x7": "go_7x7",
}
#: The original's looks, the key of `LOOKS`.
ORIGINAL = "original (multisamples=4, shadows)"
LOOKS = {
    "default": {},
    "multisamples=4": {"multisamples": 4},
    "shadows": {"shadows": True},
    ORIGINAL: {"multisamples": 4, "shadows": True},
}
SIZE = (84, 84)


def _frame_cost(
    env, frames: int, shadow_map: int | None = None, reflection: bool = True
) -> tuple[float, np.ndarray]:
    """Median ms per 84x84 front_camera frame of ``env`` in its current
    state, and the frame; ``shadow_map`` overrides the model's map size;
    without ``reflection`` no material reflects (the floor's reflectance 0:
    MuJoCo then skips its reflection pass)."""
    model, data = env.physics.model.ptr, env.physics.data.ptr
    if shadow_map is not None:
        model.vis.quality.shadowsize = shadow_map  # read when the context is made
    if not reflection:
        model.mat_reflectance[:] = 0.0
    cameras = Cameras(model)
    try:
        for _ in range(10):
            image = cameras.render(data, "front_camera", *SIZE)
        times = []
        for _ in range(frames):
            t = time.perf_counter()
            image = cameras.render(data, "front_camera", *SIZE)
            times.append(time.perf_counter() - t)
    finally:
        cameras.close()
    return 1e3 * statistics.median(times), image


def _difference(a: np.ndarray, b: np.ndarray) -> dict:
    d = np.abs(a.astype(int) - b.astype(int))
    return {
        "mean_abs": round(float(d.mean()), 4),
        "share_above_8": round(float((d.max(-1) > 8).mean()), 4),
    }


def _original_cost(name: str, args, **cost) -> tuple[float, np.ndarray]:
    """`_frame_cost` of ``name`` at the original's looks (the ``ORIGINAL`` look
    of `LOOKS`), settled from ``args.seed``, with ``cost``'s overrides."""
    env = _settled(name, LOOKS[ORIGINAL], args.seed)
    try:
        return _frame_cost(env, args.frames, **cost)
    finally:
        env.close()


def _settled(name: str, options: dict, seed: int):
    env = envs.load(name, seed=seed, **options)
    env.reset()
    rng = np.random.default_rng(seed)
    for _ in range(5):
        env.step(rng.uniform(-1, 1, env.action_spec().shape))
    return env


def _original_frame(name: str, seed: int):
    try:
        from physics_planning_games import board_games
    except ImportError:
        return None
    env = board_games.load(environment_name=ORIGINAL_NAMES[name], seed=seed)
    frame = np.asarray(env.reset().observation["front_camera"])
    env.close()
    return frame[0] if frame.ndim == 4 else frame


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument("--frames", type=cli.positive_int, default=100)
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument(
        "--shadow-maps",
        type=cli.positive_int,
        nargs="*",
        default=[512, 2048],
        help="shadow map sizes (texels a side) to compare with the original's 4096",
    )
    parser.add_argument("--picture", type=Path, help="write the side-by-side picture here")
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    cli.output_file(args.json, "--json")
    cli.output_file(args.picture, "--picture")
    rows, strips = [], []
    for name in ENVS:
        images = {}
        for label, options in LOOKS.items():
            env = _settled(name, options, args.seed)
            ms, images[label] = _frame_cost(env, args.frames)
            env.close()
            rows.append(
                {
                    "env": name,
                    "look": label,
                    "options": options,
                    "ms_per_frame": round(ms, 3),
                    "vs_default": _difference(images[label], images["default"]),
                }
            )
        ms, full_map = _original_cost(name, args, shadow_map=4096)
        rows.append(
            {
                "env": name,
                "look": "original with a 4096 shadow map",
                "options": {**LOOKS[ORIGINAL], "shadowsize": 4096},
                "ms_per_frame": round(ms, 3),
                "vs_default": _difference(full_map, images["default"]),
                "shadow_map_vs_4096": _difference(images[ORIGINAL], full_map),
            }
        )
        variants = [
            (f"original with a {size} shadow map", {"shadowsize": size}, {"shadow_map": size})
            for size in args.shadow_maps
        ] + [
            ("original without the floor's reflection", {"reflectance": 0.0}, {"reflection": False})
        ]
        for look, options, cost in variants:
            ms, image = _original_cost(name, args, **cost)
            rows.append(
                {
                    "env": name,
                    "look": look,
                    "options": {**LOOKS[ORIGINAL], **options},
                    "ms_per_frame": round(ms, 3),
                    "vs_default": _difference(image, images["default"]),
                    "vs_4096": _difference(image, full_map),
                }
            )
        original = _original_frame(name, args.seed)
        strips.append((name, images["default"], images[ORIGINAL], original))
    default_ms = {r["env"]: r["ms_per_frame"] for r in rows if r["look"] == "default"}
    print(
        f"{'environment':<16} {'look':<40} {'ms/frame':>9} {'x default':>9} "
        f"{'mean diff':>9} {'px > 8':>7}"
    )
    for r in rows:
        print(
            f"{r['env']:<16} {r['look']:<40} {r['ms_per_frame']:>9.2f} "
            f"{r['ms_per_frame'] / default_ms[r['env']]:>8.1f}x "
            f"{r['vs_default']['mean_abs']:>9.3f} "
            f"{100 * r['vs_default']['share_above_8']:>6.1f}%"
        )
    for r in rows:
        if "shadow_map_vs_4096" in r:
            d = r["shadow_map_vs_4096"]
            print(
                f"{r['env']}: the {arena_lib.SHADOW_MAP_SIZE}-texel map against 4096: mean "
                f"difference {d['mean_abs']:.4f}, {100 * d['share_above_8']:.2f}% of pixels > 8"
            )
        if "vs_4096" in r:
            d = r["vs_4096"]
            print(
                f"{r['env']}: {r['look']} against 4096: mean difference "
                f"{d['mean_abs']:.4f}, {100 * d['share_above_8']:.2f}% of pixels > 8"
            )
    picture = None
    if args.picture:
        from PIL import Image, ImageDraw

        scale = 3
        with_original = all(s[3] is not None for s in strips)
        columns = ["default", "original looks"] + (["the original"] if with_original else [])
        tile = SIZE[0] * scale
        canvas = Image.new("RGB", (tile * len(columns), (tile + 14) * len(strips)), "white")
        draw = ImageDraw.Draw(canvas)
        for i, (name, default, original_looks, original) in enumerate(strips):
            for j, image in enumerate(
                [default, original_looks] + ([original] if with_original else [])
            ):
                big = Image.fromarray(np.asarray(image, np.uint8)).resize(
                    (tile, tile), Image.NEAREST
                )
                canvas.paste(big, (j * tile, i * (tile + 14) + 14))
                draw.text((j * tile + 3, i * (tile + 14)), f"{name}: {columns[j]}", fill="black")
        args.picture.parent.mkdir(parents=True, exist_ok=True)
        canvas.save(args.picture)
        picture = {"path": str(args.picture), "columns": columns}
        print(f"wrote {args.picture}")
    if args.json:
        write_json(
            args.json,
            {
                "frames": args.frames,
                "seed": args.seed,
                "size": list(SIZE),
                "shadow_map_size": arena_lib.SHADOW_MAP_SIZE,
                "rows": rows,
                "picture": picture,
            },
        )
    return 0


def main(argv=None) -> int:
    """Measures and prints; exit status 0, 2 with one line on stderr for bad input."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
