"""What differs between game families, in one adapter per family.

The option runner, the modular agent and the semi-MDP environment are
written once; the few things that depend on the kind of abstract state live
here:

=========================  ==========================  ==========================
                           `SokobanAdapter` (mujoban)  `BoardAdapter` (mujoxo,
                                                       mujogo, mujoboard)
=========================  ==========================  ==========================
abstract state             `SokobanState`              an OpenSpiel state
subgoal of a planner       ``next_push`` (walk, then   ``plan`` (one move)
                           push) when offered
nothing left to plan       the level is solved (hold,  never (the episode ends)
                           centring a box left short)
option done at the end     the estimated boxes equal   the skill decides (the
of the episode             the subgoal's               game record)
deviation                  the boxes left the          none (the skill sees a
                           subgoal's path              different move)
option-env actions         the four moves ``MOVES``    OpenSpiel's distinct
                                                       actions
option-env observation     ``(4, H, W)`` planes:       OpenSpiel's observation
                           walls, pads, boxes, player  tensor for the mover
scored by (`score`)        solved or not               win / draw / loss (games)
compared by (`metric`,     success: 1 solved, 0 not    game score: 1 win, 1/2 draw,
`episode_score`)                                       0 loss
harness judges the agent's never                       every step: its board and
estimate                                               mover against the referee's
level files, learned       yes (``level_files``)       no
option-policy planners
end-to-end inputs          proprioception of the       the arm's proprioception;
                           walker; abstract state:     abstract state: the board
                           the entity layer, 4 planes  planes; planner targets:
                           of the grid; planner        the board after the move
                           targets: the entity layer   (6 planes)
                           after the move (8 planes)
                           and a one-hot move
auxiliary target reached   the simulator's rounded     the agent's next registered
(`subgoal_reached`)        cells hold the target's     move is the target's (another
                           player and boxes            move ends the sub-episode)
discounts (env, abs)       0.99, 0.9                   0.99, 0.98
=========================  ==========================  ==========================

The episode runner (`hier_agents.agents.runner`) scores every agent's
episodes through `FamilyAdapter.score`, and comparisons
(`hier_agents.compare.report`) turn each row into a number through
`FamilyAdapter.episode_score`; the end-to-end agents'
(`hier_agents.baselines.impala.inputs`) inputs and auxiliary task read the
family's part of this table from its adapter.

`family(env_name)` names an environment's family; `adapter(family)` returns
its adapter. Every OpenSpiel game played by touch (`envs.boards.games`)
reuses `BoardAdapter`; a new kind of task adds one adapter here.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from abstract_planners.base import Subgoal

__all__ = [
    "FAMILIES",
    "family",
    "adapter",
    "env_adapter",
    "FamilyAdapter",
    "SokobanAdapter",
    "BoardAdapter",
    "encode_sokoban",
    "TIME_LIMIT_REASON",
]

#: An episode row's ``failure_reason`` when nothing ended it before the time
#: limit (a level unsolved, a game still running).
TIME_LIMIT_REASON = "time limit"

_PLAYER, _BOX = 2, 3  # full_entity_layer channels (envs.mujoban.task)


class FamilyAdapter:
    """The family-specific rules (module docstring). Stateless."""

    name = ""
    #: Episodes are games against an opponent, scored win / draw / loss;
    #: otherwise puzzles, scored solved or not.
    games = False
    #: Levels can come from a file (``--levels``) and policies over options
    #: can plan (``learned:PATH`` planners).
    level_files = False

    # -- the option runner and the agent --------------------------------------

    def expected(self, state, subgoal) -> object | None:
        """What the deviation check compares against (None: no check)."""
        return None

    def deviates(self, expected, scene) -> bool:
        """True when ``scene`` is off the subgoal's way."""
        return False

    def done_at_end(self, subgoal, scene) -> bool:
        """True when the episode's last ``scene`` shows the subgoal done."""
        return False

    def idle(self, state) -> bool:
        """True when nothing is left to plan (the agent holds still)."""
        return False

    def next_subgoal(self, planner, state, description=None) -> Subgoal:
        """The planner's next subgoal from ``state`` (``description``: the
        task's public description, for rules the planner does not know)."""
        return planner.plan(state)

    # -- the semi-MDP environment ---------------------------------------------

    def spaces(self, description, state) -> tuple[gym.spaces.Discrete, gym.spaces.Space]:
        """(action space: one action per option, observation space) of the
        option environment."""
        raise NotImplementedError

    def option_subgoal(self, state, action: int) -> Subgoal | None:
        """The subgoal of option ``action`` from ``state``; None if illegal."""
        raise NotImplementedError

    def legal_mask(self, state, n: int | np.integer) -> np.ndarray:
        """int8 per action: 1 where the option is legal."""
        raise NotImplementedError

    def observation(self, state, space) -> np.ndarray:
        """The option environment's observation of ``state``."""
        raise NotImplementedError

    # -- scoring an episode (the episode runner) --------------------------------

    def score(self, task, timestep, reason: str | None) -> dict:
        """The verdict keys of an episode's row, from the referee (``task``):
        ``timestep`` is the episode's last one (None when it never started);
        ``reason`` why the agent stopped early (None: it played to the end).
        MuJoBan: ``solved``; board games: ``outcome``, ``final_reward`` and
        ``opponent_resigned`` (when true); both add ``failure_reason`` for an
        episode that is not a success."""
        raise NotImplementedError

    def success(self, task) -> bool:
        """Whether the referee's episode so far is a success (a solved level,
        a won game)."""
        raise NotImplementedError

    def estimate_right(self, task, scene) -> bool:
        """The harness's per-step judgement of an estimating agent's ``scene``
        against the referee (``task``), for the families that judge one
        (``games``)."""
        raise NotImplementedError

    # -- comparing agents over episodes (`hier_agents.compare.report`) ---------

    #: The comparison's per-episode metric (`episode_score`), as its tables say it.
    metric = "success"
    #: What `metric` counts, one clause (the comparison's JSON).
    metric_definition = "100 x the share of episodes that succeeded"
    #: The tables' and the plot's heading of the metric, in percent.
    metric_heading = "success %"
    #: Every episode scores 0 or 1 (a binomial proportion: Wilson intervals apply).
    binary_metric = True

    def episode_score(self, row: dict) -> float:
        """An episode row's (`score`) value in [0, 1] for comparisons: here
        1.0 for a success (``solved``, else a won game), 0.0 otherwise."""
        return float(bool(row["solved"]) if "solved" in row else row.get("outcome") == "win")

    def outcome_shares(self, rows) -> dict | None:
        """The shares of ``rows`` won, drawn and lost (``{"win", "draw",
        "loss"}`` -> fraction, summing to 1) for families whose episodes are
        games; None otherwise."""
        return None

    # -- the end-to-end agents' inputs and auxiliary task ---------------------

    #: The paper's (gamma_env, gamma_abs).
    discounts: tuple[float, float] = (0.99, 0.9)
    #: Proprioceptive observations concatenated into ``"proprio"``, in order.
    proprio_keys: tuple[str, ...] = ()
    #: The observation holding the current abstract state (``state=True``).
    state_key = ""
    #: The estimator of the auxiliary task's abstract state (ground truth).
    truth_estimator = ""
    #: The expert-planner condition's planner (None: the family's default).
    expert_planner: str | None = None
    #: The paper's batch size (unrolls per update).
    paper_batch = 64

    def planner_inputs(self, task) -> tuple[tuple[int, int, int], int]:
        """(shape of the ``"planner"`` planes, size of the ``"planner_action"``
        one-hot, 0 when there is none) of the planner conditions."""
        raise NotImplementedError

    def fill_planner_inputs(
        self, planes: np.ndarray, onehot: np.ndarray, observation, subgoal, task
    ) -> None:
        """Writes the current abstract state (from ``observation``) and the
        target (``subgoal``, None: none, the target planes repeat the current
        ones) into ``planes`` and ``onehot`` in place."""
        raise NotImplementedError

    def at_rest(self, state) -> bool:
        """Whether no target can be planned from ``state`` (solved, game over)."""
        raise NotImplementedError

    def subepisode_mark(self, task):
        """What a sub-episode of the auxiliary task remembers at its start."""
        raise NotImplementedError

    def subgoal_reached(self, task, subgoal, mark) -> tuple[bool, bool]:
        """(target reached, sub-episode over for another reason) after a
        step, judged on the referee's ground truth (``task``) since ``mark``
        (`subepisode_mark`); ``subgoal`` None: no target (over once the
        abstract state changes)."""
        raise NotImplementedError


