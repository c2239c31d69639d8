"""MuJoBan estimators' accuracy on held-out frames, and the camera's cost.

Frames come from held-out episodes of every MuJoBan level source (each
episode drawing its own wall and floor textures, as the environment does;
``by_appearance`` breaks the whole-grid accuracy down by them): generated
levels 1-5 and the shipped real Boxoban files (``unfiltered-valid-000``,
``medium-valid-000``, shuffled), each with and without pegs, at seeds from
``--seed`` + 1000 on (the tests use seeds below 100). Every episode drives
random actions (held for 6-12 steps) so that the walker rolls, pushes boxes
and stops between cells, and in half the episodes one box is moved off its
cell centre (``set_box_position``, up to 0.45 cells towards a free
neighbour, then a zero action); every estimator estimates at every step (the
rounding rule remembers the previous player cell) and 4 frames per episode,
from step 5 on, are scored. All estimators see the same frames.

Estimators: ``camera`` as the agent runs it (it reads some frames and
predicts the scene in between, see `hier_agents.estimators.camera`; scored
frames may fall between reads), ``camera/every`` (the same estimator reading
and locating everything in every frame) and the privileged ``oracle``.
Per estimator:

* ``whole_grid_accuracy``: frames whose whole abstract grid is right: walls
  and targets (the env's ``full_entity_layer`` channels 0 and 1), the box
  cells (as a set) and the player cell (the env's own ``task.abstract_cells``,
  the paper's rounding rule on the simulator's positions). A failed estimate
  (`EstimationError`, at reset or later) counts as wrong; ``walls``,
  ``targets``, ``boxes``, ``player`` accuracies break it down;
* ``walker_error`` / ``box_error``: distance (cells) from the simulator's
  positions, median and 95th percentile (boxes by index: the estimator's box
  order must follow the task's);
* ``skipped_invalid_truth``: frames not scored because the simulator's own
  state had no valid grid (two boxes rounding to one cell, e.g. one pushed
  onto another);
* ``failures``: `EstimationError` count (frames scored wrong);
* ``teleport_frames`` and ``whole_grid_accuracy_without_teleports``: the
  nudge moves a box without any physical motion, which no estimator that
  reads some frames and predicts the others can follow until it reads the
  next one; the frames scored fewer than `TELEPORT_STEPS` steps after a
  nudge are counted, and the whole-grid accuracy is also given without them;
* ``ms_per_estimate`` / ``ms_per_reset``: mean wall time of ``estimate`` and
  ``reset`` (on this machine, one process).

Render cost: ms per ``env.step`` (mujoban/level5, the same 200 held random
actions) with no camera, the 96x96 top camera and the camera estimator's
frame size.

    python benchmarks/estimator_accuracy.py --json PATH [--frames 1000] [--seed 0]

Prints a table and writes ``{"provenance", "frame_shape", "frames", "seed",
"sources", "render_ms_per_step", "rows": [...], "per_source": {...}}``.
"""

from __future__ import annotations

import math
from collections import Counter
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

import envs  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from hier_agents.estimators.base import EstimationError  # noqa: E402
from hier_agents.estimators.camera import FRAME_SHAPE, CameraEstimator  # noqa: E402
from hier_agents.estimators.grid import cells_of  # noqa: E402
from hier_agents.estimators.mujoban import OracleEstimator  # noqa: E402

PROG = prog(__file__)

BOXOBAN = Path(envs.__file__).resolve().parent / "mujoban" / "data" / "boxoban"
#: (label, env name, levels file or None)
SOURCES = [
    (f"level{d}{p}", f"mujoban/level{d}{p}", None) for p in ("", "-pegs") for d in range(1, 6)
] + [
    (f"boxoban-{f}{p}", f"mujoban/level1{p}", BOXOBAN / f"{f}-valid-000.txt")
    for p in ("", "-pegs")
    for f in ("unfiltered", "medium")
]
FRAMES_PER_EPISODE = 4
#: Scored frames fewer than this many steps after a nudge are the
#: ``teleport_frames`` (the camera estimator's longest gap between frames).
TELEPORT_STEPS = 3
SEED_OFFSET = 1000


