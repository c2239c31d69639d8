"""Our modular agent playing the *original* MuJoXO and MuJoGo (DeepMind's
``physics_planning_games.board_games``).

The original is built from DeepMind's ``deepmind-research`` repository (see
``../shared/peer/setup.sh``: its ``physics_planning_games`` folder in
``/tmp/peer``) and imported from ``PYTHONPATH``; nothing of it ships with
this project. Its tasks are used as they are: its ``TicTacToe`` against its
``TicTacToeOptimalOpponent`` (minimax, no random moves) and its 7x7 ``Go``
against its ``GoGTPOpponent`` (GNU Go at its default strength, random moves
at ``--go-random``, default 0: the paper's; the original's registered
``go_7x7`` uses 0.2), with its own physics (2 ms steps, 0.05 s control
steps), touch rules, arm reset, looks (4 samples per pixel, shadows) and
referee. The agent always plays the original's player 0 (crosses; black),
which moves first. The original has no time limit; episodes here last ours
(``--xo-time-limit`` 30 s, ``--go-time-limit`` 45 s); a game still running
then is reported as ``unfinished``.

The agent is the default observation-only modular agent with the camera
estimator (`hier_agents.modular.components.make_agent`), unchanged. It is
told the original task's public description (`original_description`, read
from the original's model and constants: points, pads, pass area, board,
the camera ``front_2`` and the Jaco arm as the original builds them) and
sees only the observations our agent reads, renamed (`Adapter`): the
camera ``front_camera_2`` (128x128, rendered when read, as our estimator
asks of ours), the arm and hand joints as ``arm/joints_pos`` and
``arm/joints_vel`` (the original gives the six arm joints as sine/cosine
pairs: decoded to angles as a joint encoder counts turns), the pinch site
and ``agent_player`` (0). The original's ``board_state``, ``move_history``,
``markers/position`` and torques never reach the agent; ``board_state`` is
read only to judge the estimate.

    PYTHONPATH=/tmp/peer python benchmarks/original_boards.py --shadows both \
        --shadowed-games 5 --json results/original_boards.json
    PYTHONPATH=/tmp/peer python benchmarks/original_boards.py --game xo --xo-games 5

Per game: the outcome by the original's referee (its reward at the game's
end: 1 win, 0.5 draw, 0 loss), control steps, the share of the agent's
estimates whose board equals the original's ``board_state``, and seconds.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Mapping
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import cli, described_camera, make_parser, prog, write_json  # noqa: E402

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from envs.boards.games import BoardGame  # noqa: E402
from envs.description import ArmDescription, BoardDescription  # noqa: E402
from hier_agents.modular.components import make_agent  # noqa: E402
from hier_agents.stats import wilson_interval  # noqa: E402

PROG = prog(__file__)

#: The camera our board estimator reads, and its frame size (height, width).
CAMERA = "front_camera_2"
FRAME = (128, 128)
#: The original's name of that camera in its arena (the same pose as ours).
ORIGINAL_CAMERA = "front_2"
#: Our environment name whose default agent plays each game.
AGENT_ENV = {"xo": "mujoxo/optimal", "go": "mujogo/7x7"}
#: The agent's player: the original's ``SELF`` (0, moves first).
AGENT_PLAYER = 0
#: Observation keys our agent receives (`Adapter`); everything else is withheld.
AGENT_KEYS = (
    CAMERA,
    "arm/joints_pos",
    "arm/joints_vel",
    "arm/pinch_site_pos",
    "arm/pinch_site_rmat",
    "agent_player",
)
#: A decoded continuous joint moving more than this (rad) in one control step
#: was teleported by the original's arm reset (velocity limits allow ~0.04).
TELEPORT = 0.5


def _import_original():
    """The original's modules; `cli.UsageError` when it is not importable."""
    try:
        from dm_control import composer
        from physics_planning_games.board_games import (
            go,
            go_logic,
            jaco_arm_board_game,
            tic_tac_toe,
            tic_tac_toe_logic,
        )
        from physics_planning_games.board_games._internal import observations
    except ImportError as exc:
        raise cli.UsageError(
            f"the original physics_planning_games is not importable ({exc}); "
            f"build it with ../shared/peer/setup.sh and run with "
            f"PYTHONPATH=/tmp/peer"
        ) from None
    return {
        "composer": composer,
        "go": go,
        "go_logic": go_logic,
        "board_game": jaco_arm_board_game,
        "tic_tac_toe": tic_tac_toe,
        "tic_tac_toe_logic": tic_tac_toe_logic,
        "observations": observations,
    }


