"""Work on other processes, locally or on Ray, with one retry-on-death policy.

`Pool` keeps ``size`` stateful workers, each built once by ``factory(index)``
(picklable; run in the worker) and kept for every later call. ``submit(method,
*args, worker=None, label=...)`` queues ``worker.method(*args)`` on one worker
(the given index, else the one with the fewest calls under way; a worker runs
its calls in order, one at a time, and starts the next at once: two calls in
flight keep it busy while the caller works); ``next(timeout, should_stop)``
returns the first finished `Call` with its ``result``.

* local (``address`` None): spawned processes (no GL or torch state
  inherited) that ignore SIGINT (Ctrl-C reaches the whole process group: the
  caller decides how to stop, then `close`\\ s the pool) and die with their
  parent; results go back through a pipe from a sender thread, so a worker
  computes while the caller has not read yet.
* Ray (``address``: ``auto``, ``IP:PORT``, or ``local`` for an instance of
  this machine): Ray actors of ``cpus`` CPUs each (`hier_agents.cluster`);
  a pool larger than the cluster's CPUs is cut to fit (idle actors would wait
  for CPUs forever).

The one retry policy (`Deaths`): a worker whose process dies (a signal, an
abort in native code, the out-of-memory killer, a lost Ray node) is replaced
by a new one built by the same factory, and the calls it had under way run
again on it, with one line on stderr::

    hier_agents: a worker process died (killed by SIGKILL); running shard 3 of 12
    again in a new process (retry 1 of 3)

(one line on stderr; broken here to fit).

A call that dies more than `WORKER_RETRIES` times raises `WorkerDied`. A
call whose worker code raises is not retried: `next` raises `CallFailed`
with the worker's traceback (a factory that raises fails every call of that
worker so). Work that runs in its own child process per call (a comparison's
jobs, for isolation) reports a dead child through the same `Deaths`.
"""

from __future__ import annotations

import dataclasses
import os
import signal
import sys
import time
import traceback
from collections.abc import Hashable
from typing import Any, Callable

#: How many times a call runs again after the worker process running it died;
#: a call that dies more often raises `WorkerDied`.
WORKER_RETRIES = 3
_POLL_S = 0.5  # how often a waiting caller checks ``should_stop`` and its workers


class WorkerDied(RuntimeError):
    """A worker process died while running a call more than `WORKER_RETRIES`
    times."""


class CallFailed(RuntimeError):
    """A call raised in its worker: ``call`` (its `Call`) and ``details``
    (the worker's traceback, also in the message)."""

    def __init__(self, message: str, call=None, details: str = ""):
        super().__init__(message)
        self.call, self.details = call, details


def exit_status(code: int | None) -> str:
    """A process's exit code in words: ``"killed by SIGABRT"`` for -6."""
    if code is None:
        return "exit status unknown"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def death(exit_codes) -> str:
    """How a set of processes died, in words: the exit statuses other than 0
    and SIGTERM (what a pool sends to the workers left), or SIGTERM if that is
    all there is."""
    codes = [code for code in exit_codes if code not in (None, 0)]
    own = [code for code in codes if code != -signal.SIGTERM] or codes
    return ", ".join(map(exit_status, sorted(set(own)))) or "exit status unknown"


class Deaths:
    """The retry policy: counts each call's deaths, says each retry on stderr
    in one line, and raises `WorkerDied` past `WORKER_RETRIES`."""

    def __init__(self, retries: int = WORKER_RETRIES, stream=None):
        self.retries, self.stream = retries, stream
        self.counts: dict[Hashable, int] = {}  # deaths by call key

    def died(self, keys: list, labels: list[str], how: str, where: str = "process") -> None:
        """Notes that the calls ``keys`` (described by ``labels``) died with
        their worker (``how``: `exit_status` words); prints the retry line.

        Raises:
          WorkerDied: one of them died more than ``retries`` times.
        """
        for key in keys:
            self.counts[key] = self.counts.get(key, 0) + 1
        worst = max((self.counts[k] for k in keys), default=0)
        what = (
            ", ".join(
                label if labels.count(label) == 1 else f"{label} (x{labels.count(label)})"
                for label in dict.fromkeys(labels)
            )
            or "nothing under way"
        )
        if worst > self.retries:
            raise WorkerDied(
                f"a worker process died {worst} times running {what} ({how}); giving up"
            )
        print(
            f"hier_agents: a worker process died ({how}); running {what} again in a new "
            f"{where} (retry {worst} of {self.retries})",
            file=self.stream or sys.stderr,
            flush=True,
        )


@dataclasses.dataclass
class Call:
    """One submitted call: its worker index, method, arguments and label;
    ``result`` once `Pool.next` returned it."""

    id: int
    worker: int
    method: str
    args: tuple
    label: str
    result: Any = None


