"""Every results table of the README and the documentation site, generated from the JSON
committed under results/.

    python benchmarks/readme_tables.py            # print every table
    python benchmarks/readme_tables.py --check    # exit 1 naming each table that disagrees
    python benchmarks/readme_tables.py --write    # rewrite the tables in README.md and docs/

A table lives in README.md or in any page under docs/ (``docs/**/*.md``; the results pages
are docs/results/) between marker comments::

    <!-- table:NAME -->
    | ... generated Markdown ... |
    <!-- /table:NAME -->

and is produced by the generator registered under NAME (`TABLES`). To add a
table, write a function that returns its Markdown lines from files under
``results/`` and decorate it with ``@table("NAME")``; put the markers in the
README or a docs page and run ``--write``. Nothing is measured here: every number
comes from a JSON that records its command, commit, date and machine (`provenance`).
A table may appear in several files; ``--check`` fails when any file's copy
disagrees with the JSON, when a registered table has markers in none of the files,
or when a file has markers no generator knows.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import sys
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

import agent_table  # noqa: E402
from _common import cli, make_parser, prog  # noqa: E402

PROG = prog(__file__)
#: The sides a two-player game is measured from, the agent moving first or second.
BOTH_SIDES = ("first", "second")

#: name -> function(results_dir) -> list of Markdown lines.
TABLES: dict[str, Callable[[Path], list[str]]] = {}


def table(name: str):
    """Registers a table generator under ``name`` (its README marker name)."""

    def register(func):
        if name in TABLES:
            raise ValueError(f"table {name!r} is already registered")
        TABLES[name] = func
        return func

    return register


def _load(path: Path) -> dict:
    return json.loads(path.read_text())


# -- generators -----------------------------------------------------------------


def _rate(summary: dict, key: str = "success") -> str:
    """``"NN% [lo, hi]"`` of a run summary's rate and 95% Wilson interval."""
    low, high = summary[f"{key}_interval"]
    return f"{100 * summary[f'{key}_rate']:.1f}% [{100 * low:.1f}, {100 * high:.1f}]"


@table("headline")
def headline(results: Path) -> list[str]:
    """The README's few headline results, each from its committed JSON, with
    a link to the page that holds the full table."""
    agent = results / "agent"
    levels = [_load(agent / f"mujoban_level{k}-pegs.json") for k in range(1, 6)]
    solved = [s["success_rate"] for s in levels]
    boxoban = [
        (label, _load(agent / name))
        for label, name in (
            ("medium, first 100", "boxoban_medium-valid-000_first100-pegs.json"),
            ("unfiltered, first 200", "boxoban_unfiltered-valid-000_first200-pegs.json"),
            ("hard, first 200", "boxoban_hard-001-200-pegs.json"),
        )
    ]
    xo = [_load(agent / f"mujoxo_optimal_camera_{side}.json") for side in BOTH_SIDES]
    go = _load(agent / "mujogo_7x7_camera.json")
    compare = _load(results / "compare" / "mujoban" / "comparison.json")
    level1 = _complete_points(compare, "mujoban/level1")
    best_e2e = _best_trained(level1)
    modular = next(p for p in level1 if p["agent"] == "modular: scripted")
    span = (
        f"{100 * min(solved):.0f}"
        if min(solved) == max(solved)
        else f"{100 * min(solved):.0f}-{100 * max(solved):.0f}"
    )
    e2e = f"{best_e2e['agent']}, {best_e2e['budget']:,} frames" + (
        ", PRIVILEGED" if best_e2e.get("privileged") else ""
    )
    rows = [
        (
            "MuJoBan levels 1-5, with pegs",
            "modular (camera)",
            f"{span}% solved, {levels[0]['episodes']} episodes each",
            "results/agent.md",
        ),
        *(
            (
                f"Boxoban {label}, with pegs",
                "modular (camera)",
                f"{_rate(s)} solved of {s['episodes']}",
                "results/agent.md",
            )
            for label, s in boxoban
        ),
        (
            "MuJoXO against the optimal opponent",
            "modular (camera)",
            f"{sum(round(s['loss_rate'] * s['episodes']) for s in xo)} lost of "
            f"{sum(s['episodes'] for s in xo)} games (first and second)",
            "results/agent.md",
        ),
        (
            "MuJoGo 7x7 against GNU Go 10",
            "modular (camera)",
            f"{_rate(go, 'win')} won of {go['episodes']}",
            "results/agent.md",
        ),
        (
            "`mujoban/level1`, 3 seeds",
            "modular (camera) against end-to-end",
            f"{100 * modular['mean']:.0f}% solved against {100 * best_e2e['mean']:.0f}% for the "
            f"best end-to-end point ({e2e})",
            "results/comparison.md",
        ),
    ]
    rows.append(_boards_headline(_load(results / "compare" / "boards" / "comparison.json")))
    lines = [
        "| task | agent (observes) | result [95% interval] | details |",
        "| --- | --- | --- | --- |",
    ]
    lines += [
        f"| {task} | {who} | {result} | [{page.split('/')[-1][:-3]}](docs/{page}) |"
        for task, who, result, page in rows
    ]
    return lines


def _complete_points(data: dict, env: str) -> list[dict]:
    """The points of a comparison.json on ``env`` with every seed evaluated."""
    return [p for p in data["points"] if p["env"] == env and not p["missing_seeds"]]


def _best_trained(points: list[dict]) -> dict:
    """Of ``points``, the trained (end-to-end) one with the highest mean."""
    return max((p for p in points if p["kind"] == "train"), key=lambda p: p["mean"])


def _boards_headline(data: dict) -> tuple[str, str, str, str]:
    """The headline row of the board games' comparison (a comparison.json):
    per environment, the camera agent's mean game score and the best
    end-to-end point's (its frames, and whether it observed privileged
    state)."""
    envs = data["spec"]["envs"]
    camera, e2e, budgets, privileged = [], [], set(), False
    for env in envs:
        here = _complete_points(data, env)
        modular = next(p for p in here if p["agent"] == "modular: camera")
        best = _best_trained(here)
        camera.append(f"{100 * modular['mean']:.1f}")
        e2e.append(f"{100 * best['mean']:.1f}")
        budgets.add(best["budget"])
        privileged |= bool(best.get("privileged"))
    frames = " / ".join(f"{b:,}" for b in sorted(budgets))
    return (
        ", ".join(f"`{e}`" for e in envs) + ", 3 seeds",
        "modular (camera) against end-to-end",
        f"game score {' / '.join(camera)}% against {' / '.join(e2e)}% for the best "
        f"end-to-end point ({frames} frames{', PRIVILEGED' if privileged else ''})",
        "results/comparison.md",
    )