def original_env(
    game: str, seed: int, time_limit: float, go_random: float = 0.0, shadows: bool = True
):
    """The original task as a composer environment.

    Args:
      game: ``"xo"`` (its ``TicTacToe`` against ``TicTacToeOptimalOpponent``)
        or ``"go"`` (its 7x7 ``Go`` against ``GoGTPOpponent``, random moves
        at rate ``go_random``).
      seed: the environment's random state (arm resets, the opponent's ties
        and jitter).
      time_limit: seconds per episode.
      shadows: False switches off the shadows the original's light casts (a
        deviation from the original, to measure their effect).

    Its observations are the original's with cameras at `FRAME`; the
    ``front_camera`` observable is off and ``front_camera_2`` is rendered on
    demand by `Adapter` (through the original's own observable). Close it
    with `close_env` (Go starts a GNU Go process).
    """
    mods = _import_original()
    obs = mods["observations"]
    camera = obs.PERFECT_FEATURES.camera._replace(height=FRAME[0], width=FRAME[1])
    settings = obs.PERFECT_FEATURES._replace(camera=camera)
    if game == "xo":
        task = mods["tic_tac_toe"].TicTacToe(
            settings, opponent=mods["tic_tac_toe_logic"].TicTacToeOptimalOpponent()
        )
    elif game == "go":
        opponent = mods["go_logic"].GoGTPOpponent(board_size=7, mixture_p=float(go_random))
        task = mods["go"].Go(board_size=7, observation_settings=settings, opponent=opponent)
    else:
        raise ValueError(f"game must be 'xo' or 'go', got {game!r}")
    if not shadows:
        for light in task.root_entity.mjcf_model.find_all("light"):
            light.castshadow = False
    arena = task.root_entity.observables
    arena.front_camera.enabled = False
    arena.front_camera_2.enabled = False  # rendered when read (Adapter)
    return mods["composer"].Environment(
        task,
        time_limit=float(time_limit),
        random_state=seed,
        strip_singleton_obs_buffer_dim=True,
    )


def close_env(env) -> None:
    """Closes an `original_env` and ends the GNU Go process its Go task started."""
    logic = env.task._game_logic  # pylint: disable=protected-access
    engine = getattr(logic, "get_gtp_player", None)
    if engine is not None:
        process = engine().p
        if process.poll() is None:
            try:
                process.stdin.close()
                process.wait(timeout=5)
            except Exception:  # noqa: BLE001 - a stuck engine is ended below
                process.kill()
                process.wait()
    env.close()


def _arm_description(env) -> ArmDescription:
    """The arm's own model as the original builds it: dm_control's Jaco arm
    and hand with their default names, the base at the original's
    ``_ARM_Y_OFFSET`` along y; action bounds from the original's spec."""
    from dm_control import mjcf
    from dm_control.entities.manipulators import kinova

    board_game = _import_original()["board_game"]
    offset = (0.0, float(board_game._ARM_Y_OFFSET), 0.0)  # pylint: disable=protected-access
    root = mjcf.RootElement(model="jaco")
    arm, hand = kinova.JacoArm(), kinova.JacoHand()
    arm.attach(hand)
    root.attach(arm.mjcf_model).pos = offset
    names = tuple(j.full_identifier for j in list(arm.joints) + list(hand.joints))
    task = env.task
    original = tuple(j.full_identifier for j in list(task.arm.joints) + list(task.hand.joints))
    if names != original:
        raise RuntimeError(f"the arm's joints {names} are not the original's {original}")
    spec = env.action_spec()
    return ArmDescription(
        xml=root.to_xml_string(),
        assets=root.get_assets(),
        joint_names=names,
        pinch_site=hand.pinch_site.full_identifier,
        tool_center_point=hand.tool_center_point.full_identifier,
        base_position=offset,
        action_minimum=tuple(float(v) for v in spec.minimum),
        action_maximum=tuple(float(v) for v in spec.maximum),
    )