def die_with_parent() -> None:  # pragma: no cover - runs in child processes
    """Asks Linux to SIGKILL this process when its parent dies (no orphans)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def _build(factory, index):
    """(worker, None), or (None, traceback) if ``factory(index)`` raised."""
    try:
        return factory(index), None
    except Exception:  # noqa: BLE001 - reported with every call of this worker
        return None, traceback.format_exc()


def _run(worker, error, method, args):
    """(True, result) or (False, traceback) of ``worker.method(*args)``."""
    if error is not None:
        return False, error
    try:
        return True, getattr(worker, method)(*args)
    except Exception:  # noqa: BLE001 - the caller's to raise
        return False, traceback.format_exc()


def _close(worker) -> None:
    close = getattr(worker, "close", None)
    if close is not None:
        close()


def _serve(factory, index: int, conn) -> None:  # pragma: no cover - a worker process's body
    """A local worker: builds its object, answers ``(id, method, args)``
    messages in order until ``None`` or a closed pipe; a sender thread sends
    ``(id, ok, result)`` while the next call runs."""
    import queue
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the caller's to handle
    die_with_parent()
    os.environ.setdefault("MUJOCO_GL", "egl")
    outbox: queue.Queue = queue.Queue()

    def send():
        while (message := outbox.get()) is not None:
            conn.send(message)

    sender = threading.Thread(target=send, daemon=True)
    sender.start()
    worker, error = _build(factory, index)
    try:
        while True:
            try:
                message = conn.recv()
            except (EOFError, OSError):
                break
            if message is None:
                break
            call_id, method, args = message
            outbox.put((call_id, *_run(worker, error, method, args)))
    finally:
        outbox.put(None)
        sender.join()
        if worker is not None:
            _close(worker)


class Pool:
    """``size`` workers built by ``factory(index)``, locally or on Ray (module
    docstring); use as a context manager or call `close`.

    ``restarts`` counts the workers replaced after their process died.

    Raises (from `connect` for Ray): `physics_planning.cli.UsageError`, in one
    line, when no Ray cluster answers at ``address``.
    """

    def __init__(
        self,
        factory: Callable,
        size: int,
        *,
        address: str | None = None,
        cpus: float = 1,
        name: str = "worker",
        context=None,
    ):
        self.factory, self.address, self.cpus, self.name = factory, address, cpus, name
        self.deaths = Deaths()
        self.restarts, self._ids = 0, 0
        self._calls: dict[int, Call] = {}  # under way, by id
        self._closed = False
        if address is None:
            import multiprocessing

            self._ctx = context or multiprocessing.get_context("spawn")
            self._local = [self._start_local(i) for i in range(size)]
        else:
            from hier_agents.cluster import connect, remote

            self._ray = connect(address, num_cpus=None if address != "local" else size * cpus)
            room = int(self._ray.cluster_resources().get("CPU", 1) // cpus) or 1
            self._remote = remote(_RayWorker, num_cpus=cpus, max_restarts=0)
            self._actors = [self._start_ray(i) for i in range(min(size, room))]
            self._refs: dict = {}  # ObjectRef -> call id

    @property
    def size(self) -> int:
        return len(self._local if self.address is None else self._actors)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- submitting and waiting ---------------------------------------------------------------

    def submit(self, method: str, *args, worker: int | None = None, label: str = "") -> Call:
        """Queues ``method(*args)`` on worker ``worker`` (default: the one with
        the fewest calls under way); returns its `Call`."""
        if worker is None:
            load = [0] * self.size
            for call in self._calls.values():
                load[call.worker] += 1
            worker = load.index(min(load))
        self._ids += 1
        call = Call(self._ids, worker, method, args, label or f"call {self._ids}")
        self._calls[call.id] = call
        self._send(call)
        return call

    @property
    def pending(self) -> int:
        """Calls submitted and not yet returned by `next`."""
        return len(self._calls)

    def next(
        self, timeout: float | None = None, should_stop: Callable[[], bool] | None = None
    ) -> Call | None:
        """The first finished call (its ``result`` set), or None once
        ``should_stop()`` is true or no call is under way.

        Raises:
          CallFailed: the call raised in its worker (its traceback).
          WorkerDied: a call's worker died more than `WORKER_RETRIES` times.
          TimeoutError: nothing finished within ``timeout`` seconds.
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        while self._calls:
            if should_stop is not None and should_stop():
                return None
            done = self._poll_local() if self.address is None else self._poll_ray()
            if done is not None:
                call_id, ok, payload = done
                call = self._calls.pop(call_id)
                if not ok:
                    raise CallFailed(f"{call.label} failed:\n{payload}", call, payload)
                call.result = payload
                return call
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"no {self.name} finished a call within {timeout:.0f} s")
        return None

    def _died(self, index: int, how: str, where: str) -> None:
        """The retry policy for worker ``index``: note, replace, run its calls again."""
        calls = sorted((c for c in self._calls.values() if c.worker == index), key=lambda c: c.id)
        if calls:
            self.deaths.died([c.id for c in calls], [c.label for c in calls], how, where)
        self.restarts += 1
        if self.address is None:
            self._local[index] = self._start_local(index)
        else:
            self._actors[index] = self._start_ray(index)
        for call in calls:
            self._send(call)

    # -- local processes -------------------------------------------------------------------

    def _start_local(self, index: int):
        parent, child = self._ctx.Pipe()
        process = self._ctx.Process(
            target=_serve,
            args=(self.factory, index, child),
            daemon=True,
            name=f"{self.name}-{index}",
        )
        process.start()
        child.close()
        return process, parent

    def _send(self, call: Call) -> None:
        if self.address is None:
            try:
                self._local[call.worker][1].send((call.id, call.method, call.args))
            except (BrokenPipeError, ConnectionResetError, EOFError):
                pass  # the worker is dead: `_poll_local` sees it and sends the call again
        else:
            ref = self._actors[call.worker].call.remote(call.method, call.args)
            self._refs[ref] = call.id

    def _poll_local(self):
        from multiprocessing.connection import wait

        waits = {}
        for index, (process, conn) in enumerate(self._local):
            waits[conn] = waits[process.sentinel] = index
        ready = wait(list(waits), timeout=_POLL_S)
        for conn in [r for r in ready if not isinstance(r, int)]:
            try:
                return conn.recv()
            except (EOFError, OSError):
                pass  # its process is gone: the sentinel says how
        for sentinel in [r for r in ready if isinstance(r, int)]:
            index = waits[sentinel]
            process, conn = self._local[index]
            if conn.poll():  # results sent before it died come first
                try:
                    return conn.recv()
                except (EOFError, OSError):
                    pass
            process.join(1)
            conn.close()
            self._died(index, exit_status(process.exitcode), "process")
            return None
        return None

    # -- Ray ---------------------------------------------------------------------------------

    def _start_ray(self, index: int):
        return self._remote.remote(self.factory, index)

    def _poll_ray(self):
        ray = self._ray
        ready, _ = ray.wait(list(self._refs), num_returns=1, timeout=_POLL_S)
        if not ready:
            return None
        call_id = self._refs.pop(ready[0])
        try:
            return call_id, True, ray.get(ready[0])
        except ray.exceptions.RayTaskError as exc:
            return call_id, False, str(exc)
        except (
            ray.exceptions.RayActorError,
            ray.exceptions.WorkerCrashedError,
            ray.exceptions.NodeDiedError,
            ray.exceptions.ObjectLostError,
        ) as exc:
            index = self._calls[call_id].worker
            # The worker's other calls fail the same way: drop their references.
            for ref in [r for r, c in self._refs.items() if self._calls[c].worker == index]:
                del self._refs[ref]
            try:
                ray.kill(self._actors[index])
            except Exception:  # noqa: BLE001 - already gone
                pass
            how = f"{type(exc).__name__}: {str(exc).strip().splitlines()[0][:120]}"
            self._died(index, how, "Ray actor")
            return None

    # -- closing -----------------------------------------------------------------------------

    def close(self) -> None:
        """Stops every worker: a busy one at once (SIGTERM; its call is
        dropped), an idle one after closing its object; idempotent."""
        if self._closed:
            return
        self._closed = True
        busy = {call.worker for call in self._calls.values()}
        self._calls.clear()
        if self.address is not None:
            for actor in self._actors:
                try:
                    self._ray.kill(actor)
                except Exception:  # noqa: BLE001 - already gone
                    pass
            return
        for index, (process, conn) in enumerate(self._local):
            if index in busy:  # stopped now, not when its call ends
                process.terminate()
                continue
            try:
                conn.send(None)
            except (OSError, ValueError):
                pass
        deadline = time.monotonic() + 5
        for process, _ in self._local:
            process.join(max(0.0, deadline - time.monotonic()))
            if process.is_alive():
                process.terminate()
        for process, conn in self._local:
            process.join(5)
            if process.is_alive():
                process.kill()
                process.join()
            conn.close()


class _RayWorker:  # pragma: no cover - runs in Ray actors
    """A Ray actor holding one worker built by ``factory(index)``."""

    def __init__(self, factory, index: int):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        self.worker, self.error = _build(factory, index)

    def call(self, method: str, args: tuple):
        ok, value = _run(self.worker, self.error, method, args)
        if not ok:
            raise CallFailed(value)
        return value