def encode_sokoban(state, shape) -> np.ndarray:
    """A Sokoban state as ``(4, H, W)`` float32 planes: walls, pads, boxes, player."""
    height, width = shape
    planes = np.zeros((4, height, width), np.float32)
    for k, cells in enumerate((state.walls, state.targets, state.boxes, (state.player,))):
        for r, c in cells:
            if 0 <= r < height and 0 <= c < width:
                planes[k, r, c] = 1.0
    return planes


class SokobanAdapter(FamilyAdapter):
    """MuJoBan: Sokoban states (module docstring)."""

    name = "mujoban"
    level_files = True

    def expected(self, state, subgoal) -> frozenset | None:
        """Box placements the subgoal's moves pass through (where the walker is
        between cells is the skill's business, so only boxes are checked)."""
        moves = subgoal.action if isinstance(subgoal.action, tuple) else (subgoal.action,)
        states = [state]
        for move in moves:
            states.append(states[-1].apply(move))
        return frozenset(s.boxes for s in states)

    def deviates(self, expected, scene) -> bool:
        return scene.state.boxes not in expected

    def done_at_end(self, subgoal, scene) -> bool:
        # The last push put the boxes where the subgoal wanted them (the
        # walker may still be rolling; where no longer matters).
        return scene.state.boxes == subgoal.state.boxes

    def idle(self, state) -> bool:
        return bool(state.is_solved())

    def next_subgoal(self, planner, state, description=None) -> Subgoal:
        if hasattr(planner, "next_push"):
            return planner.next_push(state)
        return planner.plan(state)

    def spaces(self, description, state):
        from abstract_planners.sokoban import MOVES

        shape = tuple(int(v) for v in description.grid_shape)
        return (gym.spaces.Discrete(len(MOVES)), gym.spaces.Box(0.0, 1.0, (4, *shape), np.float32))

    def option_subgoal(self, state, action: int) -> Subgoal | None:
        from abstract_planners.sokoban import MOVES

        move = MOVES[action]
        if not state.is_legal(move):
            return None
        return Subgoal(action=(move,), state=state.apply(move), plan=())

    def legal_mask(self, state, n: int | np.integer) -> np.ndarray:
        from abstract_planners.sokoban import MOVES

        return np.array([state.is_legal(m) for m in MOVES], np.int8)

    def observation(self, state, space) -> np.ndarray:
        return encode_sokoban(state, space.shape[1:])

    def score(self, task, timestep, reason: str | None) -> dict:
        # (after a failed reset the task still shows the last episode's end)
        solved = timestep is not None and bool(getattr(task, "solved", False))
        return (
            {"solved": True}
            if solved
            else {"solved": False, "failure_reason": reason or TIME_LIMIT_REASON}
        )

    def success(self, task) -> bool:
        return bool(task.solved)

    metric_definition = "100 x the share of episodes solved"

    def episode_score(self, row: dict) -> float:
        """1.0 for a solved level, 0.0 otherwise."""
        return float(bool(row["solved"]))

    discounts = (0.99, 0.9)
    proprio_keys = (
        "walker/joints_pos",
        "walker/joints_vel",
        "walker/joints_torque",
        "walker/orientation",
        "walker/sensors_touch",
        "walker/sensors_accelerometer",
        "walker/sensors_gyro",
        "walker/sensors_velocimeter",
    )
    state_key = "full_entity_layer"
    truth_estimator = "entity-layer"
    # The paper's expert: the exact Sokoban solver (not the library's
    # default, the execution-time planner).
    expert_planner = "sokoban-solver"
    paper_batch = 128

    def planner_inputs(self, task) -> tuple[tuple[int, int, int], int]:
        from abstract_planners.sokoban import MOVES

        height, width = task.grid_shape
        return (8, int(height), int(width)), len(MOVES)

    def fill_planner_inputs(self, planes, onehot, observation, subgoal, task) -> None:
        from abstract_planners.sokoban import MOVES

        half = planes.shape[0] // 2
        planes[:half] = observation["full_entity_layer"].transpose(2, 0, 1)
        planes[half:] = planes[:half]
        onehot[:] = 0.0
        if subgoal is not None:
            target = subgoal.state
            planes[half + _PLAYER] = 0.0
            planes[half + _BOX] = 0.0
            planes[half + _PLAYER][target.player] = 1.0
            for cell in target.boxes:
                planes[half + _BOX][cell] = 1.0
            onehot[MOVES.index(subgoal.action)] = 1.0

    def at_rest(self, state) -> bool:
        return bool(state.is_solved())

    def subepisode_mark(self, task):
        return task.abstract_cells

    def subgoal_reached(self, task, subgoal, mark) -> tuple[bool, bool]:
        cells, player = task.abstract_cells
        if subgoal is None:  # no target: try again once the abstract state changes
            return False, (cells, player) != mark
        target = subgoal.state
        return (player == target.player and frozenset(cells) == target.boxes), False