def original_description(env, time_limit: float) -> BoardDescription:
    """The public `BoardDescription` of an `original_env`, read from the
    original's compiled model and constants (not from ours): each point is
    its touch sensor site's centre (on the board's top), ``pad_half`` the
    site's half-size, Go's pass areas the parts of its pass geom left and
    right of the board, the komi its referee's (OpenSpiel's state), the
    cameras its ``front`` and ``front_2``, the arm `_arm_description`, the
    light casting shadows (if one does).
    ``time_limit``: the episode's seconds."""
    physics, task = env.physics, env.task
    board = task._board  # pylint: disable=protected-access
    sensors = board._touch_sensors  # (rows, cols)  # pylint: disable=protected-access
    rows, cols = sensors.shape
    sites = physics.bind([s.site for s in sensors.ravel()])
    points = np.asarray(sites.xpos, float)
    pad_half = float(sites.size[0][0])
    logic = task._game_logic  # pylint: disable=protected-access
    is_go = hasattr(logic, "get_gtp_player")
    spiel_game = logic.open_spiel_state.get_game()
    squares = physics.bind(list(board._geoms.ravel()))  # pylint: disable=protected-access
    zones: dict = {}
    if is_go:
        wood = physics.bind(board.mjcf_model.find("geom", "goboard"))
        centre = np.asarray(wood.xpos, float)[:2]
        half = float(wood.size[0])
        pass_geom = physics.bind(board._pass_geom)  # pylint: disable=protected-access
        px, py, pz = (float(v) for v in pass_geom.xpos)
        sx, sy, sz = (float(v) for v in pass_geom.size)
        for side, sign in (("left", -1.0), ("right", 1.0)):
            zones[side] = {
                "centre": (px + sign * 0.5 * (half + sx), py, pz + sz),
                "half": (0.5 * (sx - half), sy),
            }
    else:
        centre = np.asarray(squares.xpos, float)[:, :2].mean(axis=0)
        half = float(np.max(np.abs(np.asarray(squares.xpos)[:, :2] - centre)) + squares.size[0][0])
    arena = task.root_entity
    marker = physics.bind(task._markers.markers[0][0])  # pylint: disable=protected-access
    model = physics.model
    casting = [i for i in range(model.nlight) if model.light_castshadow[i]]
    control = float(task.control_timestep)
    return BoardDescription(
        game="go" if is_go else "tic_tac_toe",
        board_size=int(rows),
        komi=float(spiel_game.get_parameters().get("komi", 0.0)) if is_go else 0.0,
        num_points=int(rows * cols),
        pass_action=int(rows * cols) if is_go else None,
        point_positions=tuple(tuple(float(v) for v in p) for p in points),
        pad_half=pad_half,
        pass_zones=zones,
        board_centre=(float(centre[0]), float(centre[1])),
        board_half=half,
        # Go checks a finger geom (knuckle or tip) touches the square; tic-tac-toe any contact.
        registering="fingers" if is_go else "arm",
        control_timestep=control,
        time_limit_steps=int(round(time_limit / control)),
        arm=_arm_description(env),
        front_camera=described_camera(physics, arena.front_camera, "front_camera", None),
        front_camera_2=described_camera(physics, arena.front_camera_2, CAMERA, FRAME),
        rows=int(rows),
        cols=int(cols),
        input="point",
        agent_player=AGENT_PLAYER,
        # The original ignores the agent's pass right after its own pass.
        allow_double_pass=not is_go,
        piece_radius=float(marker.size[0]),
        # The agent's marker lands where it touched, the opponent's within the pad.
        piece_spread=pad_half,
        # The light that casts the arm's shadow on the board, if shadows are on.
        shadow_light=tuple(float(v) for v in physics.data.light_xpos[casting[0]])
        if casting
        else None,
    )


class _Frames(Mapping):
    """A timestep's observations for the agent; the camera frame is rendered
    (by the original's own observable) on first read and only while
    ``adapter`` has not stepped since."""

    def __init__(self, values: dict, adapter: "Adapter", stamp: int):
        self._values, self._adapter, self._stamp = values, adapter, stamp

    def __getitem__(self, key):
        if key == CAMERA and key not in self._values:
            if self._adapter.stamp != self._stamp:
                raise RuntimeError("a frame read after the environment stepped on")
            self._values[key] = self._adapter.render()
        return self._values[key]

    def __iter__(self):
        return iter(AGENT_KEYS)

    def __len__(self) -> int:
        return len(AGENT_KEYS)


