"""Games of MuJoXO / MuJoGo played by an abstract planner + the Jaco arm-touch skill.

    python benchmarks/arm_skill.py [--envs NAME ...] [--episodes N] [--seed S]
                                   [--t-abs T] [--abstract-games N] [--json PATH]

Each episode (one game) runs the modular agent's loop with the physical arm,
behind the observation boundary (the agent sees ``env.description()`` and
timesteps only):

1. estimate: `BoardEstimator` replays the ``move_history`` observation in
   OpenSpiel (the abstract state) and reads the arm's joint observations;
2. plan: `MinimaxPlanner` for MuJoXO, `GnuGoPlanner` (level 10, 7x7, komi
   5.5; its own engine, not the environment's opponent) for MuJoGo;
3. run `skills.arm.ArmTouchSkill` on the subgoal with the option layer's
   `run_option` until it reports success or failure or ``--t-abs`` (50)
   control steps passed, then go back to 1. The environment's opponent
   replies inside the step that registers the move. (`run_option` steps the
   skill's hold action once more on the step it sees the move registered,
   so a touch counts one step more than with the hand-written loop of
   earlier versions.)

Environments: ``mujoxo/mixture`` (minimax opponent with random moves at rate
0.25, 30 s = 600 steps, truncation at the limit), ``mujoxo/optimal``,
``mujoxo/random``, ``mujogo/7x7`` (GNU Go level 10; 45 s = 900 steps; a game
still running at the limit is lost), ``mujogo/7x7-mixture``.

Per environment the table shows: games; win, draw and loss rates with 95%
Wilson score intervals (``unfinished``: a MuJoXO game truncated at the time
limit, neither won nor lost); mean control steps per game; touches attempted
(subgoals given to the skill), touches that registered the planned move,
touches that registered another move (``wrong``), touches that failed or were
cut off otherwise; mean control steps per successful touch (and its 90th
percentile); the skill's mean milliseconds per act() and per reset(); and
wall seconds per game. For MuJoXO environments the abstract
rate is printed for comparison: the same planner against the same opponent
in OpenSpiel without physics (``--abstract-games`` games).

``--json`` writes {"rows": [...], "abstract": {...}} with, per row: env,
games, wins, draws, losses, unfinished, win_rate, win_low, win_high,
draw_rate, draw_low, draw_high, loss_rate, loss_low, loss_high,
mean_steps_per_game, touches, touches_planned, touches_wrong, touches_failed,
touches_cut, mean_steps_per_touch, p90_steps_per_touch, failures (reason ->
count), mean_act_ms (skill.act), mean_reset_ms (skill.reset: the posture
planning), mean_plan_ms (the abstract planner), wall_s_per_game.
"""

from __future__ import annotations

import math
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import env_cli, cli, make_parser, prog, write_json  # noqa: E402

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import envs  # noqa: E402
from abstract_planners.epsilon_greedy import EpsilonGreedy  # noqa: E402
from abstract_planners.go import GnuGoPlanner  # noqa: E402
from abstract_planners.tictactoe import MinimaxPlanner  # noqa: E402
from hier_agents.estimators import BoardEstimator, EstimationError  # noqa: E402
from hier_agents.modular.options import T_ABS, Outcome, run_option  # noqa: E402
from hier_agents.stats import wilson_interval  # noqa: E402
from skills.arm import ArmTouchSkill  # noqa: E402

PROG = prog(__file__)
DEFAULT_ENVS = ["mujoxo/mixture", "mujogo/7x7"]
#: Opponent epsilon of the MuJoXO environments (for the abstract comparison).
MUJOXO_EPSILON = {"mujoxo/mixture": 0.25, "mujoxo/optimal": 0.0, "mujoxo/random": 1.0}


def make_planner(name: str, seed: int):
    """The agent's planner for an environment name."""
    if name.startswith("mujoxo/"):
        return MinimaxPlanner(seed=seed)
    if name.startswith("mujogo/"):
        size = 9 if name.startswith("mujogo/9x9") else 7
        return GnuGoPlanner(10, board_size=size, komi=5.5, seed=seed)
    raise ValueError(f"unknown environment {name!r}: expected mujoxo/... or mujogo/...")


class TimedSkill:
    """A skill whose ``reset`` and ``act`` are timed (into ``stats``): what
    `run_option` needs of a skill, passed through."""

    def __init__(self, skill, stats: dict):
        self.skill, self.stats = skill, stats
        self.name = skill.name

    @property
    def status(self):
        return self.skill.status

    @property
    def failure_reason(self):
        return self.skill.failure_reason

    def reset(self, description, subgoal, scene) -> None:
        start = time.perf_counter()
        self.skill.reset(description, subgoal, scene)
        self.stats["reset_s"] += time.perf_counter() - start

    def act(self, timestep, scene):
        start = time.perf_counter()
        action = self.skill.act(timestep, scene)
        self.stats["act_s"] += time.perf_counter() - start
        self.stats["acts"] += 1
        return action

    def hold(self):
        return self.skill.hold()


