"""The board games' camera estimator (`hier_agents.estimators.camera_board`):
what it reads of a frame, the arm's silhouette, and the game it keeps, judged
against the referee (which it never reads)."""

from __future__ import annotations

import numpy as np
import pytest

import envs
from fast_cover import cover, family_and_game
from arm_driving import central_action, lift, touch_point
from envs.boards.mujoboard import REGISTERED
from hier_agents.boundary import BoundaryEnv
from hier_agents.estimators.board_view import UNSEEN, BoardView
from hier_agents.estimators.camera_board import CAMERA, FRAME_EVERY, BoardCameraEstimator
from hier_agents.modular.components import ESTIMATORS, env_overrides, reads_record
from envs.boards.games import BoardGame

BOARDS = [f"mujoboard/{name}" for name, _, _ in REGISTERED] + ["mujogo/7x7"]


def _env(name, **kwargs):
    """The environment as the camera estimator asks for it, seen through the
    boundary that removes everything the task declares privileged."""
    env = envs.load(name, seed=2, **{**env_overrides(name, "camera"), **kwargs})
    return env, BoundaryEnv(env, strip=env.privileged_observations)


def _right(env, scene) -> bool:
    game, truth = env.task.game, env.task.state
    return scene.state.current_player() == truth.current_player() and np.array_equal(
        game.players(scene.state), game.players(truth)
    )


def test_the_camera_estimator_needs_no_record_and_asks_for_its_camera():
    assert not reads_record("mujoboard", "camera") and reads_record("mujoboard", "board")
    assert all("camera" in ESTIMATORS[family] for family in ("mujoxo", "mujogo", "mujoboard"))
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="frame_every"):
            BoardCameraEstimator(frame_every=bad)
    with pytest.raises(TypeError, match="still"):
        BoardCameraEstimator(still=1)
    overrides = env_overrides("mujoboard/hex-7x7", "camera")
    assert overrides[CAMERA] == (128, 128) and overrides["front_camera"] is None
    env, view = _env("mujoboard/hex-7x7")
    obs = view.reset().observation
    assert not {"board_state", "move_history"} & set(obs) and CAMERA in obs
    env.close()


@pytest.mark.parametrize(
    "name, player",
    cover(
        [
            pytest.param(name, player, id=f"{name}-{side}")
            for name in ["mujoxo/optimal", *BOARDS]
            for player, side in ((0, "first"), (1, "second"))
        ],
        lambda name, player: [*family_and_game(name), ("player", player)],
    ),
)
def test_the_first_frame_reads_as_the_referees_board(name, player, request):
    """Every cell read (not under the arm, not unsure) is the referee's, most
    cells are read, and the first estimate is the referee's game: as second
    player it already holds the opponent's first move (othello's and the
    move games' initial pieces are drawn from the first frame)."""
    if name.startswith("mujogo"):  # the opponent is GNU Go
        request.getfixturevalue("gnugo")
    env, view = _env(
        name,
        agent_player=player,
        **({"opponent": "random"} if name.startswith("mujoboard") else {}),
    )
    timestep = view.reset()
    description = view.description()
    estimator = BoardCameraEstimator()
    estimator.reset(description, timestep)
    cells, hidden = estimator.read(timestep)
    truth = env.task.game.players(env.task.state)
    seen = cells != UNSEEN
    assert seen.mean() > 0.7, f"only {seen.sum()} of {len(cells)} cells read"
    np.testing.assert_array_equal(cells[seen], truth[seen])
    scene = estimator.estimate(timestep)
    assert len(env.task.moves) >= player and _right(env, scene)
    assert scene.agent == player and scene.moves == tuple(env.task.state.history())
    env.close()


def test_mujoxo_markers_anywhere_on_their_pad_are_read_from_the_first_frame():
    """MuJoXO's markers are small (half a half-spacing) and land anywhere on
    their touch pad, so they may miss the disc around their point: its cells
    are read over their whole square. As second player the first frame
    already holds the opponent's marker, which must not be learnt as the
    empty board, even when the arm hides all but one other cell of its
    colour (seeds 5, 29, 59, 71 and 94 here)."""
    assert not BoardView(*_view_args("mujoboard/othello-8x8")).square
    seeds = sorted(set(range(0, 100, 4)) | {5, 29, 59, 71, 94})
    wrong, read, markers = [], 0, 0
    env = envs.load("mujoxo/optimal", agent_player=1, **env_overrides("mujoxo/optimal", "camera"))
    view = BoundaryEnv(env, strip=env.privileged_observations)
    try:
        for seed in seeds:
            env.seed(seed)  # the episode of an environment built with this seed
            timestep = view.reset()
            estimator = BoardCameraEstimator()
            estimator.reset(view.description(), timestep)
            assert estimator._view.square
            cells, _ = estimator.read(timestep)
            truth = env.task.game.players(env.task.state)
            seen = cells != UNSEEN
            read, markers = read + seen.sum(), markers + seen[truth >= 0].sum()
            if not np.array_equal(cells[seen], truth[seen]):
                wrong.append(seed)
    finally:
        env.close()
    assert not wrong, f"first frames read wrong for seeds {wrong}"
    assert read > 0.7 * 9 * len(seeds) and markers > 0.8 * len(seeds)