def _make_env(name, levels, seed):
    """The environment as the camera agent plays it (its camera settings,
    `CameraEstimator.env_overrides`), every frame rendered."""
    kwargs = dict(levels=str(levels), level_order="shuffle") if levels else {}
    camera = {**CameraEstimator.env_overrides, "lazy_cameras": False}
    return envs.load(name, seed=seed, egocentric_camera=None, **camera, **kwargs)


def _nudge_box(env, rng) -> None:
    """Moves one box up to 0.45 cells off its cell centre, towards a free cell."""
    task = env.task
    boxes = task.box_positions()
    if not len(boxes):
        return
    box_cells, player = task.abstract_cells
    occupied = set(map(tuple, task.level.walls)) | set(map(tuple, box_cells)) | {tuple(player)}
    i = int(rng.integers(len(boxes)))
    r, c = box_cells[i]
    free = [
        (dr, dc)
        for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1))
        if (r + dr, c + dc) not in occupied
    ]
    if not free:
        return
    dr, dc = free[int(rng.integers(len(free)))]
    cell = task.cell_size
    x, y = task.cell_to_world(r, c)
    xy = np.array([x, y]) + rng.uniform(0.1, 0.45) * cell * np.array([dc, -dr])
    # Only where it overlaps nothing: other boxes (wherever they are between
    # cells) and the walker.
    others = np.delete(boxes, i, axis=0)
    if len(others) and np.any(np.all(np.abs(others - xy) < 0.85 * cell, axis=1)):
        return
    if np.all(np.abs(task.walker_position() - xy) < (0.4 + 0.5) * cell):
        return
    task.set_box_position(env.physics, i, xy)


def _episode(env, estimators, rng, stats, frames_wanted) -> int:
    """Runs one episode; scores up to ``frames_wanted`` frames. Returns frames scored."""
    timestep = env.reset()
    description = env.description()
    layer = np.asarray(timestep.observation["full_entity_layer"])
    walls, targets = cells_of(layer[..., 0]), cells_of(layer[..., 1])
    alive = {}
    for est in estimators:
        t = time.perf_counter()
        try:
            est.reset(description, timestep)
            alive[est.label] = True
        except EstimationError:
            alive[est.label] = False
            stats[est.label]["failures"] += 1
        stats[est.label]["reset_s"].append(time.perf_counter() - t)
    steps = 5 + 6 * frames_wanted
    score_at = set(range(5, steps, 6))
    nudge_at = int(rng.integers(2, steps - 2)) if rng.random() < 0.5 else -1
    action = rng.uniform(-1, 1, size=env.action_spec().shape)
    hold = 0
    scored = 0
    for k in range(steps):
        if k == nudge_at:
            _nudge_box(env, rng)
            action = np.zeros_like(action)
        elif hold <= 0:
            action = rng.uniform(-1, 1, size=action.shape)
            hold = int(rng.integers(6, 13))
        hold -= 1
        timestep = env.step(action)
        if timestep.last():
            break
        truth_boxes, truth_player = env.task.abstract_cells
        # A physically odd state (two boxes in one cell: one pushed onto the
        # other) has no valid abstract grid; it is estimated but not scored.
        valid = len(set(map(tuple, truth_boxes))) == len(truth_boxes)
        for est in estimators:
            s = stats[est.label]
            scene = None
            if alive[est.label]:
                t = time.perf_counter()
                try:
                    scene = est.estimate(timestep)
                except EstimationError:
                    scene = None
                except ValueError:  # the oracle's SokobanState on an invalid state
                    if valid:
                        raise
                s["estimate_s"].append(time.perf_counter() - t)
            if k not in score_at:
                continue
            if not valid:
                s["invalid_truth"] += 1
                continue
            s["frames"] += 1
            teleport = nudge_at >= 0 and 0 <= k - nudge_at < TELEPORT_STEPS
            s["teleport_frames"] += int(teleport)
            if scene is None:
                if alive[est.label]:
                    s["failures"] += 1
                continue
            ok = {
                "walls": scene.state.walls == walls,
                "targets": scene.state.targets == targets,
                "boxes": scene.state.boxes == frozenset(map(tuple, truth_boxes)),
                "player": tuple(scene.state.player) == tuple(truth_player),
            }
            for key, value in ok.items():
                s[key] += int(value)
            s["whole"] += int(all(ok.values()))
            s["teleport_whole"] += int(teleport and all(ok.values()))
            look = "/".join(env.task.appearance)
            s["look_frames"][look] += 1
            s["look_whole"][look] += int(all(ok.values()))
            cell = description.cell_size
            s["walker_err"].append(
                float(np.linalg.norm(np.asarray(scene.walker_xy) - env.task.walker_position()))
                / cell
            )
            truth_xy = env.task.box_positions()
            est_xy = np.asarray(scene.box_xy, float).reshape(-1, 2)
            if est_xy.shape == truth_xy.shape:
                s["box_err"].extend((np.linalg.norm(est_xy - truth_xy, axis=1) / cell).tolist())
        if k in score_at and valid:
            scored += 1
    return scored


