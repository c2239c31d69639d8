"""Where `hier_agents.run` plays its episodes: here (`play_here`), or split
over processes (``--workers``) or Ray actors (``--ray-address``)
(`play_parallel`).

A worker of the executor (`hier_agents.executor.Pool`: a spawned process
or a Ray actor) rebuilds its own player from the `Play`
(`hier_agents.agents.runner.make_player`, one player per worker, closed at
exit) and plays shards of episodes (`play_shard`). Episode ``e`` is seeded
from ``(play.seed, e)``; the drivers only decide where it runs, never what
it does, so any split gives the same rows.
"""

from __future__ import annotations

import math
from typing import Callable

from hier_agents.agents.runner import Play, make_player, play_each
from hier_agents.executor import WORKER_RETRIES, Pool, WorkerDied  # noqa: F401 - re-exported

__all__ = [
    "Play",
    "Progress",
    "WORKER_RETRIES",
    "WorkerDied",
    "play_here",
    "play_parallel",
    "play_shard",
    "shards",
]

Progress = Callable[[dict], None]


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
    What a worker of `play_parallel` runs."""
    player = _PLAYERS.get(repr(play))
    if player is None:
        _close_players()  # one environment per process at a time
        player = _PLAYERS[repr(play)] = make_player(play)
    out: list[tuple[dict, dict]] = []  # (row, counters) per episode
    play_each(player, play, indices, out.append)
    return out, player.info


def _close_players() -> None:
    for player in _PLAYERS.values():
        player.close()
    _PLAYERS.clear()


class ShardWorker:
    """An `executor.Pool` worker of `play_parallel`: ``play(indices)`` is
    `play_shard` of its `Play`; ``close`` closes its player."""

    def __init__(self, play: Play, index: int = 0):
        self.spec = play

    def play(self, indices: list[int]) -> tuple[list, dict]:
        return play_shard(self.spec, indices)

    def close(self) -> None:
        _close_players()


#: The most episodes in one shard: progress and ``--json`` are updated per shard.
MAX_SHARD = 8


def shards(indices: list[int], workers: int) -> list[list[int]]:
    """``indices`` cut into contiguous shards, at least four per worker and
    at most `MAX_SHARD` episodes each (at least one), so that faster workers
    take more of them and progress is reported often."""
    size = max(1, min(MAX_SHARD, math.ceil(len(indices) / (4 * workers))))
    return [indices[i : i + size] for i in range(0, len(indices), size)]


def play_parallel(play: Play, indices, workers, ray_address, on_done) -> int:
    """Plays ``indices`` in `shards` over an `executor.Pool` of ``workers``
    (spawned processes, or Ray actors on the cluster at ``ray_address``; one
    player each, kept); each finished shard's results go to ``on_done`` as
    they arrive. Returns how many workers were replaced.

    A worker that dies has its shards played again by a new one (episodes
    are seeded by index, so their rows are the ones they would have been),
    the executor's one retry policy (`executor.Deaths`: a line on stderr, at
    most `WORKER_RETRIES` times per shard).

    Raises:
      WorkerDied: a shard's worker died more than `WORKER_RETRIES` times.
      UsageError: no Ray cluster answers at ``ray_address``.
    """
    from functools import partial

    pieces = shards(indices, workers)
    with Pool(
        partial(ShardWorker, play), min(workers, len(pieces)), address=ray_address, name="player"
    ) as pool:
        queue = list(enumerate(pieces))
        while queue or pool.pending:
            while queue and pool.pending < 2 * pool.size:  # one shard queued behind each
                number, piece = queue.pop(0)
                pool.submit(
                    "play",
                    piece,
                    label=f"shard {number + 1} of {len(pieces)} "
                    f"(episodes {piece[0]}-{piece[-1]} of {play.env_name})",
                )
            on_done(*pool.next().result)
        return pool.restarts