class BoardAdapter(FamilyAdapter):
    """Board games (MuJoXO, MuJoGo, MuJoBoard): OpenSpiel states; options
    are the actions of the player to move (the agent, when asked)."""

    games = True

    def __init__(self, name: str) -> None:
        self.name = name

    def next_subgoal(self, planner, state, description=None) -> Subgoal:
        """The planner's move, unless the task would ignore it: a pass right
        after the agent's own pass where ``description.allow_double_pass``
        is False (MuJoGo, the original's rule). Then the legal point nearest
        the board's centre (the easiest to reach) that does not fill one of
        the agent's own eyes (a point whose neighbours are all the agent's
        stones), or the legal point nearest the centre."""
        subgoal = planner.plan(state)
        pass_action = getattr(description, "pass_action", None)
        if (
            pass_action is None
            or subgoal.action != pass_action
            or getattr(description, "allow_double_pass", True)
        ):
            return subgoal
        history = state.history()
        if len(history) < 2 or history[-2] != pass_action:
            return subgoal
        centre = np.asarray(description.board_centre, float)
        points = sorted(
            (a for a in state.legal_actions() if a != pass_action),
            key=lambda a: float(
                np.linalg.norm(np.asarray(description.point_positions[a][:2]) - centre)
            ),
        )
        if not points:
            return subgoal
        from envs.boards.games import BoardGame

        game = BoardGame.from_description(description)
        players, mover = game.players(state), state.current_player()
        action = next((a for a in points if not _own_eye(game, players, mover, a)), points[0])
        info = dict(subgoal.info, replaced_pass=True)
        return Subgoal(action, state.child(action), info=info)

    def expected(self, state, subgoal) -> tuple:
        """The moves the subgoal was planned after (the estimate's record)."""
        return tuple(state.history())

    def deviates(self, expected, scene) -> bool:
        """True when the estimate has since rewritten one of those moves (an
        opponent's reply first taken for a pass, or for another move): the
        subgoal was planned on a board that was not the game's."""
        return tuple(scene.state.history()[: len(expected)]) != expected

    def spaces(self, description, state):
        game = state.get_game()
        shape = tuple(int(v) for v in game.observation_tensor_shape())
        # OpenSpiel's tic-tac-toe and Go tensors are 0/1 planes.
        return (
            gym.spaces.Discrete(int(game.num_distinct_actions())),
            gym.spaces.Box(0.0, 1.0, shape, np.float32),
        )

    def option_subgoal(self, state, action: int) -> Subgoal | None:
        if state.is_terminal() or state.current_player() < 0 or action not in state.legal_actions():
            return None
        return Subgoal(action, state.child(action))

    def legal_mask(self, state, n: int | np.integer) -> np.ndarray:
        mask = np.zeros(n, np.int8)
        if not state.is_terminal() and state.current_player() >= 0:
            mask[list(state.legal_actions())] = 1
        return mask

    def observation(self, state, space) -> np.ndarray:
        """OpenSpiel's observation tensor for the player to move (player 0's
        once the game is over)."""
        player = max(state.current_player(), 0) if not state.is_terminal() else 0
        return np.asarray(state.observation_tensor(player), np.float32).reshape(space.shape)

    def score(self, task, timestep, reason: str | None) -> dict:
        outcome = task.outcome if timestep is not None else None
        # The task's outcome counts an opponent's resignation as a win; a
        # game still running counts as lost.
        row = {
            "outcome": outcome or "loss",
            "final_reward": float(timestep.reward or 0.0) if timestep is not None else 0.0,
        }
        if timestep is not None and getattr(task, "resigned", False):
            row["opponent_resigned"] = True
        if row["outcome"] != "win" and (reason or outcome is None):
            row["failure_reason"] = reason or TIME_LIMIT_REASON
        return row

    def success(self, task) -> bool:
        return task.outcome == "win"  # a resignation by the opponent included

    # Against MuJoXO's optimal opponent nobody wins: a draw is the best
    # result, so the comparison scores games, not wins.
    metric = "game score"
    metric_definition = "100 x the mean over episodes of 1 for a win, 1/2 for a draw, 0 for a loss"
    metric_heading = "game score % (per game: win 1, draw 1/2, loss 0)"
    binary_metric = False
    #: A row's ``outcome`` -> its `episode_score`.
    OUTCOME_SCORES = {"win": 1.0, "draw": 0.5, "loss": 0.0}

    def episode_score(self, row: dict) -> float:
        """1.0 for a won game (the opponent's resignation included), 0.5 for
        a draw, 0.0 for a loss (a row without an outcome: a game that never
        finished, lost)."""
        return self.OUTCOME_SCORES.get(row.get("outcome") or "loss", 0.0)

    def outcome_shares(self, rows) -> dict | None:
        """The shares of ``rows`` won, drawn and lost, and ``unfinished``: of
        the lost, those whose game was still running at the time limit."""
        rows = list(rows)
        outcomes = [r.get("outcome") or "loss" for r in rows]
        shares = {k: outcomes.count(k) / len(rows) if rows else 0.0 for k in self.OUTCOME_SCORES}
        unfinished = sum(r.get("failure_reason") == TIME_LIMIT_REASON for r in rows)
        shares["unfinished"] = unfinished / len(rows) if rows else 0.0
        return shares

    def estimate_right(self, task, scene) -> bool:
        """Whether the agent's ``scene`` has the referee's board (every
        point's owner) and player to move."""
        if scene is None or getattr(scene, "state", None) is None:
            return False
        game, truth, state = task.game, task.state, scene.state
        return state.current_player() == truth.current_player() and np.array_equal(
            game.players(state), game.players(truth)
        )

    discounts = (0.99, 0.98)
    proprio_keys = (
        "arm/joints_pos",
        "arm/joints_vel",
        "arm/joints_torque",
        "arm/pinch_site_pos",
        "arm/pinch_site_rmat",
    )
    state_key = "board_state"
    truth_estimator = "board"
    paper_batch = 64

    def planner_inputs(self, task) -> tuple[tuple[int, int, int], int]:
        size = int(task.game.size)
        return (6, size, size), 0

    def fill_planner_inputs(self, planes, onehot, observation, subgoal, task) -> None:
        planes[:3] = observation["board_state"].transpose(2, 0, 1)
        if subgoal is None:
            planes[3:] = planes[:3]
        else:
            planes[3:] = task.game.board_planes(subgoal.state).transpose(2, 0, 1)

    def at_rest(self, state) -> bool:
        return bool(state.is_terminal())

    def subepisode_mark(self, task):
        return task.moves_registered, len(task.moves)

    def subgoal_reached(self, task, subgoal, mark) -> tuple[bool, bool]:
        """Reached when the agent's next registered move is the target's
        action (the estimated state after the step already holds the
        opponent's reply, so the task's move record is compared); any other
        move ends the sub-episode (moves are irreversible)."""
        registered, played = mark
        if task.moves_registered == registered:
            return False, False
        if subgoal is None:
            return False, True
        moves = task.moves
        reached = len(moves) > played and moves[played] == int(subgoal.action)
        return reached, not reached


