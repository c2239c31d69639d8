"""Soak: many episodes of every environment family, watching for leaks.

    python benchmarks/soak.py --episodes 1000 --json results/soak.json [--sample-every 50]

Cycles through MuJoBan (generated levels: a new level at every reset; with
and without pegs), MuJoXO and MuJoGo (against GNU Go), each with its cameras
on and off. Every configuration keeps one environment that is reset for each
of its episodes and is closed and rebuilt every ``--rebuild-every`` of them
(construction and ``close`` are soaked too). An episode is ``--steps``
control steps of random actions; in MuJoXO and MuJoGo it also plays
``--moves`` abstract moves for the agent through the task (random legal
moves), each answered by the opponent, so GNU Go plays real games over GTP
(its process starts, answers, and is closed with its environment).

Every ``--sample-every`` episodes (and at the start and end) it samples:
resident memory (VmRSS), open file descriptors, child processes, threads,
and live OpenGL contexts (`mujoco.Renderer` objects and GL context objects
found by the garbage collector: the contexts this process holds); and, to
tell where memory goes, the resident memory of the ``[heap]`` and of
anonymous mappings and glibc's ``mallinfo2`` (bytes in use in malloc's
arenas, free there, and in use in mmapped blocks). The JSON has the samples
and, per quantity, the change after the first 100 episodes; the issue's
targets are RSS growth < 50 MB after episode 100 and constant file
descriptors and child processes. ``--only mujogo`` (a substring, repeatable)
soaks just the matching configurations.

The environments fix glibc's mmap threshold (`envs._malloc`); without that
the resident memory of this soak grew by ~274 MB from episode 100 to 1000
(results/soak_before_fix.json).
"""

from __future__ import annotations

import gc
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, make_parser, prog, write_json  # noqa: E402

import numpy as np  # noqa: E402

import envs  # noqa: E402

PROG = prog(__file__)

#: (name, cameras on) configurations, cycled in this order.
CONFIGS = [
    ("mujoban/level1", False),
    ("mujoban/level3-pegs", True),
    ("mujoban/level5", False),
    ("mujoban/level2-pegs", False),
    ("mujoxo/mixture", True),
    ("mujoxo/mixture", False),
    ("mujogo/7x7", True),
    ("mujogo/7x7", False),
]


def _children() -> int:
    me, count = os.getpid(), 0
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    stat = f.read()
            except OSError:
                continue
            if int(stat[stat.rindex(")") + 2 :].split()[1]) == me:
                count += 1
    return count


