"""Ray, the one way this library uses it: connecting and making remote
functions and actors that can import the library on every node.

`connect(address)` joins a cluster (``"auto"``: the one ``ray start`` made
on this machine; an ``IP:PORT``) or, with ``None``, starts a local instance
with ``num_cpus``; an already connected process stays connected. `remote`
wraps a function or class as a Ray task or actor whose worker processes get
this checkout on ``PYTHONPATH`` and the caller's ``MUJOCO_GL`` (so a node
started with ``ray start`` anywhere imports the same code; on a multi-machine
cluster the library must be at the same path, or installed, on every node).
"""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def connect(address: str | None = None, *, num_cpus: int | None = None,
            log_to_driver: bool = False):
    """Connects this process to Ray (once); returns the ``ray`` module.

    Raises:
      ConnectionError (Ray's): no cluster at ``address``.
    """
    import ray

    if not ray.is_initialized():
        kwargs = {"include_dashboard": False, "log_to_driver": log_to_driver,
                  "configure_logging": False, "runtime_env": {"env_vars": worker_env()}}
        if address not in (None, "local"):
            ray.init(address=address, **kwargs)
        else:
            ray.init(**({"num_cpus": num_cpus} if num_cpus else {}), **kwargs)
    return ray


def worker_env() -> dict[str, str]:
    """Environment variables of Ray workers: this checkout first on
    ``PYTHONPATH``, and ``MUJOCO_GL`` (default ``egl``)."""
    path = [str(ROOT)] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])
    return {"MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "PYTHONPATH": os.pathsep.join(path)}


def remote(target, **options):
    """``ray.remote(**options)(target)`` with `worker_env` in its runtime
    environment; call `connect` first."""
    import ray

    return ray.remote(runtime_env={"env_vars": worker_env()}, **options)(target)