def test_only_a_checkerboard_has_two_parities():
    """Cells stand in for each other by parity (`BoardView.parity`): two on
    a checkerboard (its squares' two colours), one on wood and plain tiles."""
    for name, checker in (
        ("mujoboard/breakthrough-6x6", True),
        ("mujoboard/gomoku-9x9", False),
        ("mujoboard/othello-8x8", False),
    ):
        parity = BoardView(*_view_args(name)).parity
        assert set(parity.tolist()) == ({0, 1} if checker else {0}), name


def _first_frame(name, episode, **options):
    """(env, first timestep, estimator reset on it) of episode ``episode`` of
    seed 0 of ``name`` as the camera estimator asks for it, with
    ``options``, seen through the boundary."""
    env = envs.load(name, seed=0, **{**env_overrides(name, "camera"), **options})
    view = BoundaryEnv(env, strip=env.privileged_observations)
    env.seed(0, episode=episode)
    timestep = view.reset()
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), timestep)
    return env, timestep, estimator


def test_an_edge_row_darker_than_the_rest_is_learnt_from_the_first_frame():
    """Gomoku, the opponent first (episode 0 of seed 0): the light leaves the
    last row darker than the others and the arm hides half of it. Its cells
    are checked against their own row, not the board's (one wood colour:
    no parities), so they are learnt, and the first estimate is the
    referee's game (it was not, all game long, when they were checked
    against the whole board's brighter cells of their parity)."""
    env, timestep, estimator = _first_frame("mujoboard/gomoku-9x9", 0, agent_player=1)
    try:
        last_row = np.arange(72, 81)
        cells, _ = estimator.read(timestep)
        assert (cells[last_row] != UNSEEN).sum() >= 4  # the arm hides the rest
        assert _right(env, estimator.estimate(timestep))
    finally:
        env.close()


def test_under_the_originals_light_a_dark_square_is_not_lent_a_light_ones_colour():
    """MuJoXO at the original's looks (shadows, 4 samples), episode 12 of
    seed 0: at the first frame the arm and its shadow leave only cells 2, 3
    and 6 of the empty board to learn. Dark cell 0 lacks samples only light
    cell 3 has; lent its white, cell 0's own grey read as an O and the game
    was lost. Lent its pattern on cell 0's colour, the first frame reads as
    the referee's empty board."""
    env, timestep, estimator = _first_frame("mujoxo/optimal", 12, shadows=True, multisamples=4)
    try:
        cells, _ = estimator.read(timestep)
        truth = env.task.game.players(env.task.state)
        seen = cells != UNSEEN
        np.testing.assert_array_equal(cells[seen], truth[seen])
        assert _right(env, estimator.estimate(timestep))
    finally:
        env.close()


def test_a_board_full_of_see_through_pieces_is_read_with_either_colour_anywhere():
    """Clobber starts with a piece on every point, so no empty cell shows
    the board: its colour as the pieces' colour model sees it is taken
    through the first frame's pieces. Every cell in view is then read right
    with the colours swapped (each parity held one colour) and without
    pieces."""
    env, view = _env("mujoboard/clobber-5x6", opponent="random")
    timestep = view.reset()
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), timestep)
    assert np.isnan(estimator._colours.background).all()  # no empty cell to learn from
    truth = env.task.game.players(env.task.state)
    still = np.zeros(env.action_spec().shape)
    pieces = [env.physics.bind(piece) for piece in env.task.arena.pieces]
    colours = env.task.arena.colours
    for piece, player in zip(pieces, truth):
        piece.rgba = colours[1 - player]
    cells, hidden = estimator.read(view.step(still))
    np.testing.assert_array_equal(cells[~hidden], 1 - truth[~hidden])
    for piece in pieces:
        piece.rgba[3] = 0.0
    cells, hidden = estimator.read(view.step(still))
    assert (cells[~hidden] == -1).all(), cells
    env.close()


def _view_args(name):
    env = envs.load(name, **env_overrides(name, "camera"))
    description = env.description()
    env.close()
    return description, BoardGame.from_description(description), description.front_camera_2


