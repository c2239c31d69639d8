"""Run notebooks from top to bottom and save them with their outputs.

    python notebooks/save_outputs.py notebooks/*.ipynb        # in place, full settings
    python notebooks/save_outputs.py NOTEBOOK --out OTHER.ipynb

The notebooks are committed with the outputs of a full-size run (no
``NOTEBOOK_SMALL``); `tests/test_notebook.py` runs them small and checks that
every cell still shows the kinds of output saved here. Run from the
repository's root with ``PYTHONPATH=. MUJOCO_GL=egl``.

Saved streams are made readable: consecutive pieces of one stream are
joined and the text a carriage return overwrote (progress bars) is dropped,
so a cell keeps what a reader saw last, not every redraw.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import nbformat
from nbclient import NotebookClient


def _last_redraw(text: str) -> str:
    """Each line as a terminal shows it after its carriage returns."""
    lines = []
    for line in text.split("\n"):
        parts = [part for part in line.split("\r") if part]
        lines.append(parts[-1] if parts else "")
    return "\n".join(lines)


def tidy_streams(notebook) -> None:
    """Joins consecutive outputs of the same stream and drops overwritten text."""
    for cell in notebook.cells:
        if cell.cell_type != "code":
            continue
        outputs = []
        for out in cell.outputs:
            if (
                out.output_type == "stream"
                and outputs
                and outputs[-1].output_type == "stream"
                and outputs[-1].name == out.name
            ):
                outputs[-1].text += out.text
            else:
                outputs.append(out)
        for out in outputs:
            if out.output_type == "stream":
                out.text = _last_redraw(out.text)
        cell.outputs = outputs


def save_outputs(path: Path, out: Path | None = None, timeout: int = 3600) -> float:
    """Executes ``path`` (working directory: its folder) and writes it with its
    outputs to ``out`` (default: in place). Returns the seconds it took."""
    notebook = nbformat.read(path, as_version=4)
    start = time.perf_counter()
    NotebookClient(
        notebook,
        timeout=timeout,
        kernel_name="python3",
        resources={"metadata": {"path": str(path.resolve().parent)}},
    ).execute()
    seconds = time.perf_counter() - start
    tidy_streams(notebook)
    nbformat.write(notebook, out or path)
    return seconds


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python notebooks/save_outputs.py", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("notebooks", nargs="+", type=Path)
    parser.add_argument("--out", type=Path, help="write here (one notebook only)")
    args = parser.parse_args(argv)
    if args.out and len(args.notebooks) > 1:
        parser.error("--out takes one notebook")
    if os.environ.get("NOTEBOOK_SMALL") == "1":
        print(
            "warning: NOTEBOOK_SMALL=1 is set; the saved outputs will be the small run's",
            file=sys.stderr,
        )
    for path in args.notebooks:
        seconds = save_outputs(path, args.out)
        target = args.out or path
        print(
            f"{path}: executed in {seconds:.0f} s, saved to {target} "
            f"({target.stat().st_size:,} bytes)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