class Adapter:
    """Turns an `original_env`'s timesteps into what our agent reads.

    ``adapt(raw, steps)`` returns the timestep with only `AGENT_KEYS`:
    ``arm/joints_pos`` (9: the six arm joints, decoded from the original's
    (sine, cosine) pairs, then the three fingers), ``arm/joints_vel`` (9),
    ``arm/pinch_site_pos``/``rmat`` (the hand's), ``agent_player`` [0] and
    the lazily rendered `CAMERA`. A joint limited to a range within one
    turn gets its angle in that range; a continuous joint the angle nearest
    its previous one, or in [0, 2 pi) (as the original's IK leaves it)
    after a teleport (`TELEPORT`) or at the first step. A last timestep
    before the time limit (the game ended) gets discount 0, as dm_env
    marks a termination (composer gives 1 there too).
    """

    def __init__(self, env, description: BoardDescription):
        self.env = env
        model = description.arm.model()
        ids = [model.joint(name).id for name in description.arm.joint_names[:6]]
        self._limited = model.jnt_limited[ids].astype(bool)
        self._range = model.jnt_range[ids].copy()
        self._limit = description.time_limit_steps
        self._camera = env.task.root_entity.observables.front_camera_2
        self._previous: np.ndarray | None = None
        self.stamp = 0

    def reset(self) -> None:
        """Forgets the joints (call at each episode's start)."""
        self._previous = None

    def render(self) -> np.ndarray:
        """The current `CAMERA` frame, as the original's observable renders it."""
        render = self._camera.observation_callable(self.env.physics, self.env.random_state)
        return np.asarray(render(), np.uint8)

    def joints(self, sin_cos) -> np.ndarray:
        """The six arm joint angles (rad) from (6, 2) (sine, cosine) pairs."""
        sc = np.asarray(sin_cos, float)
        angle = np.mod(np.arctan2(sc[:, 0], sc[:, 1]), 2 * math.pi)
        lo, hi = self._range[:, 0], self._range[:, 1]
        for k in (-1.0, 1.0):  # a limited joint's angle within its range
            shifted = angle + k * 2 * math.pi
            fix = self._limited & ((angle < lo) | (angle > hi)) & (shifted >= lo) & (shifted <= hi)
            angle = np.where(fix, shifted, angle)
        prev = self._previous
        if prev is not None:
            near = prev + (np.mod(angle - prev + math.pi, 2 * math.pi) - math.pi)
            moved = np.abs(near - prev)
            angle = np.where(~self._limited & (moved <= TELEPORT), near, angle)
        self._previous = angle
        return angle

    def adapt(self, raw, steps: int):
        """The agent's timestep for the original's ``raw`` after ``steps`` control steps."""
        self.stamp += 1
        o = raw.observation
        hand = "jaco_arm/jaco_hand/"
        values = {
            "arm/joints_pos": np.r_[
                self.joints(o["jaco_arm/joints_pos"]), np.asarray(o[hand + "joints_pos"], float)
            ],
            "arm/joints_vel": np.r_[
                np.asarray(o["jaco_arm/joints_vel"], float),
                np.asarray(o[hand + "joints_vel"], float),
            ],
            "arm/pinch_site_pos": np.asarray(o[hand + "pinch_site_pos"], float),
            "arm/pinch_site_rmat": np.asarray(o[hand + "pinch_site_rmat"], float),
            "agent_player": np.array([AGENT_PLAYER], np.int32),
        }
        timestep = raw._replace(observation=_Frames(values, self, self.stamp))
        if raw.last() and steps < self._limit:
            timestep = timestep._replace(discount=0.0)
        return timestep


def true_players(board_state) -> np.ndarray:
    """(num_points,) -1 empty, else the player (0, 1) holding each point, from
    the original's ``board_state`` (planes: empty, player 0, player 1[, Go's
    komi plane])."""
    planes = np.asarray(board_state, bool)
    out = np.full(planes.shape[0] * planes.shape[1], -1, np.int8)
    out[planes[..., 1].ravel()] = 0
    out[planes[..., 2].ravel()] = 1
    return out


def _outcome(env, last) -> str:
    """The original's referee: at its game's end, its reward says who won."""
    if not env.task.should_terminate_episode(env.physics):
        return "unfinished"
    return {1.0: "win", 0.5: "draw", 0.0: "loss"}[float(last.reward)]


