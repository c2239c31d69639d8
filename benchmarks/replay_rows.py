"""Re-plays committed agent rows with their recorded settings and checks they are identical.

    python benchmarks/replay_rows.py [FILE ...] [--only GLOB] [--episodes 2]
        [--first-episode 0] [--json results/replay_rows.json]

For every ``hier_agents.run --json`` file given (default: every
``results/agent/*.json``), re-plays episodes ``FIRST`` .. ``FIRST + K - 1``
through `hier_agents.run.run` with exactly the settings the file records
(env, seed, agent, planner, skill, estimator, levels, the environment's
settings: ``deviations`` from the original's, or for a file written before
summaries recorded them ``env_options`` on the original's settings,
`envs.recorded_options`; a
checkpoint agent's sampling from its recorded condition) and compares each
re-played row with the committed row of the same ``episode`` index on every
key that decides the outcome: `OUTCOME_KEYS` (return, steps, solved or
outcome, failure_reason, subgoals, estimation failures, estimates) and any
other key both rows hold, except the timing keys (``wall_s``, ``profile_s``,
anything ending in ``_s``/``_ms`` or naming time). A key only one side
records (e.g. ``estimates``, added to rows later) is listed, not counted as a
difference; ``failure_reason`` and ``error`` are absent when there is none,
so absence is compared too.

Files whose settings cannot be replayed are skipped with the reason: no
per-episode rows, rows without an ``episode`` index, a setting the JSON does
not record, a levels file not in this repository (``levels`` may be relative
to the repository root), a checkpoint file not present, settings this code
refuses. (Older board-game files do not record ``levels``, which only
MuJoBan plays: they are replayed without.) Rows of files recorded at older commits (each file's
``provenance.commit`` is shown) may differ because the code did: a difference
is a finding about the committed row.

Prints a table (file, commit, episodes re-played, identical or the keys that
differ with both values, seconds) and writes ``--json``: ``{"episodes",
"first_episode", "identical", "replayed", "differing", "files": [{"file",
"commit", "settings", "episodes", "identical", "differences": [{"episode",
"key", "committed", "replayed"}], "one_sided_keys", "rows", "seconds"}],
"skipped": [{"file", "commit", "reason"}], "provenance"}``.

``--baseline REPORT`` (a JSON this script wrote, e.g. before a refactor)
also compares each re-played row with the row that report re-played for the
same file and episode (``baseline_identical``, ``baseline_differences``;
rows it did not re-play are listed in ``baseline_missing``): committed rows
from older code may differ, two replays of the same code must not. With
``--baseline`` the exit status is decided by that comparison.

    python benchmarks/replay_rows.py FILE ... --json results/replay_rows_after.json \
        --baseline results/replay_rows_before.json

Exit status: 0 when every re-played row is identical (to the committed row,
or with ``--baseline`` to the baseline's), 1 when any differs (or a replay
raised), 2 on bad input (one line on stderr).
"""

from __future__ import annotations

import fnmatch
import json
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import cli, make_parser, prog, write_json  # noqa: E402

import envs  # noqa: E402

PROG = prog(__file__)
ROOT = Path(__file__).resolve().parents[1]
DEFAULT_GLOB = "results/agent/*.json"

#: Row keys that decide an episode's outcome, compared whenever both rows hold them.
OUTCOME_KEYS = (
    "return",
    "steps",
    "solved",
    "outcome",
    "final_reward",
    "failure_reason",
    "error",
    "subgoals_issued",
    "subgoals_reached",
    "estimation_failures",
    "estimates",
    "wrong_estimates",
)
#: Keys whose absence means "none": a row without one differs from a row with one.
ABSENT_MEANS_NONE = ("failure_reason", "error")
#: Keys never compared: the index itself and timing.
IGNORED_KEYS = ("episode", "wall_s", "profile_s")


class Skip(Exception):
    """A committed file whose settings cannot be replayed (the message says why)."""


def _is_timing(key: str) -> bool:
    return key in IGNORED_KEYS or key.endswith(("_s", "_ms")) or "time" in key or "profile" in key


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b or (type(a) is type(b) and a == b)
    return a == b


