"""The environment variables of a child process a test starts: this
checkout (and ``extra`` folders) first on ``PYTHONPATH``, headless rendering
(``MUJOCO_GL=egl`` unless set), plus ``variables``."""

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def child_env(*extra: Path, **variables: str) -> dict:
    """``os.environ`` with ``PYTHONPATH`` = ROOT, ``extra``, then the
    inherited path; ``MUJOCO_GL`` defaulting to ``egl``; ``variables`` set."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        filter(None, [str(ROOT), *map(str, extra), env.get("PYTHONPATH")])
    )
    env.setdefault("MUJOCO_GL", "egl")
    env.update(variables)
    return env