def test_the_arm_hides_the_cells_under_the_hand():
    """With the fingertips pressed on a point, that point's cell is hidden
    (its own model, posed at the observed joints, projected into the frame)."""
    env, view = _env("mujoboard/gomoku-9x9", opponent="random")
    view.reset()
    description = view.description()
    board = BoardView(
        description, BoardGame.from_description(description), description.front_camera_2
    )
    point = 4 * 9 + 4
    target = description.point_position(point)

    def pressing():
        tool = env.task.pinch_site_position()
        return np.linalg.norm(tool[:2] - target[:2]) < 0.01 and tool[2] < target[2] + 0.03

    timestep = touch_point(env, target, until=pressing)
    assert pressing()
    obs = timestep.observation
    hidden = board.silhouette.hidden(obs["arm/joints_pos"], board.centres, board.radius)
    assert hidden[point] and hidden.sum() < len(hidden) // 2
    env.close()


def _hidden_outline_by_outline(silhouette, qpos, centres, radius, part):
    """`ArmSilhouette.hidden`'s definition, one outline at a time."""
    radius = np.broadcast_to(np.asarray(radius, float), (len(centres),))
    hidden = np.zeros(len(centres), bool)
    for poly in silhouette.outlines(qpos, part):
        a = poly[:, ::-1]
        edge = np.roll(a, -1, axis=0) - a
        normal = np.stack([edge[:, 1], -edge[:, 0]], axis=1)
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-9)
        dist = ((centres[:, None, ::-1] - a[None]) * normal[None]).sum(-1).max(axis=1)
        hidden |= dist < radius
    return hidden


@pytest.mark.parametrize("name, shadows", [("mujoxo/optimal", True), ("mujogo/7x7", False)])
def test_hidden_is_every_outline_within_a_discs_radius(name, shadows):
    """The cells and samples hidden in arm postures around the start, against
    the definition computed outline by outline (every part, radii of both
    signs)."""
    env, view = _env(name, shadows=shadows)
    timestep = view.reset()
    description = view.description()
    board = BoardView(
        description, BoardGame.from_description(description), description.front_camera_2
    )
    silhouette, samples = board.silhouette, board.sample_px.reshape(-1, 2)
    rng = np.random.default_rng(0)
    start = timestep.observation["arm/joints_pos"]
    some = False
    for _ in range(6):
        qpos = start + rng.normal(0.0, 0.4, start.shape)
        for centres, radius in [(board.centres, board.radius), (samples, 2.5), (samples, -2.5)]:
            for part in ("all", "arm", "shadow"):
                hidden = silhouette.hidden(qpos, centres, radius, part)
                expected = _hidden_outline_by_outline(silhouette, qpos, centres, radius, part)
                np.testing.assert_array_equal(hidden, expected)
                some |= bool(hidden.any()) and not hidden.all()
    assert some  # the postures hide some discs, not all
    env.close()


def test_under_a_light_that_casts_shadows_the_arms_shadow_hides_cells_too():
    """MuJoXO with the original's shadows: the description names the light,
    and the cells the arm's shadow falls on (the light straight above the
    board, the shadow under the arm) are hidden as well as those under it."""
    from hier_agents.estimators.arm_silhouette import ArmSilhouette

    env, view = _env("mujoxo/optimal", shadows=True)
    timestep = view.reset()
    description = view.description()
    assert description.shadow_light is not None
    plain_env, plain_view = _env("mujoxo/optimal")
    assert plain_view.description().shadow_light is None
    plain_env.close()
    board = BoardView(
        description, BoardGame.from_description(description), description.front_camera_2
    )
    qpos = timestep.observation["arm/joints_pos"]
    plain = ArmSilhouette(description.arm, description.front_camera_2, board.shape)
    shaded = board.silhouette.hidden(qpos, board.centres, board.radius)
    assert len(board.silhouette.outlines(qpos)) > len(plain.outlines(qpos))
    assert np.all(shaded >= plain.hidden(qpos, board.centres, board.radius))
    # A point on the board straight below the light, in line with a geom:
    # the shadow's centre is drawn where the light casts that geom.
    geom, casting = board.silhouette._shadow(
        np.array([[0.0, 0.0, 0.5], [0.01, 0.0, 0.5], [0.0, 0.01, 0.5]])
    )
    assert casting.all()
    np.testing.assert_allclose(geom[:, 2], board.silhouette.plane_z)
    np.testing.assert_allclose(geom[0, :2], [0.0, 0.0])
    env.close()