def play(
    game: str,
    games: int,
    seed: int,
    time_limit: float,
    go_random: float = 0.0,
    progress: bool = True,
    shadows: bool = True,
) -> dict:
    """Our default camera agent plays ``games`` games of the original ``game``
    (``"xo"`` or ``"go"``); returns the settings, one row per game and the
    summary (outcome counts and Wilson intervals)."""
    env = original_env(game, seed, time_limit, go_random, shadows)
    rows = []
    bar = tqdm(
        total=games,
        unit="game",
        desc=f"original {game} shadows={shadows}",
        file=sys.stderr,
        disable=not progress,
    )
    agent = None
    try:
        raw = env.reset()
        description = original_description(env, time_limit)
        judge = BoardGame.from_description(description)
        adapter = Adapter(env, description)
        agent = make_agent(AGENT_ENV[game], description, estimator="camera", seed=seed)
        for index in range(games):
            start = time.perf_counter()
            if index:
                raw = env.reset()
            adapter.reset()
            steps = 0
            timestep = adapter.adapt(raw, steps)
            agent.reset(description, timestep, seed=seed * 100_003 + index)
            reason, right, judged, final_right = None, 0, 0, None
            try:
                while not timestep.last():
                    action = agent.act(timestep)
                    if agent.scene is not None:  # the agent's estimate of this timestep
                        judged += 1
                        right += bool(
                            np.array_equal(
                                judge.players(agent.scene.state),
                                true_players(raw.observation["board_state"]),
                            )
                        )
                    if agent.gave_up is not None:
                        reason = agent.gave_up
                        break
                    raw = env.step(action)
                    steps += 1
                    timestep = adapter.adapt(raw, steps)
                if timestep.last():
                    agent.end_episode(timestep)
                    # The estimate of the last frame (the agent does not act on it).
                    final = agent.estimator.estimate(timestep)
                    final_right = bool(
                        np.array_equal(
                            judge.players(final.state),
                            true_players(raw.observation["board_state"]),
                        )
                    )
                outcome = _outcome(env, raw) if timestep.last() else "gave up"
            except Exception as exc:  # noqa: BLE001 - an error ends the game, not the run
                outcome, reason = "error", f"{type(exc).__name__}: {exc}"
            true = true_players(raw.observation["board_state"])
            row = {
                "game": index,
                "outcome": outcome,
                "steps": steps,
                "moves": int(np.count_nonzero(true >= 0)),
                "estimates": judged,
                "estimates_right": right,
                "final_estimate_right": final_right,
                "wall_s": round(time.perf_counter() - start, 2),
            }
            if reason:
                row["failure_reason"] = reason
            rows.append(row)
            bar.update(1)
            bar.set_postfix({k[0]: sum(r["outcome"] == k for r in rows) for k in _OUTCOMES[:3]})
    finally:
        bar.close()
        if agent is not None:
            agent.close()
        close_env(env)
    return {
        "game": game,
        "original_task": _TASKS[game].format(go_random=go_random),
        "agent_env": AGENT_ENV[game],
        "agent_player": f"{AGENT_PLAYER} ({'crosses' if game == 'xo' else 'black'}, moves first)",
        "time_limit_s": time_limit,
        "shadows": shadows,
        "seed": seed,
        "summary": summarise(rows),
        "rows": rows,
    }


_OUTCOMES = ("win", "draw", "loss", "unfinished", "gave up", "error")
_TASKS = {
    "xo": "tic_tac_toe.TicTacToe(opponent=TicTacToeOptimalOpponent())",
    "go": "go.Go(board_size=7, opponent=GoGTPOpponent(board_size=7, mixture_p={go_random}))",
}


def summarise(rows) -> dict:
    """Counts of each outcome, the win, loss (a loss, or a game not won nor
    drawn) and not-lost rates with 95% Wilson intervals, the share of
    estimates right, mean steps and seconds per game."""
    n = len(rows)
    counts = {k: sum(r["outcome"] == k for r in rows) for k in _OUTCOMES}
    wins, draws = counts["win"], counts["draw"]
    not_lost = wins + draws
    judged = sum(r["estimates"] for r in rows)
    finals = [r["final_estimate_right"] for r in rows if r["final_estimate_right"] is not None]
    return {
        "games": n,
        **counts,
        "win_rate": wins / n if n else float("nan"),
        "win_interval": list(wilson_interval(wins, n)),
        "not_won_nor_drawn": n - not_lost,
        "not_lost_rate": not_lost / n if n else float("nan"),
        "not_lost_interval": list(wilson_interval(not_lost, n)),
        "estimates": judged,
        "estimate_board_accuracy": sum(r["estimates_right"] for r in rows) / max(judged, 1),
        "final_estimates_right": f"{sum(finals)}/{len(finals)}",
        "mean_steps": float(np.mean([r["steps"] for r in rows])) if rows else float("nan"),
        "mean_wall_s": float(np.mean([r["wall_s"] for r in rows])) if rows else float("nan"),
    }


