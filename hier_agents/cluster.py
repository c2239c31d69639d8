"""Ray, the one way this library uses it: connecting and making remote
functions and actors that can import the library on every node.

`connect(address)` joins a cluster (``"auto"``: the one ``ray start`` made
on this machine; an ``IP:PORT``) or, with ``None`` or ``"local"``, starts a
local instance with ``num_cpus``; an already connected process stays
connected. An address with nothing behind it is refused in one line within
`PROBE_S` seconds (``ray.init`` alone waits for it without end, printing a
warning every few seconds). `remote`
wraps a function or class as a Ray task or actor whose worker processes get
this checkout on ``PYTHONPATH`` and the caller's ``MUJOCO_GL`` (so a node
started with ``ray start`` anywhere imports the same code; on a multi-machine
cluster the library must be at the same path, or installed, on every node).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TypedDict

from physics_planning.cli import UsageError

ROOT = Path(__file__).resolve().parents[1]


#: Seconds `connect` waits for a cluster's address to accept a connection.
PROBE_S = 5.0


class _RuntimeEnv(TypedDict):
    env_vars: dict[str, str]


class _InitOptions(TypedDict):
    """The ``ray.init`` arguments `connect` passes on every path."""

    include_dashboard: bool
    log_to_driver: bool
    configure_logging: bool
    runtime_env: _RuntimeEnv


def connect(
    address: str | None = None, *, num_cpus: float | None = None, log_to_driver: bool = False
):
    """Connects this process to Ray (once); returns the ``ray`` module.

    Raises:
      UsageError: nothing answers at ``address`` within `PROBE_S` seconds, or
        ``auto`` finds no cluster started on this machine (one line, saying
        how to start one).
    """
    import ray

    if not ray.is_initialized():
        kwargs: _InitOptions = {
            "include_dashboard": False,
            "log_to_driver": log_to_driver,
            "configure_logging": False,
            "runtime_env": {"env_vars": worker_env()},
        }
        if address not in (None, "local"):
            probe(address)
            try:
                ray.init(address=address, **kwargs)
            except ConnectionError as exc:
                raise UsageError(
                    f"no Ray cluster at {address} ({str(exc).strip().splitlines()[0]})"
                ) from None
        else:
            # Ray annotates num_cpus as int but takes any whole-number float (Pool's
            # size * cpus); it raises ValueError for a fractional one.
            ray.init(num_cpus=num_cpus or None, **kwargs)  # type: ignore[arg-type]
    return ray


def probe(address: str, timeout: float = PROBE_S) -> str:
    """The ``HOST:PORT`` a Ray address names (``auto``: the cluster ``ray
    start`` made on this machine), once a TCP connection to it succeeded.

    Raises:
      UsageError: a malformed address, no cluster for ``auto``, or no answer
        within ``timeout`` seconds.
    """
    import socket

    target = address.split("://", 1)[-1]
    if address == "auto":
        try:
            from ray._private.services import canonicalize_bootstrap_address

            target = canonicalize_bootstrap_address("auto") or ""
        except ConnectionError:
            raise UsageError(
                "--ray-address auto: no Ray cluster was started on this machine "
                "(start one with `ray start --head`)"
            ) from None
        except Exception:  # noqa: BLE001 - Ray's internals moved: let ray.init judge
            return address
    host, _, port = target.rpartition(":")
    if not host or not port.isdigit():
        raise UsageError(f"--ray-address {address!r}: expected auto or HOST:PORT")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        raise UsageError(
            f"no Ray cluster answers at {address} ({exc.strerror or exc}); "
            "start one with `ray start --head --port PORT` or give its "
            "address"
        ) from None
    return target


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