def _own_eye(game, players, mover: int, point: int) -> bool:
    """Whether every orthogonal neighbour of ``point`` on ``game``'s board
    holds a stone of ``mover`` (``players``: `BoardGame.players` of the state)."""
    row, col = divmod(int(point), game.cols)
    neighbours = [
        (r, c)
        for r, c in ((row - 1, col), (row + 1, col), (row, col - 1), (row, col + 1))
        if 0 <= r < game.rows and 0 <= c < game.cols
    ]
    return all(players[r * game.cols + c] == mover for r, c in neighbours)


#: family name -> adapter.
FAMILIES: dict[str, FamilyAdapter] = {
    "mujoban": SokobanAdapter(),
    "mujoxo": BoardAdapter("mujoxo"),
    "mujogo": BoardAdapter("mujogo"),
    "mujoboard": BoardAdapter("mujoboard"),
}


def family(env_name: str) -> str:
    """The family (``"mujoban"``, ``"mujoxo"``, ``"mujogo"``, ``"mujoboard"``)
    of an environment name; ValueError for environments without a modular
    agent."""
    prefix = str(env_name).split("/", 1)[0]
    if prefix not in FAMILIES:
        raise ValueError(
            f"no modular agent for {env_name!r}; environment families: "
            + ", ".join(f"{f}/*" for f in FAMILIES)
        )
    return prefix


def adapter(name: str) -> FamilyAdapter:
    """The adapter of a family name or an environment name."""
    return FAMILIES[family(name)]


#: The adapter of tasks outside the families: no deviation or end-of-episode rule.
GENERIC = FamilyAdapter()


def env_adapter(env_name: str) -> FamilyAdapter:
    """The adapter of an environment name (`adapter`), `GENERIC` for an
    environment outside the families."""
    try:
        return adapter(env_name)
    except ValueError:
        return GENERIC


def adapter_for(description) -> FamilyAdapter:
    """The adapter for a task's public description: MuJoBan's (it has a
    grid), the board games' (a board), else `GENERIC`."""
    if hasattr(description, "grid_shape"):
        return FAMILIES["mujoban"]
    if hasattr(description, "board_size"):
        return FAMILIES[
            {"tic_tac_toe": "mujoxo", "go": "mujogo"}.get(description.game, "mujoboard")
        ]
    return GENERIC
