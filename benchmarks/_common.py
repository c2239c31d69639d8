"""Helpers shared by the benchmark scripts (imported as ``_common``: each
script's own folder is on ``sys.path`` when it runs)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hier_agents.provenance import provenance  # noqa: E402


def write_json(path: Path, data, indent: int = 2) -> None:
    """Writes ``data`` to ``path`` (creating its folder) with its provenance, and says so.

    A dict gets a ``"provenance"`` key (command, commit, date, machine: see
    `hier_agents.provenance`); a list of rows is written as
    ``{"provenance": ..., "rows": [...]}``.
    """
    record = provenance()
    data = {**data, "provenance": record} if isinstance(data, dict) else {
        "provenance": record, "rows": list(data)}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=indent) + "\n")
    print(f"wrote {path}")
