"""Planners on any OpenSpiel two-player game: MCTS (OpenSpiel's C++ bot),
depth-limited alpha-beta, and `make_bot`, which builds one from a name.

These are the board games' opponents (`envs.boards`) and the modular
agent's planners for games without a dedicated engine. They plan on
pyspiel states and never mutate them.
"""

from __future__ import annotations

import math
import numbers
import time

import numpy as np
import pyspiel

from abstract_planners.base import Planner, Subgoal
from abstract_planners.board_random import RandomMovePlanner, check_decision_state

__all__ = ["MCTSPlanner", "AlphaBetaPlanner", "make_bot", "BOT_FORMS"]


def _check_real(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return float(value)


def _check_int(value, name: str, low: int, high: int | None = None) -> int:
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if ok:
        value = int(value)
        ok = value >= low and (high is None or value <= high)
    if not ok:
        allowed = f"{low}..{high}" if high is not None else f">= {low}"
        raise ValueError(f"{name} must be an integer in the range {allowed}, got {value!r}")
    return value


class MCTSPlanner(Planner):
    """Monte-Carlo tree search (OpenSpiel's C++ ``MCTSBot``) with random rollouts.

    Works on any turn-based pyspiel game (Go, tic-tac-toe, ...).

    Args:
      simulations: tree simulations per move (>= 1).
      rollouts: random rollouts per leaf evaluation (>= 1); the rollout
        policy is uniformly random over legal actions (passes included).
      uct_c: UCT exploration constant (> 0).
      seed: seeds the search and the rollouts; ``reset(seed)`` reseeds.
        None draws a seed from fresh entropy.
      solve: let MCTS-Solver back up proven wins/losses.
      max_memory_mb: the bot's tree memory cap.

    The move is searched once per position and episode: asking again about
    the same game (the same history) before the next ``reset`` returns the
    same move, as when the option layer re-plans a touch cut off at
    ``T_abs``, so a physical agent finishes the move it started.

    Subgoal info: ``simulations``, ``visits`` (root visits of the chosen
    action), ``value`` (its mean rollout return for the mover, in [-1, 1]),
    ``ms``.
    """

    name = "mcts"

    def __init__(
        self,
        simulations: int = 1000,
        *,
        rollouts: int = 1,
        uct_c: float = 2.0,
        seed: int | None = None,
        solve: bool = False,
        max_memory_mb: int = 1000,
    ):
        self.simulations = _check_int(simulations, "simulations", 1)
        self.rollouts = _check_int(rollouts, "rollouts", 1)
        self.uct_c = _check_real(uct_c, "uct_c")
        if self.uct_c <= 0:
            raise ValueError(f"uct_c must be a number > 0, got {uct_c!r}")
        self.max_memory_mb = _check_int(max_memory_mb, "max_memory_mb", 1)
        self.solve = bool(solve)
        if seed is not None:
            _check_int(seed, "seed", 0)
        self._seed_rng = np.random.default_rng(seed)
        self._bots: dict[str, tuple] = {}
        self._chosen: dict[tuple, Subgoal] = {}

    def reset(self, seed: int | None = None) -> None:
        self._chosen.clear()
        if seed is not None:
            _check_int(seed, "seed", 0)
            self._seed_rng = np.random.default_rng(seed)
            self._bots.clear()

    def _bot(self, game) -> pyspiel.MCTSBot:
        key = str(game)
        if key not in self._bots:
            bot_seed, rollout_seed = (int(x) for x in self._seed_rng.integers(0, 2**31 - 1, size=2))
            evaluator = pyspiel.RandomRolloutEvaluator(self.rollouts, rollout_seed)
            bot = pyspiel.MCTSBot(
                game,
                evaluator,
                self.uct_c,
                self.simulations,
                self.max_memory_mb,
                self.solve,
                bot_seed,
                False,
            )
            self._bots[key] = (bot, evaluator)  # keep the evaluator alive with the bot
        return self._bots[key][0]

    def plan(self, state) -> Subgoal:
        check_decision_state(state, self.name)
        key = (str(state.get_game()), tuple(state.history()))
        chosen = self._chosen.get(key)
        if chosen is not None:
            return Subgoal(chosen.action, state.child(chosen.action), info=dict(chosen.info))
        bot = self._bot(state.get_game())
        start = time.perf_counter()
        root = bot.mcts_search(state)
        best = root.best_child()
        ms = (time.perf_counter() - start) * 1e3
        action = int(best.action)
        visits = int(best.explore_count)
        info: dict[str, object] = {
            "simulations": self.simulations,
            "visits": visits,
            "value": float(best.total_reward) / visits if visits else 0.0,
            "ms": ms,
        }
        if self.solve and best.outcome:
            info["proven_returns"] = tuple(best.outcome)
        subgoal = Subgoal(action, state.child(action), info=info)
        self._chosen[key] = subgoal
        return subgoal

    def close(self) -> None:
        self._bots.clear()
        self._chosen.clear()

    def __repr__(self) -> str:
        return (
            f"MCTSPlanner(simulations={self.simulations}, rollouts={self.rollouts}, "
            f"uct_c={self.uct_c:g})"
        )


class AlphaBetaPlanner(Planner):
    """Depth-limited negamax alpha-beta search on a two-player zero-sum game.

    Leaves are valued by the game's returns when terminal, else 0 (no
    heuristic): exact where the depth reaches the game's end (tic-tac-toe,
    endgames), a short look-ahead elsewhere. Moves of equal value are broken
    uniformly at random with ``np.random.default_rng(seed)`` (``reset(seed)``
    reseeds), so the planner is not predictable. Wins found sooner score
    higher (values shrink by 1e-3 per ply).

    Args:
      depth: plies searched (>= 1).
      seed: the tie-breaking seed.

    Subgoal info: ``value`` (the chosen move's value for the mover, about
    -1..1), ``nodes`` (states visited), ``ms``.

    Raises (from plan): ValueError for a terminal state, a chance or
    simultaneous node, or a game that is not two-player zero-sum.
    """

    name = "alphabeta"

    def __init__(self, depth: int = 4, *, seed: int | None = None):
        self.depth = _check_int(depth, "depth", 1)
        self._rng = np.random.default_rng(seed)
        self._nodes = 0

    def reset(self, seed: int | None = None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed)

    def _negamax(self, state, depth: int, alpha: float, beta: float) -> float:
        """Value of non-terminal ``state`` for its player to move."""
        self._nodes += 1
        if depth == 0:
            return 0.0
        best = -math.inf
        for action in state.legal_actions():
            child = state.child(action)
            value = self._child_value(state, child, depth, alpha, beta)
            if value > best:
                best = value
            alpha = max(alpha, value)
            if alpha >= beta:
                break
        return best

    def _child_value(self, state, child, depth, alpha, beta) -> float:
        """Value of ``child`` for the player to move in ``state`` (players
        may move twice in a row, e.g. checkers' jumps)."""
        mover = state.current_player()
        if child.is_terminal():
            self._nodes += 1
            return float(child.returns()[mover])
        if child.current_player() == mover:
            value = self._negamax(child, depth - 1, alpha, beta)
        else:
            value = -self._negamax(child, depth - 1, -beta, -alpha)
        return value * (1.0 - 1e-3)

    def plan(self, state) -> Subgoal:
        check_decision_state(state, self.name)
        game_type = state.get_game().get_type()
        if (
            state.get_game().num_players() != 2
            or game_type.utility != pyspiel.GameType.Utility.ZERO_SUM
        ):
            raise ValueError(
                f"{self.name} plans two-player zero-sum games, got {game_type.short_name!r}"
            )
        start = time.perf_counter()
        self._nodes = 0
        values = {}
        for action in state.legal_actions():
            # A full window per root move, so every tie is exact.
            values[int(action)] = self._child_value(
                state, state.child(action), self.depth, -math.inf, math.inf
            )
        best = max(values.values())
        tied = sorted(a for a, v in values.items() if v >= best - 1e-12)
        action = tied[int(self._rng.integers(len(tied)))]
        info = {"value": best, "nodes": self._nodes, "ms": (time.perf_counter() - start) * 1e3}
        return Subgoal(action, state.child(action), info=info)

    def __repr__(self) -> str:
        return f"AlphaBetaPlanner(depth={self.depth})"


#: The forms `make_bot` accepts.
BOT_FORMS = ("mcts[:SIMULATIONS]", "alphabeta[:DEPTH]", "random")


def make_bot(spec: str, seed: int | None = None) -> Planner:
    """A planner from its name: ``"mcts:100"`` (MCTS with 100 simulations;
    ``"mcts"``: 1000), ``"alphabeta:4"`` (depth 4; ``"alphabeta"``: 4) or
    ``"random"``; seeded with ``seed``.

    Raises:
      ValueError: an unknown name or a bad number.
    """
    if not isinstance(spec, str):
        raise ValueError(f"a bot is named by a string ({', '.join(BOT_FORMS)}), got {spec!r}")
    name, _, arg = spec.partition(":")
    if name == "random" and not arg:
        return RandomMovePlanner(seed=seed)
    if name in ("mcts", "alphabeta"):
        if arg:
            try:
                number = int(arg)
            except ValueError:
                raise ValueError(f"{spec!r}: {arg!r} is not an integer") from None
        else:
            number = 1000 if name == "mcts" else 4
        if name == "mcts":
            return MCTSPlanner(number, seed=seed)
        return AlphaBetaPlanner(number, seed=seed)
    raise ValueError(f"unknown bot {spec!r}; known: {', '.join(BOT_FORMS)}")