@pytest.mark.parametrize("name", ["mujoxo/optimal", "mujoboard/othello-8x8"])
def test_under_shadows_the_cells_in_the_arms_shadow_are_read_too(name):
    """At the original's looks (a light casting shadows, 4 samples per
    pixel) the share of light the arm's shadow leaves is measured on the
    first frame's empty cells under it; cells in the shadow are then read,
    and read right, as are pieces, which shade the board they show through
    (the opponent's first piece; othello's four)."""
    extra = {"opponent": "random"} if name.startswith("mujoboard") else {}
    env = envs.load(
        name,
        agent_player=1,
        shadows=True,
        multisamples=4,
        **extra,
        **env_overrides(name, "camera"),
    )
    view = BoundaryEnv(env, strip=env.privileged_observations)
    seeds = range(0, 40, 4)
    shaded, pieces = 0, 0
    try:
        for seed in seeds:
            env.seed(seed)
            timestep = view.reset()
            estimator = BoardCameraEstimator()
            estimator.reset(view.description(), timestep)
            assert estimator._colours.shade is not None and 0.3 < estimator._colours.shade < 0.9
            cells, _ = estimator.read(timestep)
            obs = timestep.observation
            unshaded, _, _, _ = estimator._view.read(
                obs[CAMERA], obs["arm/joints_pos"], estimator._colours.filled()
            )
            truth = env.task.game.players(env.task.state)
            seen = cells != UNSEEN
            np.testing.assert_array_equal(cells[seen], truth[seen], err_msg=f"seed {seed}")
            shaded += int((seen & (unshaded == UNSEEN)).sum())
            pieces += int((seen & (truth >= 0)).sum())
    finally:
        env.close()
    assert shaded >= len(seeds) and pieces >= len(seeds), (shaded, pieces)


@pytest.mark.parametrize(
    "name", ["mujoboard/hex-7x7", "mujoboard/othello-8x8", "mujoboard/breakthrough-6x6"]
)
def test_touched_moves_and_replies_are_found_among_the_continuations(name):
    """Three moves touched with the arm (a move game's as piece, then
    destination, the selection seen in between), each answered by the
    opponent: after each, the estimate is the referee's board and player to
    move, from camera frames and joints only."""
    env, view = _env(name, opponent="random")
    task = env.task
    timestep = view.reset()
    # Called once a turn here: read each time.
    estimator = BoardCameraEstimator(frame_every=1, still=False)
    estimator.reset(view.description(), timestep)
    for turn in range(3):
        if task.state.is_terminal():
            break
        action = central_action(task)
        zones = task.game.touches(task.state, action)
        if len(zones) == 2:
            touch_point(
                env,
                task.point_position(zones[0]),
                until=lambda zone=zones[0]: task._selected == zone,
            )
            timestep = touch_point(env, task.point_position(zones[0]) + (0, 0, 0.1), steps=20)
            assert estimator.estimate(timestep).selected == zones[0], f"turn {turn}"
        before = len(task.moves)
        for _ in range(3):  # a touch from an awkward arm pose may miss: again
            touch_point(env, task.point_position(zones[-1]))
            if len(task.moves) > before:
                break
        assert task.moves[before] == action
        timestep = view.step(np.zeros(view.action_spec().shape))
        scene = estimator.estimate(timestep)
        assert _right(env, scene), f"turn {turn}: {scene.moves} != {task.moves}"
        assert scene.selected == -1
    env.close()


def _counting_reads(estimator):
    """Wraps the estimator's view: returns a list that gets one entry per frame read."""
    real, reads = estimator._view, []

    def read(*args):
        reads.append(1)
        return type(real).read(real, *args)

    real.read = read
    return reads


@pytest.mark.parametrize("still", [True, False])
def test_a_confirmed_board_of_a_point_game_is_not_read_until_a_move_registers(still):
    """Connect four, agent first: once the estimate is confirmed, steps that
    cannot change the board (no arm reset, no refused press) read no frame
    (every `FRAME_EVERY`-th step with ``still=False``) and keep the
    referee's board; the step of the arm reset after a touched move reads
    one and holds the move and the reply."""
    env, view = _env("mujoboard/connect_four", opponent="random")
    task = env.task
    timestep = view.reset()
    estimator = BoardCameraEstimator(still=still)
    estimator.reset(view.description(), timestep)
    reads = _counting_reads(estimator)
    idle = np.zeros(view.action_spec().shape)
    for _ in range(2 * FRAME_EVERY):
        assert _right(env, estimator.estimate(view.step(idle)))
    # The first estimate reads; the still board is then read only as scheduled.
    assert len(reads) == (1 if still else 2), len(reads)
    action = central_action(task)
    timestep = touch_point(env, task.point_position(task.game.touches(task.state, action)[-1]))
    assert tuple(task.moves[:1]) == (action,)
    before = len(reads)
    scene = estimator.estimate(view.step(idle))
    assert len(reads) == before + 1 and _right(env, scene) and len(scene.moves) == 2
    env.close()