def compare_rows(committed: dict, replayed: dict) -> tuple[list[dict], list[str]]:
    """The outcome keys on which two rows of the same episode differ.

    Returns ``(differences, one_sided)``: ``differences`` is a list of
    ``{"key", "committed", "replayed"}`` (plus ``"delta"`` for numbers),
    ``one_sided`` the non-timing keys only one row records (not differences,
    except ``failure_reason`` and ``error``, whose absence means none).
    Timing keys (``wall_s``, ``profile_s``, ...) are never compared.
    """
    differences, one_sided = [], []
    keys = list(OUTCOME_KEYS) + sorted((set(committed) | set(replayed)) - set(OUTCOME_KEYS))
    for key in keys:
        if _is_timing(key):
            continue
        here, there = key in committed, key in replayed
        if not here and not there:
            continue
        if here != there and key not in ABSENT_MEANS_NONE:
            one_sided.append(key)
            continue
        a, b = committed.get(key), replayed.get(key)
        if not _same(a, b):
            diff = {"key": key, "committed": a, "replayed": b}
            if (
                isinstance(a, (int, float))
                and isinstance(b, (int, float))
                and not isinstance(a, bool)
                and not isinstance(b, bool)
            ):
                diff["delta"] = b - a
            differences.append(diff)
    return differences, one_sided


