"""Helpers shared by the benchmark scripts (imported as ``_common``: each
script's own folder is on ``sys.path`` when it runs).

Every benchmark follows the command-line conventions of `physics_planning.cli`:

    PROG = prog(__file__)                    # "python benchmarks/NAME.py"
    def _main(argv):
        parser = make_parser(__file__, __doc__)
        ...                                  # raise UsageError for bad input
    def main(argv=None) -> int:
        return cli.run_main(PROG, _main, argv)

so its usage line names the script as users start it, its help shows the
defaults and the docstring's usage block, and bad input ends in one line on
stderr and exit status 2 before anything is measured.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from envs import cli as env_cli  # noqa: E402
from physics_planning import cli  # noqa: E402
from hier_agents.provenance import provenance  # noqa: E402

__all__ = [
    "cli",
    "env_cli",
    "make_parser",
    "prog",
    "write_json",
    "run_in_tree",
    "baseline_worktree",
    "remove_worktree",
    "described_camera",
]


def prog(file: str) -> str:
    """How users start the benchmark at ``file``: ``python benchmarks/NAME.py``."""
    return f"python benchmarks/{Path(file).name}"


def make_parser(file: str, doc: str) -> cli.Parser:
    """The benchmark's `physics_planning.cli.Parser`: usage ``python benchmarks/NAME.py``,
    the docstring's first paragraph as description and the rest as epilog."""
    first, _, rest = doc.strip().partition("\n\n")
    return cli.Parser(prog(file), description=first, epilog=rest or None)


def write_json(path: Path, data, indent: int = 2) -> None:
    """Writes ``data`` to ``path`` (creating its folder) with its provenance, and says so.

    A dict gets a ``"provenance"`` key (command, commit, date, machine: see
    `hier_agents.provenance`); a list of rows is written as
    ``{"provenance": ..., "rows": [...]}``. The file is replaced in one step
    (`physics_planning.cli.write_json`). Check the path up front with
    `physics_planning.cli.output_file`.
    """
    record = provenance()
    data = (
        {**data, "provenance": record}
        if isinstance(data, dict)
        else {"provenance": record, "rows": list(data)}
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    cli.write_json(path, data, indent=indent)
    print(f"wrote {path}")


def run_in_tree(tree: Path, command: list[str], timeout: float) -> None:
    """Runs ``command`` with ``tree`` as working folder and first on
    ``PYTHONPATH`` (a checkout of this project, e.g. `baseline_worktree`).

    Raises:
      RuntimeError: the command failed (its last stderr lines quoted).
    """
    import os
    import subprocess

    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(p for p in (str(tree), os.environ.get("PYTHONPATH")) if p),
    }
    done = subprocess.run(
        command, cwd=tree, env=env, capture_output=True, text=True, timeout=timeout
    )
    if done.returncode != 0:
        tail = "\n".join(done.stderr.strip().splitlines()[-15:])
        raise RuntimeError(
            f"{' '.join(command)} failed in {tree} (exit {done.returncode}):\n{tail}"
        )


def baseline_worktree(ref: str, folder: Path) -> Path:
    """A detached git worktree of this repository at commit ``ref`` in
    ``folder``/baseline (remove it with ``git worktree remove --force``).

    Raises:
      UsageError: ``ref`` is not a commit of this repository.
    """
    import subprocess

    root = Path(__file__).resolve().parents[1]
    path = Path(folder) / "baseline"
    done = subprocess.run(
        ["git", "-C", str(root), "worktree", "add", "--detach", str(path), ref],
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise cli.UsageError(f"--baseline {ref}: {done.stderr.strip() or 'git worktree failed'}")
    return path


def remove_worktree(path: Path) -> None:
    """Removes a worktree made by `baseline_worktree`."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    subprocess.run(
        ["git", "-C", str(root), "worktree", "remove", "--force", str(path)], capture_output=True
    )


def described_camera(physics, element, name: str, shape):
    """The `envs.description.CameraDescription` of a camera of a compiled
    model other than ours (the original environments'): its world pose and
    field of view as ``physics`` holds them after a forward pass.

    Args:
      physics: the environment's `dm_control.mjcf.Physics`.
      element: the camera's MJCF element.
      name: the observation key of its frames.
      shape: (height, width) of the frames read, or None.
    Returns the description, with the model's offscreen multisamples."""
    import numpy as np

    from envs.description import CameraDescription

    cam = physics.bind(element)
    xmat = np.asarray(cam.xmat).reshape(3, 3)
    return CameraDescription(
        name,
        tuple(float(v) for v in cam.xpos),
        tuple(float(v) for v in np.r_[xmat[:, 0], xmat[:, 1]]),
        float(cam.fovy),
        shape,
        multisamples=int(physics.model.vis.quality.offsamples),
    )
