"""Helpers shared by the benchmark scripts (imported as ``_common``: each
script's own folder is on ``sys.path`` when it runs)."""

from __future__ import annotations

import json
from pathlib import Path


def write_json(path: Path, data, indent: int = 2) -> None:
    """Writes ``data`` to ``path`` (creating its folder) and says so."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=indent) + "\n")
    print(f"wrote {path}")