def _new_stats():
    return dict(
        frames=0,
        whole=0,
        walls=0,
        targets=0,
        boxes=0,
        player=0,
        failures=0,
        teleport_frames=0,
        teleport_whole=0,
        invalid_truth=0,
        walker_err=[],
        box_err=[],
        estimate_s=[],
        reset_s=[],
        look_frames=Counter(),
        look_whole=Counter(),
    )


def _summary(name, privileged, s) -> dict:
    n = max(s["frames"], 1)

    def q(values, p):
        return round(float(np.percentile(values, p)), 4) if values else None

    return {
        "estimator": name,
        "privileged": privileged,
        "frames": s["frames"],
        "whole_grid_accuracy": round(s["whole"] / n, 4),
        "teleport_frames": s["teleport_frames"],
        "whole_grid_accuracy_without_teleports": round(
            (s["whole"] - s["teleport_whole"]) / max(s["frames"] - s["teleport_frames"], 1), 4
        ),
        "walls_accuracy": round(s["walls"] / n, 4),
        "targets_accuracy": round(s["targets"] / n, 4),
        "boxes_accuracy": round(s["boxes"] / n, 4),
        "player_accuracy": round(s["player"] / n, 4),
        "failures": s["failures"],
        "skipped_invalid_truth": s["invalid_truth"],
        "walker_error_median_cells": q(s["walker_err"], 50),
        "walker_error_p95_cells": q(s["walker_err"], 95),
        "box_error_median_cells": q(s["box_err"], 50),
        "box_error_p95_cells": q(s["box_err"], 95),
        "ms_per_estimate": round(1e3 * float(np.mean(s["estimate_s"])), 3)
        if s["estimate_s"]
        else None,
        "ms_per_reset": round(1e3 * float(np.mean(s["reset_s"])), 3) if s["reset_s"] else None,
        "by_appearance": {
            look: {
                "frames": n_look,
                "whole_grid_accuracy": round(s["look_whole"][look] / n_look, 4),
            }
            for look, n_look in sorted(s["look_frames"].items())
        },
    }


