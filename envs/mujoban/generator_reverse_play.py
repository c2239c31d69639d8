"""Steps 2-5 of the level generator (`envs.mujoban.generator`): from a carved
room, place a solved state, play it in reverse (random walks that pull
boxes), keep the best-scoring state and turn it into a `Level` with its
forward solution (loops cut out).

Rooms are flat ``size*size`` bytearrays (1 = floor) and cells flat indices;
directions index ``(up, down, left, right)`` and ``d ^ 1`` is the opposite
of ``d``. Only the random generator passed in is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.mujoban.levels import Level

#: Probability that a step away from an adjacent box pulls it.
_PULL_PROB = 0.8
#: Reverse-play steps per floor cell of the room.
_STEPS_PER_CELL = 10
#: Reverse-play walks per solved state; the best state over all is kept.
_WALKS = 4
#: Solved states (target and player placements) tried per room.
_PLACEMENTS = 3

#: Move letters, indexed by direction; ``d ^ 1`` is the opposite of ``d``.
_LETTERS = ("U", "D", "L", "R")


@dataclass
class _Found:
    """The best reverse-play state: box cells, targets and player (flat indices).

    ``rank`` orders states: first those with no box on a target (as in the
    Boxoban levels), then by score.
    """

    rank: tuple[bool, int]
    targets: tuple[int, ...]
    boxes: tuple[int, ...]
    player: int
    moves: list[int]


def _best_reverse_play(
    floor: bytearray, size: int, num_boxes: int, rng: np.random.Generator
) -> _Found | None:
    """The best state over several placements and walks, or None."""
    cells = np.flatnonzero(np.frombuffer(bytes(floor), dtype=np.uint8))
    steps = _STEPS_PER_CELL * len(cells)
    best: _Found | None = None
    for _ in range(_PLACEMENTS):
        chosen = [int(i) for i in rng.choice(cells, size=num_boxes + 1, replace=False)]
        targets, player = tuple(chosen[:-1]), chosen[-1]
        for _ in range(_WALKS):
            found = _reverse_walk(floor, size, targets, player, steps, rng)
            if found is not None and (best is None or found.rank > best.rank):
                best = found
    return best


def _reverse_walk(
    floor: bytearray,
    size: int,
    targets: tuple[int, ...],
    player: int,
    steps: int,
    rng: np.random.Generator,
) -> _Found | None:
    """One random walk of reverse play from the solved state.

    Returns the walk's best state (see `_Found.rank`) among those with a
    positive score and at least one box off the targets, or None.
    """
    deltas = (-size, size, -1, 1)
    target_set = set(targets)
    boxes = list(targets)
    where = {cell: i for i, cell in enumerate(boxes)}  # cell -> box id
    on_target, displacement, swaps, last = len(boxes), 0, 0, -1
    directions = rng.integers(0, 4, steps).tolist()
    pulls = (rng.random(steps) < _PULL_PROB).tolist()
    moves: list[int] = []
    best_rank, best_state = (False, 0), None
    for d, pull in zip(directions, pulls):
        ahead = player + deltas[d]
        if not floor[ahead] or ahead in where:
            continue
        behind = player - deltas[d]
        box = where.get(behind) if pull else None
        if box is not None:
            del where[behind]
            where[player] = box
            boxes[box] = player
            on_target += (player in target_set) - (behind in target_set)
            displacement += _distance(player, targets[box], size) - _distance(
                behind, targets[box], size
            )
            swaps += box != last
            last = box
        player = ahead
        moves.append(d)
        rank = (on_target == 0, swaps * displacement)
        if rank[1] > 0 and on_target < len(boxes) and rank > best_rank:
            best_rank, best_state = rank, (tuple(boxes), player, len(moves))
    if best_state is None:
        return None
    best_boxes, best_player, length = best_state
    return _Found(best_rank, targets, best_boxes, best_player, moves[:length])


def _distance(a: int, b: int, size: int) -> int:
    """Manhattan distance between two flat cell indices."""
    ar, ac = divmod(a, size)
    br, bc = divmod(b, size)
    return abs(ar - br) + abs(ac - bc)


# -- step 5: the level -------------------------------------------------------------


def _to_level(floor: bytearray, size: int, found: _Found) -> tuple[Level, list[str]]:
    """The `Level` of a reverse-play state and its forward solution."""
    cell = lambda i: divmod(i, size)  # noqa: E731
    walls = frozenset(cell(i) for i in range(size * size) if not floor[i])
    level = Level(
        walls=walls,
        targets=frozenset(map(cell, found.targets)),
        boxes=frozenset(map(cell, found.boxes)),
        player=cell(found.player),
        height=size,
        width=size,
    )
    forward = [d ^ 1 for d in reversed(found.moves)]
    solution = _shorten(forward, size, found.boxes, found.player, set(found.targets))
    return level, [_LETTERS[d] for d in solution]


def _shorten(
    moves: list[int], size: int, boxes: tuple[int, ...], player: int, targets: set[int]
) -> list[int]:
    """A forward solution without its detours.

    Replays ``moves`` (known to end solved), cutting out every loop that
    returns to an earlier state and stopping at the first solved state.
    """
    deltas = (-size, size, -1, 1)
    box_set = set(boxes)
    states = [(player, frozenset(box_set))]  # states[i]: after kept[:i]
    seen = {states[0]: 0}
    kept: list[int] = []
    for d in moves:
        if box_set == targets:
            break
        ahead = player + deltas[d]
        if ahead in box_set:
            box_set.remove(ahead)
            box_set.add(ahead + deltas[d])
        player = ahead
        state = (player, frozenset(box_set))
        if state in seen:  # a loop: forget everything since the first visit
            for dropped in states[seen[state] + 1 :]:
                del seen[dropped]
            del states[seen[state] + 1 :], kept[seen[state] :]
        else:
            kept.append(d)
            states.append(state)
            seen[state] = len(kept)
    return kept