def play_game(env, planner, skill, t_abs: int, stats: dict) -> dict:
    """One game with the agent loop of the module docstring; updates ``stats``."""
    description = env.description()
    estimator = BoardEstimator()
    timed = TimedSkill(skill, stats)
    timestep = env.reset()
    estimator.reset(description, timestep)
    steps = 0
    scene = None
    while not timestep.last():
        try:
            scene = estimator.estimate(timestep)
        except EstimationError:
            timestep = env.step(skill.hold())
            steps += 1
            continue
        if scene.state.is_terminal():  # cannot happen while the episode runs
            break
        start = time.perf_counter()
        subgoal = planner.plan(scene.state)
        stats["plan_s"] += time.perf_counter() - start
        stats["plans"] += 1
        stats["touches"] += 1
        result = run_option(env, estimator, timed, subgoal, timestep, t_abs=t_abs, scene=scene)
        timestep = result.timestep
        steps += result.duration
        if result.outcome is Outcome.REACHED:
            stats["planned"] += 1
            stats["touch_steps"].append(result.duration)
        elif result.outcome is Outcome.FAILED:
            reason = result.reason or "unknown"
            stats["failures"][reason.split(":")[0]] += 1
            if reason.startswith("wrong move"):
                stats["wrong"] += 1
            else:
                stats["failed"] += 1
        else:
            stats["cut"] += 1
        if result.duration == 0 and not timestep.last():
            # The skill gave up before moving (e.g. no posture found from
            # here): let time pass so the game cannot loop without steps.
            timestep = env.step(skill.hold())
            steps += 1
    try:
        state = estimator.estimate(timestep).state
    except EstimationError:
        state = scene.state if scene is not None else None
    # The harness judges with the task's outcome (an opponent's resignation
    # is a win; the agent's estimate cannot see a resignation).
    outcome = getattr(env.task, "outcome", None)
    if outcome is not None:
        result = outcome
    elif state is not None and state.is_terminal():
        value = state.returns()[0]
        result = "win" if value > 0 else "loss" if value < 0 else "draw"
    elif description.game == "go":
        result = "loss"  # MuJoGo: a game running at the time limit is lost
    else:
        result = "unfinished"
    return {"result": result, "steps": steps}


def run_env(name: str, episodes: int, seed: int, t_abs: int) -> dict:
    env = envs.load(name, seed=seed, front_camera=None)
    planner = make_planner(name, seed)
    skill = ArmTouchSkill()
    stats = {
        "touches": 0,
        "planned": 0,
        "wrong": 0,
        "failed": 0,
        "cut": 0,
        "touch_steps": [],
        "failures": Counter(),
        "plan_s": 0.0,
        "plans": 0,
        "act_s": 0.0,
        "acts": 0,
        "reset_s": 0.0,
    }
    results, game_steps = Counter(), []
    start = time.perf_counter()
    try:
        for episode in tqdm(range(episodes), desc=name, unit="game", leave=False):
            planner.reset(seed=seed * 100_003 + episode)
            game = play_game(env, planner, skill, t_abs, stats)
            results[game["result"]] += 1
            game_steps.append(game["steps"])
    finally:
        planner.close()
        env.close()
    wall = time.perf_counter() - start
    row = {
        "env": name,
        "games": episodes,
        "wins": results["win"],
        "draws": results["draw"],
        "losses": results["loss"],
        "unfinished": results["unfinished"],
    }
    for key, count in (
        ("win", results["win"]),
        ("draw", results["draw"]),
        ("loss", results["loss"]),
    ):
        low, high = wilson_interval(count, episodes)
        row.update({f"{key}_rate": count / episodes, f"{key}_low": low, f"{key}_high": high})
    touch_steps = stats["touch_steps"]
    row.update(
        {
            "mean_steps_per_game": float(np.mean(game_steps)),
            "touches": stats["touches"],
            "touches_planned": stats["planned"],
            "touches_wrong": stats["wrong"],
            "touches_failed": stats["failed"],
            "touches_cut": stats["cut"],
            "mean_steps_per_touch": float(np.mean(touch_steps)) if touch_steps else math.nan,
            "p90_steps_per_touch": float(np.percentile(touch_steps, 90))
            if touch_steps
            else math.nan,
            "failures": dict(stats["failures"]),
            "mean_act_ms": 1e3 * stats["act_s"] / max(stats["acts"], 1),
            "mean_reset_ms": 1e3 * stats["reset_s"] / max(stats["touches"], 1),
            "mean_plan_ms": 1e3 * stats["plan_s"] / max(stats["plans"], 1),
            "wall_s_per_game": wall / episodes,
        }
    )
    return row


