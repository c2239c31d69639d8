"""Our modular agent playing the *original* MuJoBan (DeepMind's
``physics_planning_games``), and our looks compared with the original's.

The original is built from DeepMind's ``deepmind-research`` repository by
``../shared/peer/setup.sh`` (into ``/tmp/peer`` by default) and imported from
``PYTHONPATH``; nothing of it ships with this project. Its environment is
used as it is: its own task, walker (``JumpingBallWithHead``, whose third
action, the kick, the agent leaves at 0), physics (1 ms), its 199x199 top
camera (the same pose and field of view as ours) and its own success rule
(the episode ends with the +10 level-solved reward). Levels are the first
``--levels`` of a Boxoban file (default: the shipped unfiltered-valid-000),
fed to the original's ``MujobanLevel`` in order; the control step is the
paper's 0.05 s and episodes last 45 s (900 steps).

The agent is the default observation-only modular agent (``camera``
estimator, execution-time Sokoban planner, ball skill), unchanged. It is
told the original task's public description, read from the original's
model and constants (grid, camera pose and field of view, box size, object
colours and light), and it sees only the observations (the original's
``full_entity_layer`` and ``pixel_layer`` are removed, as behind our
`hier_agents.boundary`).

    PYTHONPATH=/tmp/peer python benchmarks/original_env.py --levels 20 \
        --json results/original_env.json
    PYTHONPATH=/tmp/peer python benchmarks/original_env.py --picture results/looks_side_by_side.png

``--picture`` renders the same Boxoban level and texture draw in the
original and in ours (the same walker heading) side by side, and records
the rendered colours of box, pad, covered pad and box on a pad in both
(``--json``'s ``looks``).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import described_camera, env_cli, cli, make_parser, prog, write_json  # noqa: E402

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import envs  # noqa: E402
from envs.description import MujobanDescription, MujobanLooks  # noqa: E402
from envs.mujoban.levels import BOXOBAN_DIR, read_levels, write_levels  # noqa: E402
from hier_agents.boundary import PRIVILEGED_OBSERVATIONS  # noqa: E402
from hier_agents.modular.components import make_agent  # noqa: E402
from hier_agents.modular.families import TIME_LIMIT_REASON  # noqa: E402
from hier_agents.estimators.grid import cells_of  # noqa: E402
from hier_agents.stats import wilson_interval  # noqa: E402

PROG = prog(__file__)

FRAME = (199, 199)
CONTROL_TIMESTEP = 0.05
TIME_LIMIT = 45.0


def _import_original():
    try:
        from dm_control import composer
        from dm_control.locomotion import walkers
        from physics_planning_games.mujoban import mujoban as original
        from physics_planning_games.mujoban.mujoban_level import MujobanLevel
    except ImportError as exc:
        raise cli.UsageError(
            f"the original physics_planning_games is not importable ({exc}); "
            f"build it with ../shared/peer/setup.sh and run with "
            f"PYTHONPATH=/tmp/peer"
        ) from None
    return composer, walkers, original, MujobanLevel


def original_env(levels, pegs: bool, seed: int, frame=FRAME):
    """The original MuJoBan playing ``levels`` (our `Level` objects) in order."""
    composer, walkers, original, MujobanLevel = _import_original()
    texts = [level.to_text() for level in levels]

    def generator():
        while True:
            yield from texts

    walker = walkers.JumpingBallWithHead(add_ears=True, camera_height=0.25)
    task = original.Mujoban(
        walker=walker,
        maze=MujobanLevel(generator),
        control_timestep=CONTROL_TIMESTEP,
        top_camera_height=frame[0],
        top_camera_width=frame[1],
        with_grid_pegs=pegs,
    )
    return composer.Environment(
        time_limit=TIME_LIMIT, task=task, random_state=seed, strip_singleton_obs_buffer_dim=True
    )


def original_description(env, pegs: bool) -> MujobanDescription:
    """The public description of the original task, read from its model and
    constants (not from ours)."""
    _, _, original, _ = _import_original()
    physics, task = env.physics, env.task
    top = described_camera(
        physics,
        task._arena.top_camera,
        "top_camera",
        FRAME,  # pylint: disable=protected-access
    )
    maze = task._maze  # pylint: disable=protected-access
    ears = [
        site
        for site in task._walker.mjcf_model.find_all("site")  # pylint: disable=protected-access
        if site.type == "sphere" and site.size is not None and site.size[0] == 0.26
    ]
    red = next(tuple(s.rgba) for s in ears if s.rgba[0] > 0)
    blue = next(tuple(s.rgba) for s in ears if s.rgba[2] > 0)
    light = physics.model.vis.headlight
    half, _, half_height = task._box_size  # pylint: disable=protected-access
    looks = MujobanLooks(
        box=tuple(original._BOX_RGBA),
        box_on_pad=tuple(original._BOX_PRESSED_RGBA),
        pad=tuple(original._TARGET_RGBA),
        pad_covered=tuple(original._PRESSED_TARGET_RGBA),
        right_ear=red,
        left_ear=blue,
        headlight_ambient=float(light.ambient[0]),
        headlight_diffuse=float(light.diffuse[0]),
    )
    return MujobanDescription(
        grid_shape=(int(maze.height), int(maze.width)),
        cell_size=float(task._arena.xy_scale),
        pegs=pegs,
        max_boxes=4,
        control_timestep=CONTROL_TIMESTEP,
        time_limit_steps=int(round(TIME_LIMIT / CONTROL_TIMESTEP)),
        pad_tolerance=0.5 - float(half),
        box_half=float(half),
        box_half_height=float(half_height),
        ball_radius=0.2,
        peg_radius=original._PEG_SIZE,
        top_camera=top,
        looks=looks,
    )


def _visible(timestep):
    obs = {k: v for k, v in timestep.observation.items() if k not in PRIVILEGED_OBSERVATIONS}
    return timestep._replace(observation=obs)


def _grid_right(state, layer) -> bool:
    """Whether an abstract state equals the original's ``full_entity_layer``
    (walls, targets, the box cells, the player cell; the original rounds as
    ours does: boxes first, the player keeps its cell on overlap)."""
    layer = np.asarray(layer)
    return (
        state.walls == cells_of(layer[..., 0])
        and state.targets == cells_of(layer[..., 1])
        and state.boxes == cells_of(layer[..., 3])
        and cells_of(layer[..., 2]) == {tuple(state.player)}
    )


def play(levels, pegs: bool, seed: int, progress: bool = True) -> dict:
    """Our default agent on the original, one episode per level."""
    env = original_env(levels, pegs, seed)
    name = "mujoban/level5-pegs" if pegs else "mujoban/level5"
    rows = []
    bar = tqdm(
        total=len(levels),
        unit="level",
        desc=f"original pegs={pegs}",
        file=sys.stderr,
        disable=not progress,
    )
    agent = None
    try:
        for index in range(len(levels)):
            start = time.perf_counter()
            raw = env.reset()
            timestep = _visible(raw)
            description = original_description(env, pegs)
            if agent is None:
                agent = make_agent(name, description, seed=seed)
            agent.reset(description, timestep, seed=seed * 100_003 + index)
            steps, solved, reason, right, judged = 0, False, None, 0, 0
            try:
                while not timestep.last():
                    action = agent.act(timestep)
                    if agent.scene is not None:  # the agent's estimate of this timestep
                        judged += 1
                        right += _grid_right(
                            agent.scene.state, raw.observation["full_entity_layer"]
                        )
                    if agent.gave_up is not None:
                        reason = agent.gave_up
                        break
                    raw = env.step(np.r_[action, 0.0])  # kick: 0
                    timestep = _visible(raw)
                    steps += 1
                # The original's own rule: the last step carries its +10 solved reward.
                solved = timestep.last() and float(timestep.reward) >= 10.0
            except Exception as exc:  # noqa: BLE001 - an error ends the episode, not the run
                reason = f"error: {type(exc).__name__}: {exc}"
            row = {
                "level": index,
                "solved": bool(solved),
                "steps": steps,
                "estimates": judged,
                "estimates_right": right,
                "wall_s": round(time.perf_counter() - start, 2),
            }
            if not solved:
                row["failure_reason"] = reason or TIME_LIMIT_REASON
            rows.append(row)
            bar.update(1)
            bar.set_postfix(solved=sum(r["solved"] for r in rows))
    finally:
        bar.close()
        if agent is not None:
            agent.close()
        env.close()
    solved = sum(r["solved"] for r in rows)
    low, high = wilson_interval(solved, len(rows))
    judged = sum(r["estimates"] for r in rows)
    return {
        "pegs": pegs,
        "episodes": len(rows),
        "solved": solved,
        "estimate_whole_grid_accuracy": sum(r["estimates_right"] for r in rows) / max(judged, 1),
        "estimates": judged,
        "success_rate": solved / max(len(rows), 1),
        "interval": [low, high],
        "mean_steps_solved": float(np.mean([r["steps"] for r in rows if r["solved"]]))
        if solved
        else None,
        "rows": rows,
    }


def side_by_side(level, seed: int, path: Path) -> dict:
    """Renders ``level`` in the original and in ours with the same texture draw
    and heading; writes the picture; returns each's object colours."""
    from PIL import Image

    np.random.seed(seed)  # the original draws its textures from numpy's global generator
    orig = original_env([level], pegs=False, seed=seed)
    orig_ts = orig.reset()
    arena = orig.task._arena  # pylint: disable=protected-access
    wall = arena._current_wall_texture["*"].name  # pylint: disable=protected-access
    floor_tex = orig.physics.bind(arena.mjcf_model.find("material", "floor_0")).texid
    floor_name = next(
        t.name
        for t in orig.task._arena.mjcf_model.find_all("texture")  # noqa
        if orig.physics.bind(t).element_id == int(np.ravel(floor_tex)[1])
    )
    heading = float(
        orig.physics.bind(
            orig.task._walker.mjcf_model.find(  # noqa
                "joint", "steer"
            )
        ).qpos[0]
    )

    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        level_file = Path(tmp) / "level.txt"
        write_levels([level], level_file)
        ours = envs.load(
            "mujoban/level1",
            seed=seed,
            levels=str(level_file),
            top_camera=FRAME,
            egocentric_camera=None,
        )
    ours.reset()
    task = ours.task
    task.set_appearance(wall, floor_name)
    steer = ours.physics.bind(task.walker.mjcf_model.find("joint", "steer"))
    steer.qpos = heading
    ours.physics.forward()
    ours_frame = ours.physics.render(*FRAME, camera_id="top_camera")
    orig_frame = np.asarray(orig_ts.observation["top_camera"])
    gap = np.full((FRAME[0], 8, 3), 255, np.uint8)
    Image.fromarray(np.concatenate([orig_frame, gap, ours_frame], 1)).resize(
        (2 * (2 * FRAME[1] + 8), 2 * FRAME[0]), Image.NEAREST
    ).save(path)
    diff = np.abs(orig_frame.astype(int) - ours_frame.astype(int)).max(-1)
    colours = {}
    for label, frame in (("original", orig_frame), ("ours", ours_frame)):
        looks = (
            original_description(orig, False).looks
            if label == "original"
            else ours.description().looks
        )
        colours[label] = {
            name: int(np.all(frame == np.rint(looks.facing_rgb(getattr(looks, name))), -1).sum())
            for name in ("box", "pad")
        }
    comparison = {
        "identical_pixels": float(np.mean(diff == 0)),
        "pixels_within_8_levels": float(np.mean(diff <= 8)),
        "mean_abs_difference": float(
            np.abs(orig_frame.astype(int) - ours_frame.astype(int)).mean()
        ),
        "pixels_of_exact_object_colour": colours,
    }
    orig.close()
    ours.close()
    return {"wall_texture": wall, "floor_texture": floor_name, "heading": heading, **comparison}


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--levels", type=cli.positive_int, default=20, help="Boxoban levels per setting"
    )
    parser.add_argument(
        "--file",
        type=Path,
        default=BOXOBAN_DIR / "unfiltered-valid-000.txt",
        help="Boxoban levels file (its first --levels levels are played)",
    )
    parser.add_argument(
        "--pegs",
        choices=("both", "yes", "no"),
        default="both",
        help="play with pegs, without, or both",
    )
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument("--picture", type=Path, help="write the side-by-side picture here")
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    env_cli.levels_file("mujoban/level5", args.file, flag="--file")
    cli.output_file(args.picture, "--picture")
    cli.output_file(args.json, "--json")
    _import_original()
    levels = read_levels(args.file)[: args.levels]
    out = {
        "levels_file": str(args.file.name),
        "levels": len(levels),
        "seed": args.seed,
        "frame_shape": list(FRAME),
        "agent": "modular: camera + sokoban-solver:time + ball",
        "privileged": False,
    }
    if args.picture:
        out["picture"] = {
            "path": str(args.picture),
            **side_by_side(levels[0], args.seed, args.picture),
        }
        print(
            f"wrote {args.picture}: "
            + ", ".join(f"{k} {v}" for k, v in out["picture"].items() if k not in ("path",))
        )
    else:
        settings = {"both": (False, True), "yes": (True,), "no": (False,)}[args.pegs]
        out["runs"] = [play(levels, pegs, args.seed) for pegs in settings]
        print(
            f"{'pegs':>5} {'levels':>6} {'solved':>7} {'rate':>7} {'95% interval':>15} "
            f"{'mean steps':>10} {'estimates right':>15}"
        )
        for run in out["runs"]:
            low, high = run["interval"]
            steps = run["mean_steps_solved"]
            print(
                f"{str(run['pegs']):>5} {run['episodes']:>6} {run['solved']:>7} "
                f"{100 * run['success_rate']:6.1f}% [{100 * low:5.1f}, {100 * high:5.1f}] "
                f"{steps if steps is None else round(steps):>10} "
                f"{100 * run['estimate_whole_grid_accuracy']:>14.2f}%"
            )
    if args.json:
        write_json(args.json, out)
    return 0


def main(argv=None) -> int:
    """Plays (or draws) both implementations, prints the table, writes
    ``--json``; bad input or a missing original: one line on stderr, exit
    status 2, before anything is played."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
