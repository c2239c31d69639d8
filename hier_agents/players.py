"""Where `hier_agents.run` plays its episodes: here (`play_here`), or split
over processes (``--workers``) or Ray tasks (``--ray-address``)
(`play_parallel`).

A worker process rebuilds its own player from the `Play`
(`hier_agents.agents.runner.make_player`, one player per process, closed at
exit) and plays shards of episodes (`play_shard`). Episode ``e`` is seeded
from ``(play.seed, e)``; the drivers only decide where it runs, never what
it does, so any split gives the same rows.
"""

from __future__ import annotations

import math
import sys
from typing import Callable

from hier_agents.agents.runner import Play, make_player, play_each

__all__ = ["Play", "Progress", "play_here", "play_parallel", "play_shard"]

Progress = Callable[[dict], None]
_play_each = play_each


def play_here(play: Play, indices, on_done, built=None) -> None:
    """Plays ``indices`` in this process, reporting each episode to ``on_done``."""
    player = make_player(play)
    try:
        if built is not None:
            built(player.info)
        play_each(player, play, indices, lambda result: on_done([result], player.info))
    finally:
        player.close()


#: Per worker process: its player, by the ``repr`` of its `Play`.
_PLAYERS: dict = {}


def play_shard(play: Play, indices: list[int]) -> tuple[list, dict]:
    """Plays ``indices`` with this process's player of ``play`` (built on
    first use and kept for later shards); returns ([(row, counters)], info).
    The function worker processes and Ray tasks run."""
    player = _PLAYERS.get(repr(play))
    if player is None:
        _close_players()  # one environment per process at a time
        player = _PLAYERS[repr(play)] = make_player(play)
    out = []
    _play_each(player, play, indices, out.append)
    return out, player.info


def _close_players() -> None:
    for player in _PLAYERS.values():
        player.close()
    _PLAYERS.clear()


#: The most episodes in one shard: progress and ``--json`` are updated per shard.
MAX_SHARD = 8


def shards(indices: list[int], workers: int) -> list[list[int]]:
    """``indices`` cut into contiguous shards, at least four per worker and
    at most `MAX_SHARD` episodes each (at least one), so that faster workers
    take more of them and progress is reported often."""
    size = max(1, min(MAX_SHARD, math.ceil(len(indices) / (4 * workers))))
    return [indices[i:i + size] for i in range(0, len(indices), size)]


#: How many times a shard is played again after the process or Ray task
#: playing it died (a crash in native code, the out-of-memory killer, a lost
#: node); a shard that dies more often fails the run.
WORKER_RETRIES = 3


class WorkerDied(RuntimeError):
    """A worker process died while playing a shard more than `WORKER_RETRIES`
    times: the run stops (the episodes already played are in the ``--json``
    written so far)."""


def play_parallel(play: Play, indices, workers, ray_address, on_done) -> int:
    """Plays ``indices`` in `shards` over ``workers`` spawned processes (one
    player each), or as Ray tasks on the cluster at ``ray_address``; each
    finished shard's results go to ``on_done`` as they arrive.

    A worker process that dies (a signal, an abort in native code) takes its
    pool with it: the shards not yet reported are played again in a new pool
    (episodes are seeded by index, so their rows are the ones they would have
    been), with a line on stderr, at most `WORKER_RETRIES` times; Ray retries
    a dead task as often. Returns how many times a local pool was replaced.

    Raises:
      WorkerDied: the workers died more than `WORKER_RETRIES` times.
    """
    pieces = shards(indices, workers)
    if ray_address is not None:
        _play_ray(play, pieces, workers, ray_address, on_done)
        return 0
    from concurrent.futures.process import BrokenProcessPool

    restarts = 0
    while True:
        try:
            _play_pool(play, pieces, workers, on_done)
            return restarts
        except BrokenProcessPool as exc:
            restarts += 1
            if restarts > WORKER_RETRIES:
                raise WorkerDied(
                    f"a worker process died while playing {play.env_name} "
                    f"{WORKER_RETRIES + 1} times ({exc.reason}); the episodes under way "
                    "are not played") from exc
            print(f"hier_agents: a worker process died ({exc.reason}); playing its "
                  f"{len(pieces)} unfinished shard(s) again in new processes "
                  f"(retry {restarts} of {WORKER_RETRIES})", file=sys.stderr, flush=True)


def _play_pool(play: Play, pieces: list, workers: int, on_done) -> None:
    """`play_parallel` in one process pool. Shards are removed from
    ``pieces`` as their results are handed to ``on_done``; on
    `BrokenProcessPool` (``reason`` set to what is known of the death) the
    ones left are those still to play."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    context = multiprocessing.get_context("spawn")  # no GL or torch state inherited
    pool = ProcessPoolExecutor(max_workers=min(workers, len(pieces)), mp_context=context,
                               initializer=_worker_init)
    processes = []
    try:
        pending = {pool.submit(play_shard, play, piece): piece for piece in pieces}
        # The pool forgets its processes once broken: keep them to say how one died.
        processes = list((getattr(pool, "_processes", None) or {}).values())
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                piece = pending.pop(future)
                on_done(*future.result())
                pieces.remove(piece)
    except BaseException as exc:
        # Ctrl-C, a failed shard or a dead worker: the shards under way are
        # dropped, their workers stopped now rather than when their shard ends.
        processes = processes or list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        for process in processes:
            process.join(5)
        if isinstance(exc, BrokenProcessPool):
            exc.reason = _death(process.exitcode for process in processes)
        raise
    pool.shutdown(wait=True)


def _death(exit_codes) -> str:
    """How a broken pool's workers died, in words: the exit statuses other
    than 0 and SIGTERM (which the pool, then this module, send to the workers
    left), or SIGTERM if that is all there is."""
    import signal
    codes = [code for code in exit_codes if code not in (None, 0)]
    own = [code for code in codes if code != -signal.SIGTERM] or codes
    return ", ".join(map(_exit_status, sorted(set(own)))) or "exit status unknown"


def _exit_status(code: int) -> str:
    """A process's exit code in words: ``"killed by SIGABRT"`` for -6."""
    if code < 0:
        import signal
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def _worker_init() -> None:
    import atexit
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    atexit.register(_close_players)


def _play_ray(play: Play, pieces, workers, address, on_done) -> None:
    from hier_agents.cluster import connect, remote

    ray = connect(address)
    task = remote(play_shard, num_cpus=1, max_retries=WORKER_RETRIES)
    queue = list(pieces)
    running = []
    while queue or running:
        while queue and len(running) < workers:
            running.append(task.remote(play, queue.pop(0)))
        done, running = ray.wait(running, num_returns=1)
        for ref in done:
            on_done(*ray.get(ref))