def test_a_move_registered_without_an_arm_reset_is_read_while_the_hand_is_low():
    """Connect four with no arm reset: the hand stays where it touched, so
    no joint jump tells of the move; frames are read while the hand is low
    over the board (not at every step), and once it rises the estimate is
    the referee's game."""
    env, view = _env("mujoboard/connect_four", opponent="random", arm_reset=False)
    task = env.task
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), view.reset())
    reads = _counting_reads(estimator)
    step, scenes = env.step, []

    def estimated_step(action):
        timestep = step(action)
        scenes.append(estimator.estimate(timestep))
        return timestep

    env.step = estimated_step
    action = central_action(task)
    touch_point(env, task.point_position(task.game.touches(task.state, action)[-1]))
    assert tuple(task.moves[:1]) == (action,) and len(task.moves) == 2
    assert 0 < len(reads) < len(scenes)
    lift(env)  # the reply may lie under the hand until it rises (a press held may play again)
    assert _right(env, scenes[-1]) and len(scenes[-1].moves) >= 2
    env.close()


def test_a_move_game_reads_frames_between_moves_for_the_selection():
    """Breakthrough: a touch can select a piece with no arm reset, so a
    confirmed board is still read every `FRAME_EVERY` steps."""
    env, view = _env("mujoboard/breakthrough-6x6", opponent="random")
    timestep = view.reset()
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), timestep)
    reads = _counting_reads(estimator)
    idle = np.zeros(view.action_spec().shape)
    for _ in range(2 * FRAME_EVERY):
        assert _right(env, estimator.estimate(view.step(idle)))
    assert len(reads) == 2, len(reads)
    env.close()


def test_the_last_move_under_the_hand_is_found_when_the_game_ends():
    """A game that ends on the agent's touch: the piece may still be under the
    hand in the last frame, and the estimate must still be the finished game."""
    env, view = _env("mujoboard/connect_four", opponent="random")
    timestep = view.reset()
    task = env.task
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), timestep)
    # Play the agent's pieces straight into column 3 by the referee's own hand,
    # the opponent answering in column 0, until one touch wins.
    for _ in range(3):
        task._apply(3, piece_xy=None)
        task._apply(0, piece_xy=None, rng=np.random.default_rng(0))
    timestep = view.step(np.zeros(view.action_spec().shape))
    estimator.estimate(timestep)
    timestep = touch_point(env, task.point_position(3 * 7 + 3))
    assert timestep.last() and task.state.is_terminal()
    scene = estimator.estimate(timestep)
    assert scene.state.is_terminal() and _right(env, scene)
    env.close()


def test_a_stone_first_taken_for_a_pass_is_found_when_seen(request):
    """Go: the agent's stone under the hand and the opponent's reply in view
    are first explained as the agent's pass and the reply (nothing contradicts
    it); once the stone shows, the estimate has it."""
    request.getfixturevalue("gnugo")
    env, view = _env("mujogo/7x7")
    timestep = view.reset()
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), timestep)
    game = BoardGame.from_description(view.description())
    n = game.num_points
    mine, reply = 24, 25
    truth = np.full(n, -1, np.int8)
    truth[[mine, reply]] = [0, 1]
    shares = np.stack([truth == 0, truth == 1], axis=1).astype(float)
    hidden = np.zeros(n, bool)
    hidden[mine] = True
    cells = np.where(hidden, UNSEEN, truth).astype(np.int8)
    first = estimator._explain(cells, np.where(hidden[:, None], np.nan, shares), over=False)
    assert first.history() == [game.pass_action, reply]  # nothing contradicts it
    second = estimator._explain(truth.copy(), shares, over=False)
    # The stone in view: the board and the player to move are the game's again
    # (the history may keep the pass, the opponent's pass answering the stone).
    np.testing.assert_array_equal(game.players(second), truth)
    assert second.current_player() == 0
    env.close()


def test_the_touched_move_is_looked_for_after_the_unconfirmed_estimate(request):
    """Go: the agent's stone A stays hidden by the arm at rest, so the
    estimate [A, B] runs unconfirmed ahead of the last anchor (the empty
    board). The agent then touches C, the arm resets and D replies, C hidden
    too: the touch played C after [A, B], not at the anchor, so the estimate
    is [A, B, C, D], not [A, B, pass, D] (which changes fewer hidden cells)."""
    request.getfixturevalue("gnugo")
    env, view = _env("mujogo/7x7")
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), view.reset())
    game = BoardGame.from_description(view.description())
    a, b, c, d = 24, 25, 10, 40
    estimator._register(a)
    cells, shares = _frame(game, {a: 0, b: 1}, hidden=[a])
    estimator._belief = estimator._explain(cells, shares, over=False)
    assert estimator._belief.history() == [a, b]
    assert [s.history() for s in estimator._anchors] == [[]]  # A was never seen
    assert game.zone_effects(estimator._belief, -1)[0][c] == c
    estimator._register(c)
    cells, shares = _frame(game, {a: 0, b: 1, c: 0, d: 1}, hidden=[a, c])
    assert estimator._explain(cells, shares, over=False).history() == [a, b, c, d]
    env.close()