@table("agent-results")
def agent_results(results: Path) -> list[str]:
    """The modular agent's results: exactly what `benchmarks/agent_table.py`
    prints from results/agent/ (its file order and labels)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = agent_table.main(["--dir", str(results / "agent")])
    if code:
        raise RuntimeError(f"benchmarks/agent_table.py exited with {code}")
    return out.getvalue().splitlines()


#: execution_time JSONs in the README's order: (file under results/, ball skill).
#: ``execution_time_before/`` holds the runs with the ball skill of issue 13
#: (it stopped after every stroke; the time model's first weights).
EXECUTION_TIME_FILES = (
    ("execution_time_before/execution_time_medium.json", "issue 13"),
    ("execution_time_before/execution_time_medium_time-planner.json", "issue 13"),
    ("execution_time_medium.json", "chained"),
    ("execution_time_medium_time-planner.json", "chained"),
    ("execution_time_medium_time-planner_oracle.json", "chained"),
    ("execution_time_before/execution_time_unfiltered.json", "issue 13"),
    ("execution_time_before/execution_time_unfiltered_time-planner.json", "issue 13"),
    ("execution_time_unfiltered_time-planner.json", "chained"),
)


@table("agent-original-physics")
def agent_original_physics(results: Path) -> list[str]:
    """MuJoBan's modular-agent rows at the default (resting bodies sleep,
    ``results/agent/``) beside the same commands on the original's physics
    (``sleep=False``: ``results/agent_original_physics/``, measured before the
    default changed), episode for episode."""
    before_dir = results / "agent_original_physics"
    lines = [
        "| environment | levels | estimator | default (sleep): solved [95% CI], mean steps "
        "| original's physics: solved [95% CI], mean steps | intervals overlap "
        "| episodes ending alike |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for path in sorted(before_dir.rglob("*.json"), key=lambda p: (p.parent.name, p.name)):
        before = _load(path)
        now = _load(results / "agent" / path.relative_to(before_dir))
        if before.get("deviations") or now.get("deviations") != {"sleep": True}:
            raise ValueError(f"{path}: not a default row beside an original-physics one")
        alike = sum(
            a["solved"] == b["solved"] for a, b in zip(now["rows"], before["rows"], strict=True)
        )
        overlap = (
            now["success_interval"][0] <= before["success_interval"][1]
            and before["success_interval"][0] <= now["success_interval"][1]
        )
        levels = Path(now["levels"]).name if now.get("levels") else "generated"
        lines.append(
            f"| `{now['env']}` | {levels} | {now['estimator']} "
            f"| {_rate(now)}, {now['mean_steps_solved']:.0f} "
            f"| {_rate(before)}, {before['mean_steps_solved']:.0f} "
            f"| {'yes' if overlap else 'no'} | {alike} of {len(now['rows'])} |"
        )
    return lines


@table("execution-time")
def execution_time(results: Path) -> list[str]:
    """Real Boxoban levels against the clock (`benchmarks/execution_time.py`)."""
    lines = [
        "| levels (pegs) | planner | ball skill | estimator | solved [95% CI] "
        "| control steps per push "
        "| share of the limit used, solved levels (median / p90 / max) "
        "| time model: estimate - measured, mean / mean abs (solved levels) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    runs = [(_load(results / name)["summary"], skill) for name, skill in EXECUTION_TIME_FILES]
    for s, skill in runs:
        # A run whose fitted weights are the ones other runs used: the model
        # was fitted on it, so its estimate error is not out of sample.
        used_elsewhere = [o["default_weights"] for o, _ in runs if o is not s]
        label = f"`{s['levels_file']}`, first {s['levels']}"
        planner = f"`{s.get('planner') or 'sokoban-solver'}`"
        estimator = s["estimator"] + (" (**privileged**)" if s.get("privileged") else "")
        low, high = s["success_interval"]
        solved = f"{100 * s['success_rate']:.1f}% [{100 * low:.1f}, {100 * high:.1f}]"
        share = s["limit_share_solved"]
        shares = " / ".join(f"{100 * share[k]:.0f}%" for k in ("median", "p90", "max"))
        fitted = s.get("fitted_weights")
        if (
            fitted
            and any(_same_weights(fitted, w) for w in used_elsewhere)
            and not _same_weights(s["default_weights"], fitted)
        ):
            error = "the weights were fitted on this run"
        else:
            err = s["estimate_error_solved"]
            error = f"{err['mean']:+.0f} / {err['mean_abs']:.0f}".replace("+-", "-")
            if error.startswith("-0 ") or error.startswith("+0 "):
                error = "0" + error[2:]
        lines.append(
            f"| {label} | {planner} | {skill} | {estimator} | {solved} | "
            f"{s['mean_steps_per_push']:.1f} | {shares} | {error} |"
        )
    return lines


def _same_weights(a: dict, b: dict) -> bool:
    keys = ("walk", "push", "stroke", "turn")
    return all(abs(float(a[k]) - float(b[k])) < 0.05 for k in keys)


def _whole(value: float) -> str:
    """Rounded half up, thousands separated (470.5 -> "471")."""
    return f"{math.floor(value + 0.5):,}"


def _span(values, fmt=None) -> str:
    show = _whole if fmt is None else fmt.format
    low, high = show(min(values)), show(max(values))
    return low if low == high else f"{low}-{high}"


def _speed_row(label: str, rows: list[dict], *, ratio: bool, level5: bool) -> str:
    steps = _span([r["steps_per_s"] for r in rows])
    fives = [r for r in rows if r["env"].startswith("mujoban/level5")]
    if level5 and fives:
        steps += f" (level 5: {_span([r['steps_per_s'] for r in fives])})"
    limit = _span([r["ratio"] for r in rows], "{:.2f}") if ratio else "-"
    reset = _span([1000 * r["reset_s"] for r in rows]) + " ms"
    return f"| {label} | {steps} | {limit} | {reset} |"


@table("env-speed")
def env_speed(results: Path) -> list[str]:
    """Control steps/s of every environment (`benchmarks/env_speed.py`), cameras off and on."""
    rows = _load(results / "env_speed.json")["rows"]
    both = _load(results / "env_speed_both_cameras.json")["rows"]
    mujoban = [r for r in rows if r["env"].startswith("mujoban/")]
    boards = [r for r in rows if not r["env"].startswith("mujoban/")]
    cams = lambda group, cameras: [r for r in group if r["cameras"] == cameras]  # noqa: E731
    return [
        "| setting | steps/s | physics limit ratio | reset |",
        "| --- | --- | --- | --- |",
        _speed_row(
            "MuJoBan, cameras off, levels 1-5 with and without pegs",
            cams(mujoban, []),
            ratio=True,
            level5=True,
        ),
        _speed_row(
            "MuJoBan, 96x96 top camera", cams(mujoban, ["top_camera"]), ratio=False, level5=True
        ),
        _speed_row(
            "MuJoBan, both 96x96 cameras (the default observations), level 5",
            both,
            ratio=False,
            level5=False,
        ),
        _speed_row("MuJoXO / MuJoGo, cameras off", cams(boards, []), ratio=True, level5=False),
        _speed_row(
            "MuJoXO / MuJoGo, 84x84 front camera (the paper's one camera)",
            cams(boards, ["front_camera"]),
            ratio=False,
            level5=False,
        ),
        _speed_row(
            "MuJoXO / MuJoGo, two 84x84 views (the original code's set)",
            cams(boards, ["front_camera", "front_camera_2"]),
            ratio=False,
            level5=False,
        ),
    ]


@table("original-speed")
def original_speed(results: Path) -> list[str]:
    """Ours and the original side by side (`benchmarks/original_speed.py`), per pair."""
    d = _load(results / "original_speed.json")
    lines = [
        "| pair (same timestep, cameras, random actions) | ours, steps/s | the original, "
        "steps/s | x the original |",
        "| --- | --- | --- | --- |",
    ]
    pairs = list(dict.fromkeys(r["pair"] for r in d["rows"]))
    for pair in pairs:
        rows = [r for r in d["rows"] if r["pair"] == pair]
        lines.append(
            f"| {pair} | {_span([r['ours_steps_per_s'] for r in rows], '{:.0f}')} "
            f"| {_span([r['original_steps_per_s'] for r in rows], '{:.1f}')} "
            f"| {_span([r['x_original'] for r in rows], '{:.1f}')}x |"
        )
    return lines


@table("physical-limit")
def physical_limit(results: Path) -> list[str]:
    """Control steps the agent took on Boxoban hard over the walker's lower
    bound (`benchmarks/physical_limit.py`), medians over the solved levels and all."""
    d = _load(results / "physical_limit_hard.json")
    lines = [
        "| levels | levels counted | median bound, control steps | median steps taken "
        "| median steps / bound |",
        "| --- | --- | --- | --- | --- |",
    ]
    names = {
        "solved": "solved",
        "all": "all (an unsolved level counts the 900-step limit: a floor)",
    }
    for key, label in names.items():
        s = d["summary"][key]
        lines.append(
            f"| {label} | {s['levels']} | {s['median_bound_steps']:.0f} "
            f"| {s['median_steps']:.0f} | {s['median_steps_over_bound']:.2f} |"
        )
    return lines


@table("compare-check")
def compare_check(results: Path) -> list[str]:
    """The shipped comparisons' records replayed from their shipped
    checkpoints (``python -m hier_agents.compare SPEC --check N``,
    ``results/compare/NAME/check.json``), one row per comparison."""
    lines = [
        "| comparison | episodes per point | points replayed | agree | differ (records of this "
        "CPU kind) | differ (records of another CPU kind) | failed | not replayed | wall time "
        "| CPUs |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name in ("mujoban", "boards"):
        d = _load(results / "compare" / name / "check.json")
        pts = d["points"]
        differ = sum(1 for p in pts if p.get("differences") and not p["other_cpu"])
        other = sum(1 for p in pts if p.get("differences") and p["other_cpu"])
        failed = sum(1 for p in pts if "error" in p)
        agree = len(pts) - differ - other - failed
        minutes, seconds = divmod(round(d["wall_s"]), 60)
        lines.append(
            f"| `experiments/{name}.toml` | {d['episodes_per_point']} | {len(pts)} "
            f"({sum(p['episodes'] for p in pts)} episodes) | {agree} | {differ} | {other} "
            f"| {failed} | {len(d['not_replayed'])} | {minutes} min {seconds:02d} s "
            f"| {d['cpus']} |"
        )
    return lines


@table("board-physics")
def board_physics(results: Path) -> list[str]:
    """The board games' raw physics under cheaper solver settings
    (`benchmarks/board_physics.py`), as ratios to the compiled default."""
    d = _load(results / "board_physics.json")
    lines = [
        "| environment | setting | mj_step/s (median) | x the default |",
        "| --- | --- | --- | --- |",
    ]
    for r in d["rows"]:
        lines.append(
            f"| `{r['env']}` | {r['setting']} | {r['mj_steps_per_s']:,.0f} "
            f"| {_span(r['x_default_rounds'], '{:.2f}')}x |"
        )
    return lines


@table("physics-behaviour")
def physics_behaviour(results: Path) -> list[str]:
    """Candidate physics settings: behaviour against the original's and speed beside it
    (`benchmarks/physics_behaviour.py`)."""
    d = _load(results / "physics_behaviour.json")
    original = d["original"]
    lines = [
        "| setting | walker rolls / coasts, m | pushes a box, m | 10 / 20 / 40 N slide a box, m "
        "| largest deviation from the original | x the original, no pegs | with pegs |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]

    def cells(v: dict) -> str:
        return (
            f"{v['roll_m']:.3f} / {v['coast_m']:.3f} | {v['push_box_m']:.3f} "
            f"| {v['slide_10N_m']:.4f} / {v['slide_20N_m']:.3f} / {v['slide_40N_m']:.3f}"
        )

    lines.append(f"| the original | {cells(original)} | - | 1x | 1x |")
    for row in d["rows"]:
        within = "within 1%" if row["within_tolerance"] else "**outside the tolerance**"
        speed = [
            _span([s["x_original"] for s in row["speed"] if s["pegs"] is pegs], "{:.1f}") + "x"
            for pegs in (False, True)
        ]
        lines.append(
            f"| {row['setting']} | {cells(row['behaviour'])} "
            f"| {row['max_deviation']:.2%} ({within}) | {speed[0]} | {speed[1]} |"
        )
    return lines


@table("vector-speed")
def vector_speed(results: Path) -> list[str]:
    """Batched environments against one environment and gymnasium's vector
    environments (`benchmarks/vector_speed.py`), medians over its rounds."""
    d = _load(results / "vector_speed.json")
    lines = [
        "| environment | setup | environments | physics threads | steps/s | x one environment "
        "| x `AsyncVectorEnv` of 2 |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    names = {
        "single": "one environment",
        "processes": "independent processes at once (the cores' ceiling)",
        "async": "gymnasium `AsyncVectorEnv` (a process each)",
        "sync": "gymnasium `SyncVectorEnv`",
        "batched": "`envs.vector` (batched)",
    }
    for r in d["rows"]:
        if r["setup"] == "batched" and r["threads"] == 1 and r["num_envs"] != 16:
            continue  # one thread: the N=16 row stands for the rest
        x_async = "-" if r["x_async2"] is None else f"{r['x_async2']:.2f}"
        lines.append(
            f"| `{r['env']}` | {names[r['setup']]} | {r['num_envs']} "
            f"| {r['threads'] if r['threads'] is not None else '-'} | {r['steps_per_s']:,.0f} "
            f"| {r['x_single']:.2f} | {x_async} |"
        )
    return lines


@table("learner-speed")
def learner_speed(results: Path) -> list[str]:
    """Actor-learner frames/s against as many bare environment processes stepping at once
    and, for actors that batch their physics on threads, against the same batch
    stepping alone; one row per measurement (each measured in one run, side by side)."""
    lines = [
        "| run | learner frames/s | bare environment processes at once | ratio to them "
        "| the same batch alone, on its threads | ratio to it | one bare process | ratio to it |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name in LEARNER_SPEED_FILES:
        if not (results / name).exists():
            continue
        s = _load(results / name)
        procs = s["actors"]
        words = {1: "one", 2: "two", 3: "three", 4: "four"}.get(procs, str(procs))
        state = ", abstract state (privileged)" if s.get("state") else ""
        threads = s.get("env_threads", 1)
        on = f", physics on {threads} threads" if threads > 1 else ""
        options = "".join(
            f", {key.replace('_', ' ')} {value}"
            for key, value in s.get("train_options", {}).items()
        )
        batched = (
            ("-", "-")
            if s.get("batched_env_steps_per_s") is None
            else (
                f"{s['batched_env_steps_per_s']:,.0f} steps/s",
                f"**{s['ratio_to_batched']:.2f}**",
            )
        )
        # The ratio that matters is in bold: to the processes, or to the batch.
        to_parallel = f"{s['ratio_to_parallel']:.2f}"
        to_parallel = to_parallel if threads > 1 else f"**{to_parallel}**"
        lines.append(
            f"| `{s['env']}` {s['agent']}, cameras {'on' if s['cameras'] else 'off'}"
            f"{state}{options}, {procs} actors x {s['envs_per_actor']} envs{on} "
            f"({s['backend']}) "
            f"| {s['learner_frames_per_s']:,.0f} | {words}: "
            f"{s['parallel_env_steps_per_s']:,.0f} steps/s "
            f"| {to_parallel} "
            f"| {batched[0]} | {batched[1]} "
            f"| {s['env_steps_per_s']:,.0f} steps/s | {s['ratio']:.2f} |"
        )
    return lines


#: `learner_speed`'s rows, in the table's order.
LEARNER_SPEED_FILES = (
    "learner_speed.json",
    "learner_speed_state.json",
    "learner_speed_state_2x32.json",
    "learner_speed_state_threads.json",
    "learner_speed_comparison_row.json",
    "learner_speed_comparison_row_threads.json",
)


def _level_key(path: Path):
    stem = path.stem.split("level", 1)[-1]
    return (int(stem.split("-")[0]) if stem[:1].isdigit() else 99, stem)


def _ci(rate, interval) -> str:
    return f"{100 * rate:.1f}% [{100 * interval[0]:.1f}, {100 * interval[1]:.1f}]"


@table("soak")
def soak(results: Path) -> list[str]:
    """`benchmarks/soak.py`: each sampled quantity after the first 100 episodes."""
    d = _load(results / "soak.json")
    summary = d["summary"]
    lines = [
        f"| quantity (episodes {summary['from_episode']}-{summary['to_episode']}) "
        "| at episode 100 | last | min | max | growth |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for key, words in (
        ("rss_mb", "resident memory, MB"),
        ("heap_rss_mb", "of it the heap, MB"),
        ("anon_rss_mb", "anonymous mappings, MB"),
        ("open_fds", "file descriptors"),
        ("children", "child processes"),
        ("threads", "threads"),
        ("gl_objects", "GL contexts"),
    ):
        q = summary.get(key)
        if q is None:
            continue
        lines.append(
            f"| {words} | {q['at_base']:g} | {q['last']:g} | {q['min']:g} | {q['max']:g} "
            f"| {q['growth']:+g} |"
        )
    return lines


@table("learned-ball")
def learned_ball(results: Path) -> list[str]:
    """Solver + learned ball skill on generated levels, beside the scripted skill's rows."""
    lines = [
        "| environment | learned skill: solved [95% CI] | mean steps | subgoal success "
        "| scripted skill (results/agent): solved | mean steps |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for path in sorted((results / "learned_ball").glob("run_level*.json"), key=_level_key):
        s = _load(path)
        if s.get("skill") != "learned-ball" or s.get("privileged"):
            raise ValueError(f"{path}: not an observation-only learned-ball run")
        ref_path = results / "agent" / (s["env"].replace("/", "_") + ".json")
        ref = _load(ref_path) if ref_path.exists() else None
        sub = s.get("subgoal_success_rate")
        lines.append(
            f"| `{s['env']}` | {_ci(s['success_rate'], s['success_interval'])} "
            f"| {s['mean_steps']:.0f} | {'-' if sub is None else f'{100 * sub:.1f}%'} | "
            + (
                f"{_ci(ref['success_rate'], ref['success_interval'])} | {ref['mean_steps']:.0f} |"
                if ref
                else "- | - |"
            )
        )
    opt = _load(results / "learned_ball" / "option_success_camera.json")
    for name, r in opt["rows"].items():
        success = _ci(r["success"], (r["wilson_low"], r["wilson_high"]))
        lines.append(
            f"| held-out options, {', '.join(r['sources'])} scenes, {r['estimator']} "
            f"estimator, {name} | {success} "
            f"({r['successes']}/{r['episodes']}) | {r['mean_steps_success']:.0f} | - "
            f"| - | - |"
        )
    return lines


def _wdl(s: dict) -> str:
    return f"{100 * s['win_rate']:.0f}% / {100 * s['draw_rate']:.0f}% / {100 * s['loss_rate']:.0f}%"


@table("learned-arm")
def learned_arm(results: Path) -> list[str]:
    """Default planner + learned arm skill on the board games, beside the
    scripted (mink) skill's rows, and the skill alone on held-out options."""
    lines = [
        "| environment | games | learned arm: win / draw / loss | touches registered "
        "| scripted arm (results/agent): win / draw / loss | touches registered |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for path in sorted((results / "learned_arm").glob("run_*.json")):
        s = _load(path)
        if s.get("skill") != "learned-arm" or s.get("privileged"):
            raise ValueError(f"{path}: not an observation-only learned-arm run")
        ref_path = results / "agent" / (s["env"].replace("/", "_") + ".json")
        ref = _load(ref_path) if ref_path.exists() else None
        lines.append(
            f"| `{s['env']}` | {s['episodes']} | {_wdl(s)} "
            f"| {100 * s['subgoal_success_rate']:.1f}% | "
            + (f"{_wdl(ref)} | {100 * ref['subgoal_success_rate']:.1f}% |" if ref else "- | - |")
        )
    opt_path = results / "learned_arm" / "option_success.json"
    if opt_path.exists():
        opt = _load(opt_path)
        for name, r in opt["rows"].items():
            lines.append(
                f"| held-out options (MuJoXO and MuJoGo scenes), {name} | {r['episodes']} "
                f"| - | {_ci(r['success'], (r['wilson_low'], r['wilson_high']))} "
                f"| - | - |"
            )
    return lines


@table("option-policy")
def option_policy(results: Path) -> list[str]:
    """The learned policy over options as a planner (`results/option_policy/`)."""
    folder = results / "option_policy"
    lines = [
        "| policy over options | environment | solved [95% CI] | mean steps "
        "| subgoal success | frames trained (planner + skill) | abstract option steps "
        "| training CPU (planner) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    groups = (
        (
            "",
            "approach_D/train_D_summary.json",
            "**shipped** (`learned`): approach D, the learned policy alone",
        ),
        (
            "approach_B",
            "approach_B/train_B_summary.json",
            "approach B + hand-written dead-push rule",
        ),
        (
            "approach_B/no_pruning",
            "approach_B/train_B_summary.json",
            "approach B, the learned policy alone",
        ),
    )
    for sub, train, words in groups:
        t = _load(folder / train)
        for path in sorted((folder / sub).glob("level*.json"), key=_level_key):
            s = _load(path)
            if s.get("privileged") or not str(s.get("planner", "")).startswith("learned"):
                raise ValueError(f"{path}: not an observation-only learned-planner run")
            sub_rate = s.get("subgoal_success_rate")
            lines.append(
                f"| {words}, skill `{s['skill']}` | `{s['env']}` "
                f"| {_ci(s['success_rate'], s['success_interval'])} | {s['mean_steps']:.0f} "
                f"| {'-' if sub_rate is None else f'{100 * sub_rate:.1f}%'} "
                f"| {t['control_frames']:,} + {s['training_frames'] - t['control_frames']:,} "
                f"| {t['abstract_steps']:,} | {t['cpu_minutes']:.1f} min |"
            )
    return lines


def _points_to_come(data: dict) -> list[str]:
    """``AGENT on ENV at B1, B2 frames`` for each spec budget without a point
    of all its seeds in ``data`` (a comparison.json)."""
    done = {(p["agent"], p["env"], p["budget"]) for p in data["points"] if not p["missing_seeds"]}
    out = []
    for agent in data["spec"]["agent"]:
        budgets = agent.get("budgets")
        if not budgets:
            continue
        for env in agent.get("envs") or data["spec"]["envs"]:
            wanted = budgets.get(env, []) if isinstance(budgets, dict) else budgets
            todo = [b for b in wanted if (agent["label"], env, b) not in done]
            if todo:
                frames = ", ".join(f"{b:,}" for b in todo)
                out.append(f"{agent['label']} on `{env}` at {frames} frames")
    return out


def _compare(results: Path, name: str) -> list[str]:
    """A shipped comparison (``python -m hier_agents.compare
    experiments/NAME.toml``, its outputs in ``results/compare/NAME``): one row
    per environment and point, the points still to come, then each series'
    CPU hours."""
    from hier_agents.compare import report

    data = _load(results / "compare" / name / "comparison.json")
    lines = report.format_markdown(data["spec"]["envs"], data["points"], data["series_cost"])
    if data["jobs_missing"]:
        lines += [
            "",
            f"*{data['jobs_missing']} of {data['jobs']} jobs not run yet; "
            f"points still to come: {'; '.join(_points_to_come(data))}.*",
        ]
    lines += [
        "",
        "| series | environment | training CPU-h | evaluation CPU-h | jobs |",
        "| --- | --- | --- | --- | --- |",
    ]
    for c in data["series_cost"]:
        train, evals = (
            f"{'>=' if c[f'cpu_partial_{kind}_jobs'] else ''}{c[f'{kind}_cpu_hours']:.2f}"
            for kind in ("train", "eval")
        )
        lines.append(
            f"| {c['agent']} | `{c['env']}` | {train if c['train_jobs'] else '-'} "
            f"| {evals} "
            f"| {c['train_jobs']} training, {c['eval_jobs']} evaluation |"
        )
    return lines


@table("compare-mujoban")
def compare_mujoban(results: Path) -> list[str]:
    """MuJoBan's shipped comparison (`_compare`)."""
    return _compare(results, "mujoban")


@table("compare-boards")
def compare_boards(results: Path) -> list[str]:
    """The board games' shipped comparison (`_compare`)."""
    return _compare(results, "boards")


#: The MuJoBoard games with camera rows, and their sides measured
#: (checkers with the agent second is not measured yet).
CAMERA_BOARDS = {
    "connect_four": BOTH_SIDES,
    "hex-7x7": BOTH_SIDES,
    "othello-8x8": BOTH_SIDES,
    "gomoku-9x9": BOTH_SIDES,
    "breakthrough-6x6": BOTH_SIDES,
    "checkers": BOTH_SIDES,
    "clobber-5x6": BOTH_SIDES,
}


@table("mujoboard-camera")
def mujoboard_camera(results: Path) -> list[str]:
    """The observation-only board rows (``--estimator camera``), first and
    second: the MuJoBoard games measured with the camera (`CAMERA_BOARDS`),
    MuJoXO against the optimal opponent, then MuJoGo 7x7; each with the
    commit it was measured at."""
    lines = [
        "| game | agent moves | won / drawn / lost [95% CI of won] | estimated board right "
        "| wrong move | other failed touches | cut-off options | control steps / s | commit |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    sides = {f"mujoboard/{game}": s for game, s in CAMERA_BOARDS.items()}
    sides["mujoxo/optimal"] = BOTH_SIDES
    rows = [
        (env, side, f"{env.replace('/', '_')}_camera_{side}.json")
        for env, measured in sides.items()
        for side in measured
    ] + [
        ("mujogo/7x7", "first", "mujogo_7x7_camera.json"),
        ("mujogo/7x7", "second", "mujogo_7x7_camera_second.json"),
    ]
    for env, side, name in rows:
        s = _load(results / "agent" / name)
        if s.get("estimator") != "camera" or s.get("privileged") or s.get("env") != env:
            raise ValueError(f"{name}: not a camera row of {env}")
        failures = s["subgoals"]["failures"]
        wrong = sum(v for k, v in failures.items() if k.startswith("wrong move"))
        other = sum(failures.values()) - wrong
        lines.append(
            f"| `{env}` | {side} | {_ci(s['win_rate'], s['win_interval'])} / "
            f"{100 * s['draw_rate']:.0f}% / {100 * s['loss_rate']:.0f}% "
            f"| {100 * s['estimate_accuracy']:.2f}% | {wrong} | {other} "
            f"| {s['subgoals']['cut_off']} | {s['control_steps_per_s']:.0f} "
            f"| `{s['provenance']['commit'][:7]}` |"
        )
    return lines


#: `benchmarks/agent_speed.py` results: MuJoBan, then the board games.
AGENT_SPEED_FILES = ("agent_speed.json", "agent_speed_mujoxo.json", "agent_speed_mujogo.json")


@table("agent-speed")
def agent_speed(results: Path) -> list[str]:
    """The camera agent against the environment alone (`benchmarks/agent_speed.py`)."""
    lines = [
        "| environment | code | agent steps/s | environment alone, no camera | ratio "
        "| solved / won | time: physics / render / estimator / planner / skill / other |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name in AGENT_SPEED_FILES:
        d = _load(results / name)
        for tree in ("current", "baseline"):
            if tree not in d["summary"]:
                continue
            rows = [r["trees"][tree] for r in d["rounds"]]
            s = d["summary"][tree]
            label = "now" if tree == "current" else f"before (`{d['baseline']}`)"
            shares = s["shares"]
            lines.append(
                f"| `{d['env']}` | {label} "
                f"| {_span([r['agent']['steps_per_s'] for r in rows], '{:.0f}')} "
                f"| {_span([r['env']['steps_per_s'] for r in rows], '{:.0f}')} "
                f"| **{_span([r['ratio'] for r in rows], '{:.3f}')}** "
                f"| {100 * s['success_rate']:.0f}% of {len(rows)} x {d['episodes']} | "
                + " / ".join(
                    f"{100 * shares[k]:.0f}%"
                    for k in ("physics", "render", "estimator", "planner", "skill", "other")
                )
                + " |"
            )
    return lines


@table("board-looks")
def board_looks(results: Path) -> list[str]:
    """Per board-game look: ms per 84x84 frame and the difference of its image
    from the default look's (`benchmarks/board_looks.py`)."""
    d = _load(results / "board_looks.json")
    default = {r["env"]: r["ms_per_frame"] for r in d["rows"] if r["look"] == "default"}
    lines = [
        "| environment | look | ms per 84x84 frame | x the default | mean difference "
        "from the default (of 255) | pixels off by more than 8 | against the 4096-texel map: "
        "mean difference, pixels off by more than 8 |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    # The library's own map against 4096 is recorded on the 4096 row.
    own = {r["env"]: r["shadow_map_vs_4096"] for r in d["rows"] if "shadow_map_vs_4096" in r}
    for r in d["rows"]:
        full = r.get("vs_4096")
        if r["look"] == "original (multisamples=4, shadows)":
            full = own[r["env"]]
        against = f"{full['mean_abs']:.2f}, {100 * full['share_above_8']:.2f}%" if full else "-"
        lines.append(
            f"| `{r['env']}` | {r['look']} | {r['ms_per_frame']:.1f} "
            f"| {r['ms_per_frame'] / default[r['env']]:.1f}x "
            f"| {r['vs_default']['mean_abs']:.2f} "
            f"| {100 * r['vs_default']['share_above_8']:.1f}% | {against} |"
        )
    return lines


@table("camera-speed")
def camera_speed(results: Path) -> list[str]:
    """The paper's cameras, this code beside a baseline commit (`benchmarks/camera_speed.py`)."""
    d = _load(results / "camera_speed.json")
    lines = [
        f"| environment | cameras | steps/s now | steps/s at `{d['baseline']}` | speed-up |",
        "| --- | --- | --- | --- | --- |",
    ]
    settings = list(dict.fromkeys((r["env"], r["cameras"]) for r in d["rows"]))
    for env, cameras in settings:
        rows = [r for r in d["rows"] if (r["env"], r["cameras"]) == (env, cameras)]
        lines.append(
            f"| `{env}` | {cameras.replace('+', ', ')} "
            f"| {_span([r['steps_per_s'] for r in rows])} "
            f"| {_span([r['baseline_steps_per_s'] for r in rows])} "
            f"| {_span([r['x_baseline'] for r in rows], '{:.2f}')}x |"
        )
    return lines


@table("render-profile")
def render_profile(results: Path) -> list[str]:
    """One frame's cost, part by part, per camera (`benchmarks/render_profile.py`)."""
    d = _load(results / "render_profile.json")
    lines = [
        "| looks | camera | size, samples | scene update | render passes | read-back "
        "| whole frame | of which reflection | shadows | skybox |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in d["rows"]:
        full = r["update_ms"] + r["render_ms"]
        parts = [
            max(full - r[k], 0.0) for k in ("no_reflection_ms", "no_shadow_ms", "no_skybox_ms")
        ]
        lines.append(
            f"| {r['case']} | {r['camera']} | {r['height']}x{r['width']}, "
            f"{r['multisamples']} | {r['update_ms']:.3f} | {r['draw_ms']:.2f} "
            f"| {r['readback_ms']:.3f} | {r['frame_ms']:.2f} | "
            + " | ".join(f"{p:.2f}" for p in parts)
            + " |"
        )
    return lines


@table("parallel-eval")
def parallel_eval(results: Path) -> list[str]:
    """``hier_agents.run --workers N`` against one worker (`benchmarks/parallel_eval.py`)."""
    d = _load(results / "parallel_eval.json")
    lines = [
        f"| workers ({d['cpus']} CPUs) | episodes | wall s | episodes/s | speed-up "
        f"| solved | rows equal to 1 worker's |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in d["rows"]:
        lines.append(
            f"| {r['workers']} | {r['episodes']} | {r['wall_s']:.0f} "
            f"| {r['episodes_per_s']:.3f} | {r['speedup']:.2f}x "
            f"| {100 * r['success_rate']:.1f}% "
            f"| {'yes' if r['rows_identical_to_first'] else 'no'} |"
        )
    return lines


@table("original-env")
def original_env(results: Path) -> list[str]:
    """Our default modular agent on the original MuJoBan (`benchmarks/original_env.py`)."""
    d = _load(results / "original_env.json")
    lines = [
        "| environment | levels | pegs | agent (observation-only) | solved [95% CI] "
        "| mean steps (solved) | its estimates right |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for run in d["runs"]:
        steps = run["mean_steps_solved"]
        lines.append(
            f"| the original (`physics_planning_games`) | first {run['episodes']} of "
            f"`{d['levels_file']}` | {'yes' if run['pegs'] else 'no'} | {d['agent']} "
            f"| {_ci(run['success_rate'], run['interval'])} "
            f"| {'-' if steps is None else f'{steps:.0f}'} "
            f"| {100 * run['estimate_whole_grid_accuracy']:.2f}% of "
            f"{run['estimates']:,} steps |"
        )
    return lines


@table("original-boards")
def original_boards(results: Path) -> list[str]:
    """Our default camera agent on the original MuJoXO and MuJoGo
    (`benchmarks/original_boards.py`): ``original_boards.json``'s runs, then
    ``original_go_shadows.json``'s and ``original_xo_shadows.json``'s (each
    game under shadows measured again later), each with its commit."""
    d = _load(results / "original_boards.json")
    again = [_load(results / f"original_{game}_shadows.json") for game in ("go", "xo")]
    lines = [
        "| the original | its looks | games | agent (observation-only) | won / drawn / lost "
        "| not lost [95% CI] | its estimates right | mean steps |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    runs = [
        (run, f", at `{data['provenance']['commit'][:7]}`")
        for data in (d, *again)
        for run in data["runs"]
    ]
    for run, when in runs:
        s = run["summary"]
        other = s["games"] - s["win"] - s["draw"] - s["loss"]
        looks = ("as it is (shadows)" if run["shadows"] else "shadows off") + when
        lines.append(
            f"| `{run['original_task']}` | {looks} | {s['games']} | camera estimator, "
            f"{'minimax' if run['game'] == 'xo' else 'gnugo'}, arm-touch "
            f"| {s['win']} / {s['draw']} / {s['loss']}"
            f"{f' (+{other} unfinished)' if other else ''} "
            f"| {_ci(s['not_lost_rate'], s['not_lost_interval'])} "
            f"| {100 * s['estimate_board_accuracy']:.1f}% | {s['mean_steps']:.0f} |"
        )
    return lines


@table("estimator-accuracy")
def estimator_accuracy(results: Path) -> list[str]:
    """`benchmarks/estimator_accuracy.py`: whole-grid accuracy and errors per estimator."""
    d = _load(results / "estimator_accuracy.json")
    lines = [
        "| estimator | frames | whole grid right | without frames just after a teleport "
        "| walls / targets / boxes / player "
        "| worst wall/floor appearance | walker error median / p95 (cells) "
        "| box error median / p95 (cells) | ms per estimate |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in d["rows"]:
        looks = r.get("by_appearance") or {}
        worst = "-"
        if looks:
            name, w = min(looks.items(), key=lambda kv: (kv[1]["whole_grid_accuracy"], kv[0]))
            worst = (
                f"all {len(looks)} seen at 100%"
                if w["whole_grid_accuracy"] == 1.0
                else f"{name}: {100 * w['whole_grid_accuracy']:.1f}% of {w['frames']} "
                f"({len(looks)} seen)"
            )
        label = r["estimator"] + (" (**privileged**)" if r["privileged"] else "")
        parts = " / ".join(
            f"{100 * r[k + '_accuracy']:.1f}%" for k in ("walls", "targets", "boxes", "player")
        )
        clean = r["frames"] - r["teleport_frames"]
        lines.append(
            f"| {label} | {r['frames']} | {100 * r['whole_grid_accuracy']:.1f}% "
            f"| {100 * r['whole_grid_accuracy_without_teleports']:.1f}% of {clean} "
            f"| {parts} | {worst} | {r['walker_error_median_cells']:.4f} / "
            f"{r['walker_error_p95_cells']:.4f} | {r['box_error_median_cells']:.4f} / "
            f"{r['box_error_p95_cells']:.4f} | {r['ms_per_estimate']:.1f} |"
        )
    return lines


# -- README markers ---------------------------------------------------------------

_BLOCK = re.compile(
    r"(<!-- table:(?P<name>[\w.-]+) -->\n)(?P<body>.*?)(<!-- /table:(?P=name) -->)", re.DOTALL
)
_OPEN = re.compile(r"<!-- table:([\w.-]+) -->")


def generate(results: Path, names=None) -> dict[str, str]:
    """Every registered table's Markdown (or only those in ``names``), by name."""
    return {
        name: "\n".join(func(results)) + "\n"
        for name, func in TABLES.items()
        if names is None or name in names
    }


def check(readme_text: str, tables: dict[str, str]) -> list[str]:
    """Problems: tables that differ from the README, missing or unknown markers."""
    found = {m.group("name"): m.group("body") for m in _BLOCK.finditer(readme_text)}
    problems = []
    for name in _OPEN.findall(readme_text):
        if name not in found:
            problems.append(f"table {name!r}: no closing <!-- /table:{name} --> marker")
        elif name not in tables:
            problems.append(
                f"table {name!r}: no generator registered in benchmarks/readme_tables.py"
            )
    for name, text in tables.items():
        if name not in found:
            problems.append(f"table {name!r}: no <!-- table:{name} --> markers in the README")
        elif found[name] != text:
            problems.append(
                f"table {name!r}: the README differs from the results JSON "
                f"(run `python benchmarks/readme_tables.py --write`)"
            )
    return problems


def check_files(texts: dict[str, str], tables: dict[str, str]) -> list[str]:
    """Problems across files (``texts``: a label, e.g. "the README" or a docs path, ->
    its text): per file, tables that differ from the JSON and markers without a closing
    marker or a generator; then every registered table that no file holds."""
    problems = []
    for label, text in texts.items():
        found = {m.group("name"): m.group("body") for m in _BLOCK.finditer(text)}
        for name in _OPEN.findall(text):
            if name not in found:
                problems.append(
                    f"{label}: table {name!r}: no closing <!-- /table:{name} --> marker"
                )
            elif name not in TABLES and name not in tables:
                problems.append(
                    f"{label}: table {name!r}: no generator registered in "
                    f"benchmarks/readme_tables.py"
                )
        for name, body in found.items():
            if name in tables and body != tables[name]:
                problems.append(
                    f"table {name!r}: {label} differs from the results JSON "
                    f"(run `python benchmarks/readme_tables.py --write`)"
                )
    held = {m.group("name") for text in texts.values() for m in _BLOCK.finditer(text)}
    for name in tables:
        if name not in held:
            problems.append(
                f"table {name!r}: no <!-- table:{name} --> markers in {' or '.join(texts)}"
            )
    return problems


def docs_pages(docs: Path) -> list[Path]:
    """Every Markdown page under ``docs`` (recursively), in path order; none if no folder."""
    return sorted(docs.rglob("*.md")) if docs.is_dir() else []


def _label(path: Path, readme: Path) -> str:
    if path == readme:
        return "the README"
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def write(readme_text: str, tables: dict[str, str]) -> str:
    def replace(match):
        name = match.group("name")
        if name not in tables:
            return match.group(0)
        return match.group(1) + tables[name] + match.group(4)

    return _BLOCK.sub(replace, readme_text)


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument(
        "--check",
        action="store_true",
        help="exit 1 when a table of the README or a docs page disagrees with the JSON",
    )
    mode.add_argument(
        "--write", action="store_true", help="rewrite the tables of the README and the docs pages"
    )
    parser.add_argument("--readme", type=cli.existing_file, default=ROOT / "README.md")
    parser.add_argument(
        "--docs",
        type=Path,
        default=ROOT / "docs",
        help="the folder whose Markdown pages (recursively) also hold tables",
    )
    parser.add_argument(
        "--results",
        type=Path,
        default=ROOT / "results",
        help="the folder of committed results JSON",
    )
    parser.add_argument(
        "--table",
        action="append",
        metavar="NAME",
        help=f"only this table, of {', '.join(sorted(TABLES))} (repeatable; default: all)",
    )
    args = parser.parse_args(argv)
    for name in args.table or ():
        cli.choice("table", name, sorted(TABLES))
    if not args.results.is_dir():
        raise cli.UsageError(f"--results {str(args.results)!r} is not a folder")
    tables = generate(args.results, args.table)
    if not (args.check or args.write):
        for name, text in tables.items():
            print(f"<!-- table:{name} -->\n{text}<!-- /table:{name} -->\n")
        return 0
    files = [args.readme] + [
        p for p in docs_pages(args.docs) if p.resolve() != args.readme.resolve()
    ]
    texts = {path: path.read_text() for path in files}
    labels = {_label(path, args.readme): text for path, text in texts.items()}
    if args.write:
        written = 0
        for path, text in texts.items():
            new = write(text, tables)
            if new != text:
                path.write_text(new)
                written += 1
        print(f"wrote {len(tables)} table(s) into {len(files)} file(s) ({written} changed)")
        held = {m.group("name") for text in texts.values() for m in _BLOCK.finditer(text)}
        missing = [name for name in tables if name not in held]
        for name in missing:
            print(
                f"table {name!r} has no markers in {args.readme} or {args.docs}; add "
                f"<!-- table:{name} --> and <!-- /table:{name} --> around it",
                file=sys.stderr,
            )
        return 1 if missing else 0
    problems = check_files(labels, tables)
    for problem in problems:
        print(problem, file=sys.stderr)
    if not problems:
        print(f"{len(tables)} table(s) agree with {args.results} in {len(files)} file(s)")
    return 1 if problems else 0


def main(argv=None) -> int:
    """Prints, checks (exit 1 on a difference) or writes the tables of the README and the
    docs pages; bad input: one line on stderr, exit status 2."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