def _main(argv=None) -> int:
    parser = make_parser(__file__, __doc__)
    parser.add_argument(
        "--game", choices=("both", "xo", "go"), default="both", help="which original to play"
    )
    parser.add_argument("--xo-games", type=cli.positive_int, default=50, help="MuJoXO games")
    parser.add_argument("--go-games", type=cli.positive_int, default=20, help="MuJoGo games")
    parser.add_argument(
        "--xo-time-limit", type=cli.positive_float, default=30.0, help="MuJoXO seconds per game"
    )
    parser.add_argument(
        "--go-time-limit", type=cli.positive_float, default=45.0, help="MuJoGo seconds per game"
    )
    parser.add_argument(
        "--go-random",
        type=cli.fraction,
        default=0.0,
        help="GNU Go's rate of random moves (the original's mixture_p; its go_7x7 has 0.2)",
    )
    parser.add_argument(
        "--shadows",
        choices=("yes", "no", "both"),
        default="yes",
        help="keep the shadows the original's light casts (yes: the original as it is), "
        "switch them off (no: a deviation, to measure their effect), or play both",
    )
    parser.add_argument(
        "--shadowed-games",
        type=cli.positive_int,
        help="at most this many games of each with shadows (their misread games run long)",
    )
    parser.add_argument("--seed", type=cli.non_negative_int, default=0)
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)
    cli.output_file(args.json, "--json")
    _import_original()
    plan = {"both": ("xo", "go"), "xo": ("xo",), "go": ("go",)}[args.game]
    out = {
        "agent": "modular: camera estimator + default planner + arm skill (unchanged)",
        "privileged": False,
        "frame_shape": list(FRAME),
        "camera": f"the original's {ORIGINAL_CAMERA!r} as {CAMERA!r}",
        "runs": [],
    }
    shadows = {"yes": (True,), "no": (False,), "both": (False, True)}[args.shadows]
    for shade in shadows:
        for game in plan:
            games = args.xo_games if game == "xo" else args.go_games
            if shade and args.shadowed_games:
                games = min(games, args.shadowed_games)
            limit = args.xo_time_limit if game == "xo" else args.go_time_limit
            out["runs"].append(play(game, games, args.seed, limit, args.go_random, shadows=shade))
    print(
        f"{'game':>4} {'shadows':>7} {'games':>5} {'win':>4} {'draw':>4} {'loss':>4} {'other':>5} "
        f"{'win rate [95%]':>22} {'not lost [95%]':>22} {'read right':>10} "
        f"{'steps':>6} {'s/game':>6}"
    )
    for run in out["runs"]:
        s = run["summary"]
        other = s["games"] - s["win"] - s["draw"] - s["loss"]
        print(
            f"{run['game']:>4} {str(run['shadows']):>7} {s['games']:>5} "
            f"{s['win']:>4} {s['draw']:>4} {s['loss']:>4} "
            f"{other:>5} {_rate(s['win_rate'], s['win_interval']):>22} "
            f"{_rate(s['not_lost_rate'], s['not_lost_interval']):>22} "
            f"{100 * s['estimate_board_accuracy']:>9.1f}% {s['mean_steps']:>6.0f} "
            f"{s['mean_wall_s']:>6.1f}"
        )
    if args.json:
        write_json(args.json, out)
    return 0


def _rate(rate: float, interval) -> str:
    low, high = interval
    return f"{100 * rate:5.1f}% [{100 * low:5.1f}, {100 * high:5.1f}]"


def main(argv=None) -> int:
    """Plays the originals, prints the table, writes ``--json``; bad input or
    a missing original: one line on stderr, exit status 2, before anything
    is played."""
    return cli.run_main(PROG, _main, argv)


if __name__ == "__main__":
    sys.exit(main())