def test_the_registered_move_is_kept_until_an_anchor_holds_it(request):
    """Go: the agent touches A (the arm resets: a registered move), and the
    reply B lies hidden by the arm at rest: the estimate [A, pass] runs
    unconfirmed. The agent presses B, the game refuses it, and the hand now
    hides A too: [pass, B] changes fewer hidden cells than [A, B], but the
    touch played A at that ply, so the estimate is [A, B] (taken for [pass,
    B] and confirmed once B was seen, the agent kept pressing A to the time
    limit: episode 44 of seed 0 of `mujogo/7x7` with the agent second)."""
    request.getfixturevalue("gnugo")
    env, view = _env("mujogo/7x7")
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), view.reset())
    game = BoardGame.from_description(view.description())
    a, b = 43, 44
    estimator._register(a)
    cells, shares = _frame(game, {a: 0}, hidden=[b])
    estimator._belief = estimator._explain(cells, shares, over=False)
    assert estimator._belief.history() == [a, game.pass_action]
    assert [s.history() for s in estimator._anchors] == [[]]  # the pass is not confirmed
    estimator._refused = {b}
    cells, shares = _frame(game, {a: 0, b: 1}, hidden=[a, b])
    assert estimator._explain(cells, shares, over=False).history() == [a, b]
    env.close()


def test_a_frame_the_last_anchor_cannot_explain_is_explained_from_an_earlier_one():
    """Hex: a reply first read at B (confirmed), then seen at C with B empty:
    no continuation of the first explanation fits, the one before it does."""
    env, view = _env("mujoboard/hex-7x7", opponent="random")
    timestep = view.reset()
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), timestep)
    game = BoardGame.from_description(view.description())

    def frame(pieces):
        board = np.full(game.num_points, -1, np.int8)
        for point, player in pieces.items():
            board[point] = player
        return board, np.stack([board == 0, board == 1], axis=1).astype(float)

    mine, first_reply, true_reply = 24, 25, 31
    cells, shares = frame({mine: 0, first_reply: 1})
    assert estimator._explain(cells, shares, over=False).history() == [mine, first_reply]
    cells, shares = frame({mine: 0, true_reply: 1})
    assert estimator._explain(cells, shares, over=False).history() == [mine, true_reply]
    assert [a.history() for a in estimator._anchors] == [[], [mine, true_reply]]
    env.close()


def _frame(game, pieces, hidden=()):
    """(cells, shares) of a synthetic frame: ``pieces`` {point: player}, the
    ``hidden`` points unseen, every other point read surely."""
    board = np.full(game.num_points, -1, np.int8)
    for point, player in pieces.items():
        board[point] = player
    shares = np.stack([board == 0, board == 1], axis=1).astype(float)
    hide = np.zeros(game.num_points, bool)
    hide[list(hidden)] = True
    return (np.where(hide, UNSEEN, board).astype(np.int8), np.where(hide[:, None], np.nan, shares))


def test_a_game_far_ahead_of_the_last_anchor_is_found_by_the_deeper_search():
    """Hex: ten moves played while nothing was confirmed (more than the
    search's usual `MAX_MOVES`): the frame is explained, and confirmed."""
    from hier_agents.estimators import camera_board

    env, view = _env("mujoboard/hex-7x7", opponent="random")
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), view.reset())
    game = BoardGame.from_description(view.description())
    moves = [24, 25, 17, 18, 31, 32, 10, 11, 38, 39]
    assert len(moves) > camera_board.MAX_MOVES
    cells, shares = _frame(game, {m: i % 2 for i, m in enumerate(moves)})
    state = estimator._explain(cells, shares, over=False)
    np.testing.assert_array_equal(game.players(state), cells)
    assert state.current_player() == 0 and len(estimator._anchors) == 2
    env.close()