def _status(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return -1


def _gl_contexts() -> int:
    gc.collect()
    count = 0
    for obj in gc.get_objects():
        name = type(obj).__name__
        if name == "GLContext" or name == "Renderer" and type(obj).__module__.startswith("mujoco"):
            count += 1
    return count


def _mappings() -> dict:
    """Resident MB of the ``[heap]`` and of anonymous mappings (smaps)."""
    rss = {"heap_rss_mb": 0, "anon_rss_mb": 0}
    key = None
    with open("/proc/self/smaps") as f:
        for line in f:
            fields = line.split()
            if not fields[0].endswith(":"):  # a mapping's header line
                path = fields[5] if len(fields) > 5 else ""
                key = "heap_rss_mb" if path == "[heap]" else "anon_rss_mb" if not path else None
            elif fields[0] == "Rss:" and key:
                rss[key] += int(fields[1])
    return {k: round(v / 1024, 1) for k, v in rss.items()}


def _malloc_stats() -> dict:
    """glibc's mallinfo2 in MB: in use and free in the arenas, in use in mmapped blocks."""
    m = envs._malloc.mallinfo()  # pylint: disable=protected-access
    if m is None:
        return {}
    return {
        "malloc_in_use_mb": round(m["uordblks"] / 2**20, 1),
        "malloc_free_mb": round(m["fordblks"] / 2**20, 1),
        "malloc_mmapped_mb": round(m["hblkhd"] / 2**20, 1),
    }


def sample(episode: int, started: float) -> dict:
    return {
        "episode": episode,
        "wall_s": round(time.perf_counter() - started, 1),
        "rss_mb": round(_status("VmRSS") / 1024, 1),
        "open_fds": len(os.listdir("/proc/self/fd")),
        "children": _children(),
        "threads": _status("Threads"),
        "gl_objects": _gl_contexts(),
        **_mappings(),
        **_malloc_stats(),
    }


def _build(name: str, cameras: bool, seed: int):
    kwargs = {} if cameras else envs.no_cameras(name)
    return envs.load(name, seed=seed, **kwargs)


def play_episode(env, rng, steps: int, moves: int) -> None:
    env.reset()
    spec = env.action_spec()
    for _ in range(steps):
        if env.step(rng.uniform(spec.minimum, spec.maximum)).last():
            return
    task = env.task
    if hasattr(task, "_play_agent_move"):  # board games: real opponent replies
        for _ in range(moves):
            if task.game_over or task.state.is_terminal():
                break
            legal = task.state.legal_actions()
            task._play_agent_move(int(rng.choice(legal)), None, rng)  # pylint: disable=protected-access


def soak(
    episodes: int,
    *,
    sample_every: int = 50,
    rebuild_every: int = 25,
    steps: int = 20,
    moves: int = 4,
    seed: int = 0,
    progress: bool = True,
    configs: list[tuple[str, bool]] | None = None,
) -> dict:
    configs = CONFIGS if configs is None else configs
    rng = np.random.default_rng(seed)
    live: dict[int, tuple] = {}  # config index -> (env, episodes played)
    samples, errors = [], []
    started = time.perf_counter()
    samples.append(sample(0, started))
    try:
        for episode in range(1, episodes + 1):
            index = (episode - 1) % len(configs)
            name, cameras = configs[index]
            env, played = live.get(index, (None, 0))
            if env is not None and played >= rebuild_every:
                env.close()
                env = None
            if env is None:
                env, played = _build(name, cameras, seed + episode), 0
            live[index] = (env, played + 1)
            try:
                play_episode(env, rng, steps, moves)
            except Exception as exc:  # noqa: BLE001 - counted, the soak goes on
                errors.append(
                    {"episode": episode, "env": name, "error": f"{type(exc).__name__}: {exc}"}
                )
            if episode % sample_every == 0 or episode == episodes:
                samples.append(sample(episode, started))
                if progress:
                    s = samples[-1]
                    print(
                        f"episode {episode:5d}: rss {s['rss_mb']:7.1f} MB "
                        f"(heap {s['heap_rss_mb']:.0f}, anon {s['anon_rss_mb']:.0f}), "
                        f"fds {s['open_fds']}, "
                        f"children {s['children']}, threads {s['threads']}, "
                        f"gl {s['gl_objects']}, {s['wall_s']:.0f} s",
                        flush=True,
                    )
    finally:
        for env, _ in live.values():
            env.close()
    after_close = sample(episodes, started)
    return {
        "episodes": episodes,
        "configs": [{"env": n, "cameras": c} for n, c in configs],
        "malloc": {
            "mmap_threshold_fixed_by_envs": envs._malloc.applied(),  # pylint: disable=protected-access
            **{
                k: os.environ[k]
                for k in ("MALLOC_ARENA_MAX", "MALLOC_MMAP_THRESHOLD_", "GLIBC_TUNABLES")
                if k in os.environ
            },
        },
        "steps_per_episode": steps,
        "moves_per_board_episode": moves,
        "rebuild_every": rebuild_every,
        "sample_every": sample_every,
        "samples": samples,
        "after_close": after_close,
        "errors": errors,
        "summary": summarise(samples, after_close),
    }


def select(only: list[str]) -> list[tuple[str, bool]]:
    """The configurations matching any of `only` (all of them if it is empty)."""

    def matches(name: str, cameras: bool, pattern: str) -> bool:
        if pattern in ("cameras-on", "cameras-off"):
            return cameras == (pattern == "cameras-on")
        return pattern in name

    return [(n, c) for n, c in CONFIGS if not only or any(matches(n, c, p) for p in only)]


def summarise(samples: list[dict], after_close: dict) -> dict:
    base = next((s for s in samples if s["episode"] >= 100), samples[0])
    last = samples[-1]
    out = {"from_episode": base["episode"], "to_episode": last["episode"]}
    for key in (
        "rss_mb",
        "heap_rss_mb",
        "anon_rss_mb",
        "open_fds",
        "children",
        "threads",
        "gl_objects",
    ):
        values = [s[key] for s in samples if s["episode"] >= base["episode"]]
        out[key] = {
            "at_base": base[key],
            "last": last[key],
            "min": min(values),
            "max": max(values),
            "growth": round(last[key] - base[key], 1),
        }
    out["children_after_close"] = after_close["children"]
    out["targets_met"] = {
        "rss_growth_under_50_mb": out["rss_mb"]["growth"] < 50,
        "fds_constant": out["open_fds"]["min"] == out["open_fds"]["max"],
        "children_constant": out["children"]["min"] == out["children"]["max"],
        "no_children_after_close": after_close["children"] == 0,
    }
    return out


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument("--episodes", type=cli.positive_int, default=1000)
    parser.add_argument(
        "--sample-every",
        type=cli.positive_int,
        default=50,
        help="episodes between resource samples",
    )
    parser.add_argument(
        "--rebuild-every",
        type=cli.positive_int,
        default=25,
        help="episodes between environment rebuilds",
    )
    parser.add_argument(
        "--steps", type=cli.positive_int, default=20, help="random control steps per episode"
    )
    parser.add_argument(
        "--moves",
        type=cli.positive_int,
        default=4,
        help="abstract agent moves (each answered) per board-game episode",
    )
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="SUBSTRING",
        help="soak only the configurations whose name contains this "
        "('cameras-on'/'cameras-off' select by camera setting); repeatable",
    )
    parser.add_argument("--json", type=Path, help="write the samples and summary here")
    args = parser.parse_args(argv)
    configs = select(args.only)
    if not configs:
        names = sorted({name for name, _ in CONFIGS})
        raise cli.UsageError(
            f"--only {' '.join(args.only)} matches none of the "
            f"configurations: {', '.join(names)}, cameras-on, cameras-off"
        )
    cli.output_file(args.json, "--json")
    result = soak(
        args.episodes,
        sample_every=args.sample_every,
        rebuild_every=args.rebuild_every,
        steps=args.steps,
        moves=args.moves,
        seed=args.seed,
        configs=configs,
    )
    summary = result["summary"]
    print(
        f"after episode {summary['from_episode']} -> {summary['to_episode']}: "
        f"rss {summary['rss_mb']['growth']:+.1f} MB, fds {summary['open_fds']['min']}-"
        f"{summary['open_fds']['max']}, children {summary['children']['min']}-"
        f"{summary['children']['max']} (after close {summary['children_after_close']}), "
        f"errors {len(result['errors'])}"
    )
    print(
        "targets: "
        + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in summary["targets_met"].items())
    )
    if args.json:
        write_json(args.json, result)
    return 0 if not result["errors"] else 1


def main(argv=None) -> int:
    """Soaks, prints the summary, writes ``--json``; returns 1 when an episode
    errored. Bad input: one line on stderr, exit status 2, before anything runs."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