def render_cost(steps: int = 200, seed: int = 0) -> dict:
    """ms per env.step on mujoban/level5 without a camera, with the default
    96x96 top camera and with the camera estimator's camera (its
    ``env_overrides``, every frame rendered), same held random actions."""
    rng = np.random.default_rng(seed)
    actions = np.repeat(rng.uniform(-1, 1, size=(steps // 10 + 1, 2)), 10, axis=0)[:steps]
    out = {}
    agent_camera = {**CameraEstimator.env_overrides, "lazy_cameras": False}
    for label, camera in (
        ("none", dict(top_camera=None)),
        ("96x96", dict(top_camera=(96, 96))),
        (f"{FRAME_SHAPE[0]}x{FRAME_SHAPE[1]} (the estimator's)", agent_camera),
    ):
        env = envs.load("mujoban/level5", seed=seed, egocentric_camera=None, **camera)
        env.reset()
        for a in actions[:5]:
            env.step(a)
        t = time.perf_counter()
        n = 0
        for a in actions:
            if env.step(a).last():
                env.reset()
            n += 1
        out[label] = round(1e3 * (time.perf_counter() - t) / n, 3)
        env.close()
    return out


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument(
        "--frames", type=cli.positive_int, default=1000, help="frames scored in all"
    )
    parser.add_argument(
        "--seed",
        type=cli.non_negative_int,
        default=0,
        help=f"base seed (episodes use seeds from seed + {SEED_OFFSET})",
    )
    parser.add_argument(
        "--render-steps",
        type=cli.non_negative_int,
        default=200,
        help="env.step calls per render-cost setting (0: skip)",
    )
    args = parser.parse_args(argv)
    cli.output_file(args.json, "--json")

    per_source_frames = math.ceil(args.frames / len(SOURCES))
    totals = {}
    per_source = {}
    privileged = {}
    progress = tqdm(
        total=per_source_frames * len(SOURCES), desc="frames", unit="frame", leave=False
    )
    for index, (label, name, levels) in enumerate(SOURCES):
        seed = args.seed + SEED_OFFSET + index
        env = _make_env(name, levels, seed)
        every = CameraEstimator(frame_every=1, walker_every=1)
        every.label = "camera/every"
        agent = CameraEstimator()
        agent.label = "camera"
        oracle = OracleEstimator(env)
        oracle.label = "oracle"
        estimators = [agent, every, oracle]
        for est in estimators:
            privileged[est.label] = est.privileged
            totals.setdefault(est.label, _new_stats())
        stats = {est.label: _new_stats() for est in estimators}
        rng = np.random.default_rng(seed)
        done = 0
        while done < per_source_frames:
            want = min(FRAMES_PER_EPISODE, per_source_frames - done)
            got = _episode(env, estimators, rng, stats, want)
            done += got
            progress.update(got)
        env.close()
        per_source[label] = {n: _summary(n, privileged[n], s) for n, s in stats.items()}
        for n, s in stats.items():
            for key, value in s.items():
                totals[n][key] += value
    progress.close()
    rows = [_summary(n, privileged[n], s) for n, s in totals.items()]
    render = render_cost(args.render_steps, args.seed) if args.render_steps > 0 else {}

    header = (
        f"{'estimator':<10} {'priv':<5} {'frames':>6} {'grid ok':>8} {'walls':>7} "
        f"{'targets':>7} {'boxes':>7} {'player':>7} {'fail':>5} {'walker med/p95':>15} "
        f"{'box med/p95':>15} {'ms/est':>7} {'ms/reset':>8}"
    )
    print(header)
    print("-" * len(header))
    for r in rows:
        print(
            f"{r['estimator']:<10} {str(r['privileged']):<5} {r['frames']:>6} "
            f"{100 * r['whole_grid_accuracy']:>7.2f}% {100 * r['walls_accuracy']:>6.2f}% "
            f"{100 * r['targets_accuracy']:>6.2f}% {100 * r['boxes_accuracy']:>6.2f}% "
            f"{100 * r['player_accuracy']:>6.2f}% {r['failures']:>5} "
            f"{r['walker_error_median_cells']:>7.4f}/{r['walker_error_p95_cells']:<7.4f} "
            f"{r['box_error_median_cells']:>7.4f}/{r['box_error_p95_cells']:<7.4f} "
            f"{r['ms_per_estimate']:>7.2f} {r['ms_per_reset']:>8.2f}"
        )
    print(
        "without the frames fewer than {} steps after a teleporting nudge: ".format(TELEPORT_STEPS)
        + ", ".join(
            f"{r['estimator']} {100 * r['whole_grid_accuracy_without_teleports']:.2f}% "
            f"({r['frames'] - r['teleport_frames']} frames)"
            for r in rows
        )
    )
    camera = rows[0]["by_appearance"]
    worst = min(camera.items(), key=lambda kv: kv[1]["whole_grid_accuracy"])
    print(
        f"camera: {len(camera)} wall/floor appearances seen; the worst {worst[0]} "
        f"{100 * worst[1]['whole_grid_accuracy']:.1f}% of {worst[1]['frames']} frames"
    )
    print(
        "camera whole-grid accuracy per source: "
        + ", ".join(
            f"{label} {100 * v['camera']['whole_grid_accuracy']:.1f}%"
            for label, v in per_source.items()
        )
    )
    if render:
        print(
            "render cost, ms per env.step (mujoban/level5): "
            + ", ".join(f"{k} {v:.2f}" for k, v in render.items())
        )
    if args.json:
        write_json(
            args.json,
            {
                "frame_shape": list(FRAME_SHAPE),
                "frames": args.frames,
                "seed": args.seed,
                "sources": [label for label, _, _ in SOURCES],
                "render_ms_per_step": render,
                "rows": rows,
                "per_source": per_source,
            },
        )
    return 0


def main(argv=None) -> int:
    """Scores the estimators, prints the table, writes ``--json``; bad input:
    one line on stderr, exit status 2."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