def test_a_frame_is_explained_from_the_unconfirmed_estimate_when_the_anchor_is_too_far():
    """Hex: the estimate ran 16 moves ahead of the last anchor, unconfirmed
    (a changed cell never read surely); two more moves are then seen. No
    search from the anchor looks that far (`DEEP_MOVES`), one from the
    estimate does (in othello the beam can drop the true continuation
    from the anchor even within reach: its later moves flip what its
    earlier ones contradict)."""
    from hier_agents.estimators import camera_board

    env, view = _env("mujoboard/hex-7x7", opponent="random")
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), view.reset())
    game = BoardGame.from_description(view.description())
    moves = [0, 8, 2, 10, 4, 12, 6, 22, 14, 24, 16, 26, 18, 36, 20, 38, 28, 40]
    assert len(moves) - 2 == camera_board.DEEP_MOVES
    believed = estimator._anchor.clone()
    for move in moves[:-2]:
        believed.apply_action(move)
    estimator._belief = believed
    cells, shares = _frame(game, {m: i % 2 for i, m in enumerate(moves)})
    state = estimator._explain(cells, shares, over=False)
    assert state.history() == moves
    assert [len(a.history()) for a in estimator._anchors] == [0, len(moves)]
    env.close()


def test_cells_seen_in_different_frames_between_two_moves_confirm_the_estimate():
    """The hand hides the reply in one frame and the agent's own piece in the
    next (the board stands still in between): together they confirm the
    estimate, which becomes the anchor the next search starts from."""
    env, view = _env("mujoboard/hex-7x7", opponent="random")
    timestep = view.reset()
    estimator = BoardCameraEstimator(frame_every=1, still=False)
    estimator.reset(view.description(), timestep)
    game = BoardGame.from_description(view.description())
    mine, reply = 24, 25
    frames = [
        _frame(game, {mine: 0, reply: 1}, hidden=[reply]),
        _frame(game, {mine: 0, reply: 1}, hidden=[mine]),
    ]
    real = estimator._view

    class Scripted:
        """The real view, but each read returns the next scripted frame."""

        def __getattr__(self, name):
            return getattr(real, name)

        def read(self, *args):
            cells, shares = frames.pop(0)
            return cells, cells == UNSEEN, np.zeros(len(cells)), shares

    estimator._view = Scripted()
    still = np.zeros(view.action_spec().shape)
    assert estimator.estimate(view.step(still)).moves == (mine, reply)
    assert [a.history() for a in estimator._anchors] == [[]]  # the reply was hidden
    estimator.estimate(view.step(still))
    assert [a.history() for a in estimator._anchors] == [[], [mine, reply]]
    env.close()


def _go_estimator(request):
    request.getfixturevalue("gnugo")
    env, view = _env("mujogo/7x7")
    estimator = BoardCameraEstimator()
    estimator.reset(view.description(), view.reset())
    return env, estimator, BoardGame.from_description(view.description())


def test_a_pass_is_confirmed_only_when_every_empty_cell_was_read(request):
    """Go: the agent's stone seen, one empty cell hidden (a reply could lie
    there): the opponent's pass explains the frame but is not confirmed
    until that cell is read."""
    env, estimator, game = _go_estimator(request)
    mine, hidden = 24, 37
    cells, shares = _frame(game, {mine: 0}, hidden=[hidden])
    state = estimator._explain(cells, shares, over=False)
    assert state.history() == [mine, game.pass_action]
    assert [a.history() for a in estimator._anchors] == [[]]  # not confirmed
    cells, shares = _frame(game, {mine: 0})
    estimator._explain(cells, shares, over=False)
    assert estimator._anchors[-1].history() == [mine, game.pass_action]
    env.close()


def test_touch_zones_see_a_blocked_press_once_and_never_a_press_that_moves():
    """`TouchZones`: the zone under a point (its square, else the nearest
    within 1.5 half-sizes); a hand standing still just above a zone's top is
    blocked once, at exactly `STALL_STEPS` steps; one that goes down and up,
    or stands higher than `PRESS_HEIGHT`, never is; `reset` starts again;
    `within` tells a hand over a zone and low enough."""
    from types import SimpleNamespace

    from hier_agents.estimators.presses import PRESS_HEIGHT, STALL_STEPS, TouchZones

    description = SimpleNamespace(
        point_positions=[(0.0, 0.0, 0.1), (0.1, 0.0, 0.1)],
        pass_action=2,
        pass_zones={"left": {"centre": (-0.2, 0.0, 0.05), "half": (0.03, 0.1)}},
    )
    zones = TouchZones(description, 0.04)
    assert zones.under((0.03, 0.03)) == 0 and zones.under((0.1, -0.039)) == 1
    assert zones.under((-0.21, 0.09, 0.0)) == 2  # the pass area, then its number
    assert zones.under((0.05 + 0.001, 0.0)) == 1  # between squares: the nearest
    assert zones.under((0.0, 0.07)) is None  # beyond 1.5 half-sizes of every zone

    def follow(heights, x=0.1):
        out = []
        for z in heights:
            out.append(zones.blocked(np.array([x, 0.0, z])))
        return out

    still = follow([0.1 + 0.01] * (STALL_STEPS + 3))
    assert [i for i, z in enumerate(still) if z is not None] == [STALL_STEPS]
    assert still[STALL_STEPS] == 1
    zones.reset()
    bounce = [0.14, 0.12, 0.11, 0.105, 0.11, 0.12, 0.14, 0.16]
    assert follow(bounce) == [None] * len(bounce)
    high = 0.1 + PRESS_HEIGHT + 0.005
    assert follow([high] * (STALL_STEPS + 3)) == [None] * (STALL_STEPS + 3)
    assert zones.under(np.array([0.1, 0.0, 0.2])) == 1
    # `within`: over a zone and at most that high above its top (the pass area's top is lower).
    for point, height, inside in (
        ((0.1, 0.0, 0.15), 0.05, True),
        ((0.1, 0.0, 0.151), 0.05, False),
        ((-0.2, 0.0, 0.1), 0.05, True),
        ((0.0, 0.07, 0.1), 0.05, False),  # over no zone
    ):
        assert zones.within(np.array(point), height) is inside, point


