"""How long a body takes to carry out a Sokoban plan: features and a linear model.

A plan's execution time on the physical task (MuJoBan's rolling ball) is
not its number of pushes. `plan_features` counts what the ball skill spends
time on, from the plan's move letters alone:

* ``walk``: walking moves (cells rolled without a box);
* ``push``: pushing moves (cells a box is pushed);
* ``stroke``: pushing strokes: maximal runs of pushes of one box in one
  direction (the ball meets the box, pushes, and lets it settle once per
  stroke);
* ``turn``: changes of direction between consecutive walking moves or from
  a walk into a push (corners the ball rounds).

`estimate_steps` is a linear model of control steps, ``weights @ features``
plus a constant per level; `DEFAULT_WEIGHTS` were fitted (non-negative least
squares, `fit_weights`) on measured episodes of the ball skill
(``benchmarks/execution_time.py``, see that module's docstring for which).
"""

from __future__ import annotations

from typing import Iterable, Mapping, Sequence

import numpy as np

from abstract_planners.sokoban import DIRECTIONS, SokobanState

__all__ = ["FEATURES", "DEFAULT_WEIGHTS", "plan_features", "estimate_steps", "fit_weights"]

FEATURES = ("walk", "push", "stroke", "turn")
#: Control steps (0.05 s) per feature, and a constant per level ("start").
#: Refitted (`fit_weights`) on the 195 solved levels of the first 100 of the
#: shipped ``medium-valid-000.txt`` and ``unfiltered-valid-000.txt`` with pegs,
#: played by the ball skill with chained pushes (camera estimator, the time
#: planner with the previous weights; ``results/execution_time_*.json``):
#: R^2 0.99, mean |error| 14 steps. (The first fit, on the skill before
#: chaining: walk 4.75, push 13.3, stroke 19.6, turn 5.1.)
DEFAULT_WEIGHTS: Mapping[str, float] = {
    "start": 0.0,
    "walk": 6.44,
    "push": 12.18,
    "stroke": 13.52,
    "turn": 1.57,
}


def plan_features(state: SokobanState, moves: Sequence[str]) -> dict[str, int]:
    """The time features of playing ``moves`` from ``state`` (see the module
    docstring). Raises ValueError on an illegal move."""
    counts = dict.fromkeys(FEATURES, 0)
    previous, pushed_box, push_dir = None, None, None  # the last move, the box it pushed
    for k, move in enumerate(moves):
        if move not in DIRECTIONS or not state.is_legal(move):
            raise ValueError(f"move {k} ({move!r}) is illegal from player at {state.player}")
        dr, dc = DIRECTIONS[move]
        if state.is_push(move):
            box = (state.player[0] + dr, state.player[1] + dc)
            counts["push"] += 1
            if not (box == pushed_box and move == push_dir):
                counts["stroke"] += 1  # not the previous move's push, carried on
            if previous is not None and previous != move and box != pushed_box:
                counts["turn"] += 1
            pushed_box, push_dir = (box[0] + dr, box[1] + dc), move
        else:
            counts["walk"] += 1
            if previous is not None and previous != move:
                counts["turn"] += 1
            pushed_box = push_dir = None
        previous = move
        state = state.apply(move)
    return counts


def estimate_steps(
    features: Mapping[str, float], weights: Mapping[str, float] = DEFAULT_WEIGHTS
) -> float:
    """Estimated control steps: ``start`` plus each feature times its weight."""
    return float(
        weights.get("start", 0.0) + sum(weights[name] * features[name] for name in FEATURES)
    )


def fit_weights(features: Iterable[Mapping[str, float]], steps: Iterable[float]) -> dict:
    """Non-negative least-squares weights (with ``start``) of measured steps."""
    from scipy.optimize import nnls

    rows = [[1.0] + [float(f[name]) for name in FEATURES] for f in features]
    a, b = np.asarray(rows), np.asarray(list(steps), float)
    if len(a) < len(FEATURES) + 1:
        raise ValueError(f"need at least {len(FEATURES) + 1} measured plans, got {len(a)}")
    coef, _ = nnls(a, b)
    return {"start": float(coef[0]), **{n: float(c) for n, c in zip(FEATURES, coef[1:])}}
