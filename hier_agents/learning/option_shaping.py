"""Reward shaping and the physics-free warm-start environment of
`hier_agents.learning.train_options` (see its module docstring for how
training uses them).

* `potential` (Phi): ``-(box_weight * sum over boxes off pads of the box's
  distance to the nearest pad + player_weight * the player's walking
  distance to a cell next to such a box)``, distances in cells (``walk``:
  walking distance around walls; ``push``: pushes bringing the box alone
  onto a pad); 0 for a solved state.
* `Shaped`: a gymnasium wrapper adding the semi-MDP potential-based shaping
  ``gamma ** d * Phi(s') - Phi(s)`` (Ng et al. 1999) to the reward.
* `AbstractOptionEnv`: `OptionEnv`'s interface without MuJoCo (Sokoban moves
  on generated levels, every option lasting a fixed number of control
  steps); `difficulty_of` reads the level difficulty from an environment name.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from abstract_planners.sokoban import MOVES, SokobanState

__all__ = [
    "ABSTRACT_DURATION",
    "TIME_LIMIT_STEPS",
    "potential",
    "Shaped",
    "difficulty_of",
    "AbstractOptionEnv",
]

#: Control steps per option assumed by the abstract warm start (measured mean, level 1-2).
ABSTRACT_DURATION = 18
#: The MuJoBan time limit in control steps (45 s of 0.05 s).
TIME_LIMIT_STEPS = 900


# -- shaping potential ------------------------------------------------------------------------

_STEPS = ((-1, 0), (1, 0), (0, -1), (0, 1))


def _bfs(starts, free) -> dict:
    """Walking distances from ``starts`` over the cells for which ``free(cell)``."""
    dist = {cell: 0 for cell in starts}
    frontier = list(starts)
    while frontier:
        nxt = []
        for r, c in frontier:
            for dr, dc in _STEPS:
                cell = (r + dr, c + dc)
                if cell not in dist and free(cell):
                    dist[cell] = dist[(r, c)] + 1
                    nxt.append(cell)
        frontier = nxt
    return dist


_PAD_DISTANCES: dict = {}


def _push_distances(state: SokobanState, floor) -> dict:
    """Pushes needed to bring a lone box from each cell onto the nearest pad
    (other boxes ignored): a reverse search from the pads, a box at ``p``
    reaching ``p + d`` with the player at ``p - d``. Cells missing from the
    result are dead: no pad can be reached from them."""
    dist = {cell: 0 for cell in state.targets}
    frontier = list(state.targets)
    while frontier:
        nxt = []
        for r, c in frontier:
            for dr, dc in _STEPS:
                before, player = (r - dr, c - dc), (r - 2 * dr, c - 2 * dc)
                if before not in dist and floor(before) and floor(player):
                    dist[before] = dist[(r, c)] + 1
                    nxt.append(before)
        frontier = nxt
    return dist


def potential(
    state: SokobanState, box_weight: float, player_weight: float, box_distance: str = "push"
) -> float:
    """Phi(s) of the module docstring (0 for a solved state)."""
    loose = state.boxes - state.targets
    if not loose:
        return 0.0
    height, width = state.height, state.width

    def floor(cell):
        return cell not in state.walls and 0 <= cell[0] < height and 0 <= cell[1] < width

    key = (state.walls, state.targets, box_distance)
    to_pad = _PAD_DISTANCES.get(key)
    if to_pad is None:
        if len(_PAD_DISTANCES) > 4096:
            _PAD_DISTANCES.clear()
        to_pad = _PAD_DISTANCES[key] = (
            _push_distances(state, floor) if box_distance == "push" else _bfs(state.targets, floor)
        )
    far = height + width
    box_term = sum(to_pad.get(box, far) for box in loose)
    player_term = 0.0
    if player_weight:
        beside = {(r + dr, c + dc) for r, c in loose for dr, dc in _STEPS}
        walk = _bfs([state.player], lambda cell: floor(cell) and cell not in state.boxes)
        player_term = min((walk[c] for c in beside if c in walk), default=far)
    return -(box_weight * box_term + player_weight * player_term)


class Shaped(gym.Wrapper):
    """Adds the shaping ``gamma ** info["duration"] * Phi(s') - Phi(s)`` to the
    reward (``Phi(s') = 0`` when the episode terminates) and ``info["potential"]``
    (Phi of the estimated abstract state)."""

    def __init__(
        self,
        env,
        box_weight: float,
        player_weight: float,
        box_distance: str = "push",
        gamma: float = 0.995,
    ):
        super().__init__(env)
        self.weights = (float(box_weight), float(player_weight), box_distance)
        self.gamma = float(gamma)
        self._potential = 0.0

    def _with_potential(self, info):
        info["potential"] = self._potential = potential(
            self.env.unwrapped.abstract_state, *self.weights
        )
        return info

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        return obs, self._with_potential(info)

    def step(self, action):
        before = self._potential
        obs, reward, terminated, truncated, info = self.env.step(action)
        after = self._with_potential(info)["potential"]
        discount = self.gamma ** info.get("duration", 1)
        shaped = reward + discount * (0.0 if terminated else after) - before
        return obs, float(shaped), terminated, truncated, info


# -- the abstract warm-start environment ---------------------------------------------------


def difficulty_of(env_name: str) -> int:
    """``mujoban/level2`` (or ``-pegs``) -> 2."""
    tail = env_name.split("/", 1)[-1]
    if not tail.startswith("level"):
        raise ValueError(
            f"the abstract warm start needs generated levels (mujoban/levelN), got {env_name!r}"
        )
    return int(tail[len("level") :].split("-")[0])


class AbstractOptionEnv(gym.Env):
    """`OptionEnv`'s interface without physics: generated levels of one
    difficulty padded into the 10x10 arena as MuJoBan pads them, moves applied
    by `SokobanState`, MuJoBan's rewards, every option lasting ``duration``
    control steps (see the module docstring)."""

    metadata = {"render_modes": []}

    def __init__(
        self, env_name: str, seed: int, duration: int = ABSTRACT_DURATION, gamma: float = 0.995
    ):
        from envs.mujoban.sources import ARENA_SHAPE

        self.difficulty = difficulty_of(env_name)
        self.shape = ARENA_SHAPE
        self.duration, self.gamma = int(duration), float(gamma)
        self.max_options = TIME_LIMIT_STEPS // self.duration
        self.rng = np.random.default_rng(seed)
        self.action_space = gym.spaces.Discrete(len(MOVES))
        self.observation_space = gym.spaces.Box(0.0, 1.0, (4, *self.shape), np.float32)
        self.abstract_state = None

    def reset(self, *, seed=None, options=None):
        from envs.mujoban import generator

        super().reset(seed=seed)
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        level = generator.generate_level(self.difficulty, rng=self.rng).padded(*self.shape)
        self.abstract_state = SokobanState.from_level(level)
        self.options = 0
        return self._obs(), self._info(0)

    def step(self, action):
        state, move = self.abstract_state, MOVES[int(action)]
        if not state.is_legal(move):
            raise ValueError(f"illegal move {move!r} (the trainer masks them)")
        new = state.apply(move)
        on = len(new.boxes & new.targets) - len(state.boxes & state.targets)
        solved = new.is_solved()
        # The reward arrives at the option's last control step.
        reward = (self.gamma ** (self.duration - 1)) * (on + (10.0 if solved else 0.0))
        self.abstract_state = new
        self.options += 1
        truncated = not solved and self.options >= self.max_options
        return self._obs(), float(reward), bool(solved), bool(truncated), self._info(self.duration)

    def _obs(self):
        from hier_agents.learning.option_env import encode_sokoban

        return encode_sokoban(self.abstract_state, self.shape)

    def _info(self, duration):
        state = self.abstract_state
        return {
            "duration": duration,
            "action_mask": np.array([state.is_legal(m) for m in MOVES], np.int8),
        }