def test_a_press_the_game_refused_shows_the_reply_under_the_hand(request):
    """Go: the opponent's reply hidden under the hand is first taken for a
    pass; the hand standing blocked on that point, with no arm reset, says
    the game refused the move there: the reply is found. Not where the point
    was read empty since the last arm reset: the press failed to register."""
    from hier_agents.estimators import presses

    env, estimator, game = _go_estimator(request)
    mine, reply = 24, 37
    assert not estimator._refuse(np.zeros(3), True)  # the arm reset after ``mine`` registered
    cells, shares = _frame(game, {mine: 0}, hidden=[reply])
    assert estimator._explain(cells, shares, over=False).history() == [mine, game.pass_action]
    estimator._belief = estimator._explain(cells, shares, over=False)
    zones = estimator._zones
    # The hand over ``reply``, standing still just above its top.
    over_reply = np.r_[zones.centres[reply], zones.tops[reply] + 0.01]
    refused = [estimator._refuse(over_reply, False) for _ in range(presses.STALL_STEPS + 2)]
    assert refused.count(True) == 1 and refused[presses.STALL_STEPS]
    assert estimator._explain(cells, shares, over=False).history() == [mine, reply]
    # An arm reset (a registered move) forgets the refusal.
    assert not estimator._refuse(np.zeros(3), True) and not estimator._refused
    # A point read surely empty since that reset is empty still (the board
    # stands still between registered moves): a press blocked there failed
    # to register, the game refused nothing.
    estimator._belief = estimator._explain(cells, shares, over=False)
    estimator._empty_since_reset[reply] = True
    refused = [estimator._refuse(over_reply, False) for _ in range(presses.STALL_STEPS + 2)]
    assert not any(refused) and not estimator._refused
    env.close()


def test_a_press_on_a_point_empty_in_the_confirmed_estimate_is_not_a_refusal(request):
    """Go, the agent first: the hand stands blocked on a point it never saw
    empty (under the hand since the game's start), before the press
    registers. The game's start is known and nothing registered since: the
    press failed to register, the game refused nothing (it once made the
    agent believe it had passed and the opponent stood there). After the
    agent's registered move (an arm reset) and a reply confirmed, the same
    holds of the points empty in that estimate; a reply not yet confirmed
    leaves them open."""
    from hier_agents.estimators import presses

    env, estimator, game = _go_estimator(request)
    zones = estimator._zones

    def presses_on(point) -> list[bool]:
        above = np.r_[zones.centres[point], zones.tops[point] + 0.01]
        return [estimator._refuse(above, False) for _ in range(presses.STALL_STEPS + 2)]

    first, mine, reply, later = 24, 16, 30, 40
    assert not any(presses_on(first)) and not estimator._refused
    estimator._refuse(np.zeros(3), True)  # ``mine`` registered: the arm reset
    cells, shares = _frame(game, {mine: 0}, hidden=[reply, later])
    estimator._belief = estimator._explain(cells, shares, over=False)
    assert len(estimator._anchors) == 1  # a pass is not confirmed with cells hidden
    assert presses_on(later).count(True) == 1 and estimator._refused == {later}
    estimator._refuse(np.zeros(3), True)
    cells, shares = _frame(game, {mine: 0, reply: 1}, hidden=[later])
    estimator._belief = estimator._explain(cells, shares, over=False)
    assert estimator._anchor.history() == [mine, reply]
    assert not any(presses_on(later)) and not estimator._refused
    env.close()
