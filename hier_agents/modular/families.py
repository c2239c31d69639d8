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
scored by                  solved or not               win / draw / loss (games)
level files, learned       yes (``level_files``)       no
option-policy planners
=========================  ==========================  ==========================

`family(env_name)` names an environment's family; `adapter(family)` returns
its adapter. Every OpenSpiel game played by touch (`envs.boards.games`)
reuses `BoardAdapter`; a new kind of task adds one adapter here.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from abstract_planners.base import Subgoal

__all__ = ["FAMILIES", "family", "adapter", "FamilyAdapter", "SokobanAdapter",
           "BoardAdapter", "encode_sokoban"]


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

    def expected(self, state, subgoal) -> frozenset | None:
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

    def spaces(self, description, state) -> tuple[gym.spaces.Space, gym.spaces.Space]:
        """(action space, observation space) of the option environment."""
        raise NotImplementedError

    def option_subgoal(self, state, action: int) -> Subgoal | None:
        """The subgoal of option ``action`` from ``state``; None if illegal."""
        raise NotImplementedError

    def legal_mask(self, state, n: int) -> np.ndarray:
        """int8 per action: 1 where the option is legal."""
        raise NotImplementedError

    def observation(self, state, space) -> np.ndarray:
        """The option environment's observation of ``state``."""
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
        return (gym.spaces.Discrete(len(MOVES)),
                gym.spaces.Box(0.0, 1.0, (4, *shape), np.float32))

    def option_subgoal(self, state, action: int) -> Subgoal | None:
        from abstract_planners.sokoban import MOVES
        move = MOVES[action]
        if not state.is_legal(move):
            return None
        return Subgoal(action=(move,), state=state.apply(move), plan=())

    def legal_mask(self, state, n: int) -> np.ndarray:
        from abstract_planners.sokoban import MOVES
        return np.array([state.is_legal(m) for m in MOVES], np.int8)

    def observation(self, state, space) -> np.ndarray:
        return encode_sokoban(state, space.shape[1:])


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
        if (pass_action is None or subgoal.action != pass_action
                or getattr(description, "allow_double_pass", True)):
            return subgoal
        history = state.history()
        if len(history) < 2 or history[-2] != pass_action:
            return subgoal
        centre = np.asarray(description.board_centre, float)
        points = sorted((a for a in state.legal_actions() if a != pass_action),
                        key=lambda a: float(np.linalg.norm(
                            np.asarray(description.point_positions[a][:2]) - centre)))
        if not points:
            return subgoal
        from envs.boards.games import BoardGame
        game = BoardGame.from_description(description)
        players, mover = game.players(state), state.current_player()
        action = next((a for a in points if not _own_eye(game, players, mover, a)), points[0])
        info = dict(subgoal.info, replaced_pass=True)
        return Subgoal(action, state.child(action), info=info)

    def spaces(self, description, state):
        game = state.get_game()
        shape = tuple(int(v) for v in game.observation_tensor_shape())
        # OpenSpiel's tic-tac-toe and Go tensors are 0/1 planes.
        return (gym.spaces.Discrete(int(game.num_distinct_actions())),
                gym.spaces.Box(0.0, 1.0, shape, np.float32))

    def option_subgoal(self, state, action: int) -> Subgoal | None:
        if state.is_terminal() or state.current_player() < 0 \
                or action not in state.legal_actions():
            return None
        return Subgoal(action, state.child(action))

    def legal_mask(self, state, n: int) -> np.ndarray:
        mask = np.zeros(n, np.int8)
        if not state.is_terminal() and state.current_player() >= 0:
            mask[list(state.legal_actions())] = 1
        return mask

    def observation(self, state, space) -> np.ndarray:
        """OpenSpiel's observation tensor for the player to move (player 0's
        once the game is over)."""
        player = max(state.current_player(), 0) if not state.is_terminal() else 0
        return np.asarray(state.observation_tensor(player), np.float32).reshape(space.shape)


def _own_eye(game, players, mover: int, point: int) -> bool:
    """Whether every orthogonal neighbour of ``point`` on ``game``'s board
    holds a stone of ``mover`` (``players``: `BoardGame.players` of the state)."""
    row, col = divmod(int(point), game.cols)
    neighbours = [(r, c) for r, c in ((row - 1, col), (row + 1, col), (row, col - 1),
                                      (row, col + 1))
                  if 0 <= r < game.rows and 0 <= c < game.cols]
    return all(players[r * game.cols + c] == mover for r, c in neighbours)


#: family name -> adapter.
FAMILIES: dict[str, FamilyAdapter] = {"mujoban": SokobanAdapter(),
                                      "mujoxo": BoardAdapter("mujoxo"),
                                      "mujogo": BoardAdapter("mujogo"),
                                      "mujoboard": BoardAdapter("mujoboard")}


def family(env_name: str) -> str:
    """The family (``"mujoban"``, ``"mujoxo"``, ``"mujogo"``, ``"mujoboard"``)
    of an environment name; ValueError for environments without a modular
    agent."""
    prefix = str(env_name).split("/", 1)[0]
    if prefix not in FAMILIES:
        raise ValueError(f"no modular agent for {env_name!r}; environment families: "
                         + ", ".join(f"{f}/*" for f in FAMILIES))
    return prefix


def adapter(name: str) -> FamilyAdapter:
    """The adapter of a family name or an environment name."""
    return FAMILIES[family(name)]


#: The adapter of tasks outside the families: no deviation or end-of-episode rule.
GENERIC = FamilyAdapter()


def adapter_for(description) -> FamilyAdapter:
    """The adapter for a task's public description: MuJoBan's (it has a
    grid), the board games' (a board), else `GENERIC`."""
    if hasattr(description, "grid_shape"):
        return FAMILIES["mujoban"]
    if hasattr(description, "board_size"):
        return FAMILIES[{"tic_tac_toe": "mujoxo", "go": "mujogo"}.get(description.game,
                                                                       "mujoboard")]
    return GENERIC
