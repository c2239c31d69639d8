"""Where a result came from: command, commit, date and machine.

Every result JSON the library writes (``hier_agents.run --json``, the
benchmarks) carries this record under ``"provenance"``, so that a reader can
rerun the command on the same commit and compare machines.
"""

from __future__ import annotations

import datetime
import os
import platform
import shlex
import subprocess
import sys
from pathlib import Path

_ROOT = Path(__file__).resolve().parents[1]


def _git(*args: str, root: Path = _ROOT) -> str | None:
    try:
        out = subprocess.run(
            ["git", *args], cwd=root, capture_output=True, text=True, timeout=10, check=True
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


def cpu_model() -> str:
    """This machine's CPU model name (``/proc/cpuinfo``'s first ``model name``,
    else what `platform` knows): records made on another kind of CPU may
    differ in floating point's last bits."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory_gib() -> float | None:
    try:
        return round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30, 1)
    except (ValueError, OSError, AttributeError):
        return None


def _commit(root: Path = _ROOT) -> str | None:
    """HEAD of the checkout at ``root``, ``+dirty`` if code (not results) changed."""
    commit = _git("rev-parse", "HEAD", root=root)
    if commit is not None and _git(
        "status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)results", root=root
    ):
        commit += "+dirty"
    return commit


#: The checkout's state when this process imported the library: the code it
#: runs. A result written later records this, not the checkout's state then
#: (which may have moved on while a long benchmark ran).
_COMMIT_AT_START = _commit()


def provenance(command: str | None = None) -> dict:
    """The record of this process: ``command``, ``commit``, ``date``, ``machine``.

    Args:
      command: the command line to record; defaults to ``python`` followed by
        this process's arguments (``python -m pkg.mod`` for modules run with -m).

    ``commit`` is the checkout's HEAD when this process imported the library,
    with ``+dirty`` appended when tracked files other than ``results/``
    differed from it then (a benchmark run that has just rewritten one result
    file still measures the committed code), or None outside a git checkout.
    """
    if command is None:
        argv = list(sys.argv)
        main = sys.modules.get("__main__")
        spec = getattr(main, "__spec__", None)
        if spec is not None and spec.name and not spec.name.startswith("pytest"):
            argv[0:1] = ["-m", spec.name.removesuffix(".__main__")]
        elif argv and Path(argv[0]).is_absolute():
            try:
                argv[0] = str(Path(argv[0]).resolve().relative_to(_ROOT))
            except ValueError:
                pass
        command = "python " + " ".join(shlex.quote(a) for a in argv)
    commit = _COMMIT_AT_START
    import mujoco  # the simulator version matters for every physics number

    return {
        "command": command,
        "commit": commit,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "machine": {
            "cpu": cpu_model(),
            "cores": os.cpu_count(),
            "memory_gib": _memory_gib(),
            "python": platform.python_version(),
            "mujoco": mujoco.__version__,
        },
    }