def abstract_rates(epsilon: float, games: int, seed: int) -> dict:
    """Minimax (player 0) against EpsilonGreedy(minimax, epsilon) in OpenSpiel."""
    import pyspiel

    game = pyspiel.load_game("tic_tac_toe")
    agent = MinimaxPlanner(seed=seed)
    opponent = EpsilonGreedy(MinimaxPlanner(), epsilon, seed=seed + 1)
    counts = Counter()
    for index in range(games):
        agent.reset(seed=seed * 7919 + index)
        opponent.reset(seed=seed * 104_729 + index)
        state = game.new_initial_state()
        while not state.is_terminal():
            mover = agent if state.current_player() == 0 else opponent
            state.apply_action(mover.plan(state).action)
        value = state.returns()[0]
        counts["win" if value > 0 else "loss" if value < 0 else "draw"] += 1
    out = {"epsilon": epsilon, "games": games}
    for key in ("win", "draw", "loss"):
        low, high = wilson_interval(counts[key], games)
        out.update({f"{key}_rate": counts[key] / games, f"{key}_low": low, f"{key}_high": high})
    return out


def _rate(row: dict, key: str) -> str:
    rate, low, high = (100 * row[f"{key}_{part}"] for part in ("rate", "low", "high"))
    return f"{rate:5.1f} [{low:.0f},{high:.0f}]"


def format_table(rows: list[dict]) -> str:
    head = (
        f"{'env':16} {'games':>5} {'win % [95% CI]':>16} {'draw %':>16} {'loss %':>16} "
        f"{'unfin':>5} {'steps/game':>10} {'touches':>7} {'planned':>7} {'wrong':>5} "
        f"{'failed':>6} {'cut':>4} {'steps/touch':>11} {'p90':>4} {'ms/act':>6} "
        f"{'ms/reset':>8} {'s/game':>6}"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r['env']:16} {r['games']:5d} {_rate(r, 'win'):>16} {_rate(r, 'draw'):>16} "
            f"{_rate(r, 'loss'):>16} {r['unfinished']:5d} {r['mean_steps_per_game']:10.1f} "
            f"{r['touches']:7d} {r['touches_planned']:7d} {r['touches_wrong']:5d} "
            f"{r['touches_failed']:6d} {r['touches_cut']:4d} {r['mean_steps_per_touch']:11.1f} "
            f"{r['p90_steps_per_touch']:4.0f} {r['mean_act_ms']:6.2f} {r['mean_reset_ms']:8.1f} "
            f"{r['wall_s_per_game']:6.1f}"
        )
        if r["failures"]:
            lines.append(f"{'':16}   skill failures: {r['failures']}")
    return "\n".join(lines)


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--envs",
        nargs="+",
        default=DEFAULT_ENVS,
        metavar="NAME",
        help="MuJoXO / MuJoGo environments",
    )
    parser.add_argument(
        "--episodes", type=cli.positive_int, default=20, help="games per environment"
    )
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument(
        "--t-abs",
        type=cli.positive_int,
        default=T_ABS,
        help="control steps a touch may take before re-planning",
    )
    parser.add_argument(
        "--abstract-games",
        type=cli.non_negative_int,
        default=20_000,
        help="games for the abstract (no physics) MuJoXO rates (0: none)",
    )
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    boards = [n for n in envs.names() if n.startswith(("mujoxo/", "mujogo/"))]
    for name in args.envs:
        env_cli.environment(name, boards)
    cli.output_file(args.json, "--json")
    rows = [run_env(name, args.episodes, args.seed, args.t_abs) for name in args.envs]
    print(format_table(rows))
    abstract = {}
    for name in args.envs:
        if name in MUJOXO_EPSILON and args.abstract_games > 0:
            rates = abstract_rates(MUJOXO_EPSILON[name], args.abstract_games, args.seed)
            abstract[name] = rates
            print(
                f"abstract minimax vs {name} (epsilon {rates['epsilon']:g}, no physics, "
                f"{rates['games']} games): win {_rate(rates, 'win')}  "
                f"draw {_rate(rates, 'draw')}  loss {_rate(rates, 'loss')}"
            )
    if args.json:
        write_json(args.json, {"rows": rows, "abstract": abstract})
    return 0


def main(argv=None) -> int:
    """Plays, prints the table, writes ``--json``; bad input: one line on
    stderr, exit status 2."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