def _rel(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def _checkpoint_present(spec: str | None, what: str) -> None:
    """Raises Skip when a ``NAME:PATH`` component names a file that is not here."""
    if not spec or ":" not in spec:
        return
    _, arg = spec.split(":", 1)
    if "/" in arg or arg.endswith((".pt", ".pth", ".ckpt")):
        path = Path(arg) if Path(arg).is_absolute() else ROOT / arg
        if not path.exists():
            raise Skip(f"{what} checkpoint {arg} is not present")


def _takes_levels(env: str) -> bool:
    """Whether ``env``'s family plays level files (MuJoBan); unknown names: True."""
    try:
        from hier_agents.modular.components import family
        from hier_agents.modular.families import adapter

        return bool(adapter(family(env)).level_files)
    except (ValueError, KeyError):
        return True


def settings(summary: dict) -> dict:
    """The `hier_agents.run.run` keyword arguments a summary records.

    Raises:
      Skip: a setting is missing, or names a file that is not here.
    """

    def need(key):
        if key not in summary:
            raise Skip(f"does not record {key!r}")
        return summary[key]

    env, seed, agent = need("env"), need("seed"), need("agent")
    if not isinstance(env, str) or not isinstance(seed, int) or not isinstance(agent, str):
        raise Skip("env, seed or agent is not recorded as a name / integer")
    env_options = need("env_options")
    # The settings it played: its deviations from the original's, or (a file
    # from before summaries recorded them) its env_options on the original's.
    env_options = envs.recorded_options(env, summary.get("deviations", env_options or {}))
    if "levels" in summary:
        levels = summary["levels"]
    elif _takes_levels(env):
        raise Skip("does not record 'levels'")
    else:  # older files of families without level files: there was nothing to record
        levels = None
    out = dict(
        env_name=env,
        seed=seed,
        agent=agent,
        planner=None,
        skill=None,
        estimator=None,
        levels=None,
        env_options=dict(env_options or {}),
    )
    if agent == "modular":
        for key in ("planner", "skill", "estimator"):
            value = need(key)
            if not isinstance(value, str):
                raise Skip(f"does not record {key!r} as a name")
            out[key] = value
        _checkpoint_present(out["planner"], "planner")
        _checkpoint_present(out["skill"], "skill")
    elif agent.startswith("checkpoint:"):
        path = agent[len("checkpoint:") :]
        if not (Path(path) if Path(path).is_absolute() else ROOT / path).exists():
            raise Skip(f"agent checkpoint {path} is not present")
        condition = need("condition")
        out["stochastic"] = str(condition).endswith("(sampled)")
    elif not agent.startswith("random"):
        raise Skip(f"unknown agent kind {agent!r}")
    if levels is not None:
        path = Path(levels)
        path = path if path.is_absolute() else ROOT / path
        try:
            path.resolve().relative_to(ROOT)
        except ValueError:
            raise Skip(f"levels file {levels} is not in the repository") from None
        if not path.is_file():
            raise Skip(f"levels file {levels} is not in the repository")
        out["levels"] = str(path)
    return out


def _committed_rows(summary: dict) -> dict[int, dict]:
    rows = summary.get("rows")
    if not isinstance(rows, list) or not rows:
        raise Skip("no per-episode rows")
    by_index = {}
    for row in rows:
        if not isinstance(row, dict) or not isinstance(row.get("episode"), int):
            raise Skip("rows without an episode index")
        by_index[row["episode"]] = row
    return by_index


def replay_file(path: Path, episodes: int, first: int) -> dict:
    """Re-plays and compares one file; returns its report entry.

    Raises:
      Skip: its settings cannot be replayed.
    """
    from hier_agents.run import run

    summary = json.loads(path.read_text())
    if not isinstance(summary, dict) or "env" not in summary:
        raise Skip("not a hier_agents.run --json summary (no 'env')")
    committed = _committed_rows(summary)
    kwargs = settings(summary)
    wanted = [e for e in range(first, first + episodes) if e in committed]
    if not wanted:
        raise Skip(f"no committed row for episodes {first}..{first + episodes - 1}")
    count = wanted[-1] - wanted[0] + 1
    start = time.perf_counter()
    try:
        result = run(
            kwargs.pop("env_name"),
            count,
            kwargs.pop("seed"),
            first_episode=wanted[0],
            progress=False,
            **kwargs,
        )
    except (ValueError, FileNotFoundError) as exc:  # refused before anything was played
        raise Skip(f"this code refuses the settings ({type(exc).__name__}: {exc})") from None
    seconds = time.perf_counter() - start
    replayed = {row["episode"]: row for row in result.get("rows", [])}
    differences, one_sided = [], set()
    for e in wanted:
        if e not in replayed:
            differences.append(
                {"episode": e, "key": "(row)", "committed": "present", "replayed": "missing"}
            )
            continue
        diffs, keys = compare_rows(committed[e], replayed[e])
        differences += [{"episode": e, **d} for d in diffs]
        one_sided.update(keys)
    return {
        "identical": not differences,
        "episodes": wanted,
        "differences": differences,
        "one_sided_keys": sorted(one_sided),
        "rows": [replayed[e] for e in wanted if e in replayed],
        "seconds": round(seconds, 2),
    }


def _commit_of(path: Path) -> str:
    try:
        record = json.loads(path.read_text()).get("provenance") or {}
    except (OSError, ValueError, AttributeError):
        return "?"
    return str(record.get("commit") or "?")


def _short(commit: str) -> str:
    return commit[:9] + ("+dirty" if commit.endswith("+dirty") else "") if commit != "?" else "?"


def _files(args) -> list[Path]:
    if args.files:
        files = []
        for name in args.files:
            path = Path(name)
            if not path.is_file():
                raise cli.UsageError(f"no such file: {name!r}")
            files.append(path)
    else:
        files = sorted(ROOT.glob(DEFAULT_GLOB))
    if args.only:
        files = [
            p
            for p in files
            if fnmatch.fnmatch(_rel(p), args.only)
            or fnmatch.fnmatch(p.name, args.only)
            or fnmatch.fnmatch(str(p), args.only)
        ]
    if not files:
        raise cli.UsageError(
            "no result files to replay" + (f" match --only {args.only}" if args.only else "")
        )
    for path in files:
        try:
            json.loads(path.read_text())
        except ValueError as exc:
            raise cli.UsageError(f"{path} is not JSON ({exc})") from None
    return files


def _value(v) -> str:
    return json.dumps(v) if not isinstance(v, str) else repr(v)


def _print_table(entries, skipped, with_baseline: bool = False) -> None:
    print(
        "| file | commit | episodes | vs committed row | "
        + ("vs baseline | " if with_baseline else "")
        + "s |"
    )
    print("| --- | --- | --- | --- | " + ("--- | " if with_baseline else "") + "--- |")
    for e in entries:
        if e["identical"]:
            result = "identical"
        elif "error" in e:
            result = f"replay raised {e['error']}"
        else:
            keys = sorted({d["key"] for d in e["differences"]})
            result = "differs: " + ", ".join(keys)
        eps = e["episodes"]
        span = f"{eps[0]}-{eps[-1]}" if len(eps) > 1 else (str(eps[0]) if eps else "-")
        against = ""
        if with_baseline:
            against = (
                "identical"
                if e.get("baseline_identical")
                else "differs: "
                + ", ".join(
                    sorted({d["key"] for d in e.get("baseline_differences", [])})
                    | (
                        {"(not in baseline)"}
                        if e.get("baseline_missing") or not e["rows"]
                        else set()
                    )
                )
            ) + " | "
        print(
            f"| {e['file']} | {_short(e['commit'])} | {span} | {result} | {against}{e['seconds']} |"
        )
    for e in entries:
        for d in e["differences"]:
            delta = f" ({d['delta']:+g})" if "delta" in d else ""
            print(
                f"  {e['file']} episode {d['episode']}: {d['key']} committed "
                f"{_value(d['committed'])}, replayed {_value(d['replayed'])}{delta}"
            )
        for d in e.get("baseline_differences", []):
            delta = f" ({d['delta']:+g})" if "delta" in d else ""
            print(
                f"  {e['file']} episode {d['episode']}: {d['key']} baseline "
                f"{_value(d['committed'])}, replayed {_value(d['replayed'])}{delta}"
            )
    for s in skipped:
        print(f"skipped {s['file']} ({_short(s['commit'])}): {s['reason']}")


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "files",
        nargs="*",
        metavar="FILE",
        help=f"hier_agents.run --json files (default: {DEFAULT_GLOB})",
    )
    parser.add_argument(
        "--only",
        metavar="GLOB",
        default=None,
        help="replay only the files whose path (relative to the repository) or name matches",
    )
    parser.add_argument(
        "--episodes", type=cli.positive_int, default=2, help="episodes re-played per file (K)"
    )
    parser.add_argument(
        "--first-episode",
        type=cli.non_negative_int,
        default=0,
        help="index of the first episode re-played",
    )
    parser.add_argument(
        "--json", default="results/replay_rows.json", help="where to write the report"
    )
    parser.add_argument(
        "--baseline",
        metavar="REPORT",
        type=cli.existing_file,
        default=None,
        help="a report of this script whose re-played rows the new ones must equal",
    )
    args = parser.parse_args(argv)
    out = cli.output_file(args.json, "--json")
    baseline = None if args.baseline is None else _baseline_rows(args.baseline)
    files = _files(args)
    entries, skipped = [], []
    for path in files:
        commit = _commit_of(path)
        name = _rel(path)
        print(f"{name}: ", end="", flush=True)
        try:
            entry = replay_file(path, args.episodes, args.first_episode)
        except Skip as exc:
            print(f"skipped ({exc})", flush=True)
            skipped.append({"file": name, "commit": commit, "reason": str(exc)})
            continue
        except Exception as exc:  # noqa: BLE001 - a replay that raised is a finding
            print(f"raised {type(exc).__name__}: {exc}", flush=True)
            entries.append(
                {
                    "file": name,
                    "commit": commit,
                    "identical": False,
                    "episodes": [],
                    "differences": [],
                    "one_sided_keys": [],
                    "rows": [],
                    "seconds": 0,
                    "error": f"{type(exc).__name__}: {exc}",
                }
            )
            continue
        summary = json.loads(path.read_text())
        entry = {
            "file": name,
            "commit": commit,
            "settings": {
                k: summary.get(k)
                for k in (
                    "env",
                    "seed",
                    "agent",
                    "planner",
                    "skill",
                    "estimator",
                    "levels",
                    "env_options",
                )
            },
            **entry,
        }
        if baseline is not None:
            _against_baseline(entry, baseline.get(name, {}))
        entries.append(entry)
        print(
            ("identical" if entry["identical"] else "DIFFERS")
            + f" ({entry['seconds']} s)"
            + (
                ""
                if baseline is None
                else "; baseline: " + ("identical" if entry["baseline_identical"] else "DIFFERS")
            ),
            flush=True,
        )
    _print_table(entries, skipped, baseline is not None)
    differing = sum(not e["identical"] for e in entries)
    report = {
        "episodes": args.episodes,
        "first_episode": args.first_episode,
        "identical": differing == 0,
        "replayed": len(entries),
        "differing": differing,
        "files": entries,
        "skipped": skipped,
    }
    if baseline is not None:
        report["baseline"] = str(args.baseline)
        report["baseline_differing"] = sum(not e.get("baseline_identical", False) for e in entries)
        write_json(out, report)
        return 1 if report["baseline_differing"] else 0
    write_json(out, report)
    return 1 if differing else 0


def _baseline_rows(path: Path) -> dict[str, dict[int, dict]]:
    """{file: {episode: row}} of a report this script wrote."""
    try:
        report = json.loads(Path(path).read_text())
        return {e["file"]: {row["episode"]: row for row in e["rows"]} for e in report["files"]}
    except (ValueError, KeyError, TypeError) as exc:
        raise cli.UsageError(
            f"--baseline {str(path)!r} is not a report of {PROG} ({type(exc).__name__}: {exc})"
        ) from None


def _against_baseline(entry: dict, rows: dict[int, dict]) -> None:
    """Adds the comparison with the baseline's rows of the same file to ``entry``."""
    differences, missing = [], []
    for row in entry["rows"]:
        if row["episode"] not in rows:
            missing.append(row["episode"])
            continue
        diffs, _ = compare_rows(rows[row["episode"]], row)
        differences += [{"episode": row["episode"], **d} for d in diffs]
    entry["baseline_differences"] = differences
    entry["baseline_missing"] = missing
    entry["baseline_identical"] = bool(entry["rows"]) and not differences and not missing


def main(argv=None) -> int:
    """Replays, prints the table, writes ``--json``; exit 0 identical, 1 differs, 2 bad input."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
