"""The procedural level generator and the curriculum sampler."""

from __future__ import annotations

from collections import Counter, deque

import numpy as np
import pytest

from envs.mujoban import generator
from envs.mujoban.levels import Level

MOVES = {"U": (-1, 0), "D": (1, 0), "L": (0, -1), "R": (0, 1)}


def bfs_solve(level: Level, max_states: int = 2_000_000) -> list[str] | None:
    """A plain breadth-first search over (player, boxes): shortest solution or None."""
    walls = level.walls
    start = (level.player, frozenset(level.boxes))
    parent = {start: None}
    queue = deque([start])
    while queue:
        state = queue.popleft()
        player, boxes = state
        if boxes == level.targets:
            path = []
            while parent[state] is not None:
                state, move = parent[state]
                path.append(move)
            return path[::-1]
        for move, (dr, dc) in MOVES.items():
            ahead = (player[0] + dr, player[1] + dc)
            if ahead in walls:
                continue
            new_boxes = boxes
            if ahead in boxes:
                beyond = (ahead[0] + dr, ahead[1] + dc)
                if beyond in walls or beyond in boxes:
                    continue
                new_boxes = (boxes - {ahead}) | {beyond}
            new_state = (ahead, new_boxes)
            if new_state not in parent:
                parent[new_state] = (state, move)
                queue.append(new_state)
                if len(parent) > max_states:
                    raise AssertionError("BFS state budget exhausted")
    return None


def replay(level: Level, moves: list[str]) -> frozenset:
    """Plays moves by Sokoban rules (asserting each is legal); final box cells."""
    player, boxes = level.player, set(level.boxes)
    for move in moves:
        dr, dc = MOVES[move]
        ahead = (player[0] + dr, player[1] + dc)
        assert ahead not in level.walls, f"move {move} walks into a wall"
        if ahead in boxes:
            beyond = (ahead[0] + dr, ahead[1] + dc)
            assert beyond not in level.walls and beyond not in boxes, f"blocked push {move}"
            boxes.remove(ahead)
            boxes.add(beyond)
        player = ahead
    return frozenset(boxes)


def test_bfs_helper_finds_an_unsolvable_level_unsolvable():
    # The box sits in a corner: no push can move it. The BFS must say so,
    # or the solvability test below could not fail.
    stuck = Level.from_text("#####\n#$  #\n#   #\n# .@#\n#####")
    assert bfs_solve(stuck) is None
    assert bfs_solve(Level.from_text("#####\n#   #\n#@$.#\n#   #\n#####")) == ["R"]


@pytest.mark.parametrize("difficulty", [1, 2, 3])
def test_generated_levels_of_l1_to_l3_are_solved_by_bfs(difficulty):
    spec = generator.difficulty(difficulty)
    for seed in range(25):
        level = generator.generate_level(difficulty, seed=seed)
        assert (level.height, level.width) == (spec.size, spec.size)
        assert len(level.boxes) == len(level.targets) == spec.num_boxes
        assert not level.is_solved()
        solution = bfs_solve(level)
        assert solution is not None, f"seed {seed} gave an unsolvable level:\n{level.to_text()}"
        assert len(solution) >= 1


@pytest.mark.parametrize("difficulty", [1, 2, 3, 4, 5])
def test_the_returned_solution_solves_the_level(difficulty):
    for seed in range(10):
        level, solution = generator.generate_level(difficulty, seed=seed, return_solution=True)
        assert replay(level, solution) == level.targets


def test_generated_rooms_are_closed_by_walls_and_connected():
    for seed in range(20):
        level = generator.generate_level(5, seed=seed)
        size = level.height
        floor = {(r, c) for r in range(size) for c in range(size)} - level.walls
        assert all(0 < r < size - 1 and 0 < c < size - 1 for r, c in floor)
        # Every floor cell is reachable from the player, ignoring boxes.
        seen, todo = {level.player}, [level.player]
        while todo:
            r, c = todo.pop()
            for dr, dc in MOVES.values():
                nxt = (r + dr, c + dc)
                if nxt in floor and nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        assert seen == floor


def test_same_seed_same_level_and_different_seeds_differ():
    for difficulty in range(1, 6):
        first = [generator.generate_level(difficulty, seed=s).to_text() for s in range(5)]
        again = [generator.generate_level(difficulty, seed=s).to_text() for s in range(5)]
        assert first == again
        assert len(set(first)) > 1
    rng_a, rng_b = np.random.default_rng(7), np.random.default_rng(7)
    assert [generator.generate_level(4, rng=rng_a) for _ in range(3)] == [
        generator.generate_level(4, rng=rng_b) for _ in range(3)
    ]


def test_custom_size_and_box_count():
    level = generator.generate_level(9, 3, seed=0)
    assert (level.height, level.width, len(level.boxes)) == (9, 9, 3)


@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        ((0,), {}, "difficulty"),
        ((6,), {}, "difficulty"),
        ((2.0,), {}, "difficulty"),
        ((True,), {}, "difficulty"),
        ((4, 1), {}, "size"),
        ((5, 0), {}, "num_boxes"),
        ((5, 3), {}, "num_boxes"),
        ((1,), {"seed": 1, "rng": np.random.default_rng(1)}, "either"),
    ],
)
def test_bad_arguments_are_value_errors(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        generator.generate_level(*args, **kwargs)


def test_paper_difficulty_table():
    table = [(d.level, d.size, d.num_boxes, d.ratio) for d in generator.DIFFICULTIES]
    assert table == [
        (1, 5, 1, 0.25),
        (2, 7, 1, 0.25),
        (3, 7, 2, 0.2),
        (4, 8, 3, 0.2),
        (5, 10, 4, 0.1),
    ]


def test_curriculum_draws_difficulties_with_the_paper_ratios():
    curriculum = generator.Curriculum()
    rng = np.random.default_rng(0)
    n = 20_000
    counts = Counter(curriculum.sample_difficulty(rng).level for _ in range(n))
    for spec in generator.DIFFICULTIES:
        expected = spec.ratio * n
        # 5 standard deviations of a binomial count.
        assert abs(counts[spec.level] - expected) < 5 * np.sqrt(n * spec.ratio * (1 - spec.ratio))


def test_curriculum_levels_match_their_difficulty_and_custom_ratios_are_respected():
    rng = np.random.default_rng(1)
    for _ in range(20):
        spec, level = generator.Curriculum().sample(rng)
        assert (level.height, len(level.boxes)) == (spec.size, spec.num_boxes)
    only_l2 = generator.Curriculum([0, 1, 0, 0, 0])
    assert {only_l2.sample_difficulty(rng).level for _ in range(200)} == {2}


@pytest.mark.parametrize(
    "ratios", [[0.5, 0.5], [0.3, 0.3, 0.3, 0.3, 0.3], [-0.1, 0.3, 0.3, 0.3, 0.2], ["a", 0, 0, 0, 1]]
)
def test_bad_curriculum_ratios_are_value_errors(ratios):
    with pytest.raises(ValueError, match="ratios"):
        generator.Curriculum(ratios)
