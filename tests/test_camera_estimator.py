"""The camera estimator reads MuJoBan from the top camera alone.

Ground truth comes from the environment (``full_entity_layer``, the task's
abstract cells and positions); the estimator only sees frames and
proprioception.
"""

from pathlib import Path

import numpy as np
import pytest

import envs
from hier_agents.estimators.base import EstimationError
from hier_agents.estimators.camera import FRAME_SHAPE, CameraEstimator
from hier_agents.estimators.grid import cells_of

BOXOBAN = Path(envs.__file__).resolve().parent / "mujoban" / "data" / "boxoban"


def _env(name="mujoban/level1", seed=0, levels=None):
    kwargs = dict(levels=str(levels), level_order="shuffle") if levels else {}
    return envs.load(
        name, seed=seed, egocentric_camera=None, **CameraEstimator.env_overrides, **kwargs
    )


def _check_scene(env, scene, timestep, walker_tol=0.03, box_tol=0.05):
    layer = np.asarray(timestep.observation["full_entity_layer"])
    box_cells, player = env.task.abstract_cells
    assert scene.state.walls == cells_of(layer[..., 0])
    assert scene.state.targets == cells_of(layer[..., 1])
    assert tuple(scene.box_cells) == tuple(map(tuple, box_cells))  # same box order
    assert scene.state.player == tuple(player)
    cell = env.description().cell_size
    assert np.linalg.norm(scene.walker_xy - env.task.walker_position()) < walker_tol * cell
    assert np.abs(scene.box_xy - env.task.box_positions()).max() < box_tol * cell


def test_interface():
    est = CameraEstimator()
    assert est.name == "camera" and est.privileged is False
    assert est.env_overrides == {"top_camera": FRAME_SHAPE, "multisamples": 0, "lazy_cameras": True}
    with pytest.raises(EstimationError):
        est.estimate(None)
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="frame_every"):
            CameraEstimator(frame_every=bad)


@pytest.mark.parametrize("pegs", ["", "-pegs"])
@pytest.mark.parametrize("levels", ["unfiltered-valid-000.txt", "medium-valid-000.txt"])
def test_real_boxoban_grids_are_read_at_reset_under_random_textures(pegs, levels):
    env = _env(f"mujoban/level1{pegs}", seed=7 if pegs else 3, levels=BOXOBAN / levels)
    est = CameraEstimator(frame_every=1)
    for _ in range(4):  # a new level and textures every episode
        timestep = env.reset()
        est.reset(env.description(), timestep)
        _check_scene(env, est.estimate(timestep), timestep)
    env.close()


def test_generated_levels_while_rolling():
    env = _env("mujoban/level4-pegs", seed=11)
    est = CameraEstimator(frame_every=1)
    rng = np.random.default_rng(0)
    for _ in range(2):
        timestep = env.reset()
        est.reset(env.description(), timestep)
        action = rng.uniform(-1, 1, 2)
        for k in range(30):
            if k % 8 == 0:
                action = rng.uniform(-1, 1, 2)
            timestep = env.step(action)
            scene = est.estimate(timestep)  # every step: the player cell is remembered
        _check_scene(env, scene, timestep)
        # Heading and velocity come from proprioception.
        assert abs(np.angle(np.exp(1j * (scene.heading - env.task.walker_heading())))) < 1e-6
        np.testing.assert_allclose(scene.walker_velocity, env.task.walker_velocity(), atol=0.05)
    env.close()


def _free_neighbours(env, cell):
    box_cells, player = env.task.abstract_cells
    taken = set(map(tuple, env.task.level.walls)) | set(map(tuple, box_cells)) | {tuple(player)}
    r, c = cell
    return [
        (r + dr, c + dc)
        for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1))
        if (r + dr, c + dc) not in taken
    ]


def test_scripted_box_moves_are_seen():
    """Boxes moved one cell over (next to walls, next to other boxes, onto
    pads) are seen in their new cells, in the same order."""
    env = _env("mujoban/level1", seed=5, levels=BOXOBAN / "unfiltered-valid-000.txt")
    est = CameraEstimator(frame_every=1)
    moves = 0
    for _ in range(3):
        timestep = env.reset()
        est.reset(env.description(), timestep)
        for i in range(len(env.task.box_positions())):
            cell = env.task.abstract_cells[0][i]
            free = _free_neighbours(env, cell)
            if not free:
                continue
            target = free[0]
            env.task.set_box_position(env.physics, i, env.task.cell_to_world(*target))
            timestep = env.step(np.zeros(2))
            assert env.task.abstract_cells[0][i] == target
            scene = est.estimate(timestep)
            assert scene.box_cells[i] == target
            _check_scene(env, scene, timestep)
            moves += 1
    assert moves >= 4
    env.close()


def test_touching_and_off_centre_boxes():
    """Two boxes pushed together (no gap) and a box between cells."""
    env = _env("mujoban/level5", seed=2)
    est = CameraEstimator(frame_every=1)
    done = 0
    for _ in range(6):
        timestep = env.reset()
        est.reset(env.description(), timestep)
        box_cells, _ = env.task.abstract_cells
        for i, cell in enumerate(box_cells):
            free = _free_neighbours(env, cell)
            for r, c in free:
                # Is the cell beyond (r, c) another box? Push box i against it.
                dr, dc = r - cell[0], c - cell[1]
                if (r + dr, c + dc) in set(box_cells):
                    j = list(box_cells).index((r + dr, c + dc))
                    xj, yj = env.task.box_positions()[j]
                    xy = (xj - dc * 0.8, yj + dr * 0.8)  # touching box j
                    env.task.set_box_position(env.physics, i, xy)
                    timestep = env.step(np.zeros(2))
                    _check_scene(env, est.estimate(timestep), timestep)
                    done += 1
                    break
            else:
                continue
            break
        # One box 0.3 cells off its centre, towards a free cell.
        box_cells, _ = env.task.abstract_cells
        for i, cell in enumerate(box_cells):
            free = _free_neighbours(env, cell)
            if free:
                (r, c), (x, y) = free[0], env.task.cell_to_world(*cell)
                env.task.set_box_position(
                    env.physics, i, (x + 0.3 * (c - cell[1]), y - 0.3 * (r - cell[0]))
                )
                timestep = env.step(np.zeros(2))
                _check_scene(env, est.estimate(timestep), timestep)
                break
    assert done >= 1
    env.close()


def test_inconsistent_frames_raise():
    env = _env("mujoban/level3", seed=1)
    est = CameraEstimator(frame_every=1)
    timestep = env.reset()
    est.reset(env.description(), timestep)
    frame = np.asarray(timestep.observation["top_camera"])

    def with_frame(image):
        observation = dict(timestep.observation)
        observation["top_camera"] = image
        return timestep._replace(observation=observation)

    # The walker painted over with the floor colour next to it.
    hidden = frame.copy()
    red = (frame[..., 0] > 40) & (frame[..., 1] * 5 < frame[..., 0])
    blue = (frame[..., 2] > 40) & (frame[..., 0] * 5 < frame[..., 2])
    hidden[red | blue] = (128, 128, 128)
    with pytest.raises(EstimationError, match="walker not found"):
        est.estimate(with_frame(hidden))
    # A box painted over: the count no longer matches.
    looks = env.description().looks
    rows, cols = np.nonzero(
        np.all(np.abs(frame.astype(int) - looks.facing_rgb(looks.box)) <= 2, axis=-1)
    )
    assert len(rows)
    no_box = frame.copy()
    no_box[rows, cols] = (128, 128, 128)
    with pytest.raises(EstimationError, match="boxes seen"):
        est.estimate(with_frame(no_box))
    # The untouched frame is fine again.
    _check_scene(env, est.estimate(timestep), timestep)
    env.close()


def test_between_frames_the_scene_is_predicted_and_a_moved_box_is_seen_at_the_next_frame():
    """The default estimator reads every third frame (the environment renders
    only those, lazily) and predicts the walker from its velocimeter and the
    boxes from their measured velocity in between."""
    env = _env("mujoban/level3", seed=21)
    est = CameraEstimator(frame_every=3)
    timestep = env.reset()
    est.reset(env.description(), timestep)
    est.estimate(timestep)
    rng = np.random.default_rng(1)
    action, errors = rng.uniform(-1, 1, 2), []
    for k in range(40):
        if k % 10 == 0:
            action = rng.uniform(-1, 1, 2)
        timestep = env.step(action)
        scene = est.estimate(timestep)
        errors.append(np.linalg.norm(scene.walker_xy - env.task.walker_position()))
    # Every third frame, every second near a box: never two in a row.
    assert est.frames_read + est.steps_predicted == 41 and 14 <= est.frames_read <= 21
    assert max(errors) < 0.03 * env.description().cell_size
    # A box moved by hand (one cell over) shows up within frame_every steps.
    box_cells, player = env.task.abstract_cells
    i = 0
    r, c = box_cells[i]
    free = next(
        (r + dr, c + dc)
        for dr, dc in ((0, 1), (0, -1), (1, 0), (-1, 0))
        if (r + dr, c + dc) not in est.walls
        and (r + dr, c + dc) not in box_cells
        and (r + dr, c + dc) != player
    )
    env.task.set_box_position(env.physics, i, env.description().cell_centre(*free))
    seen_after = None
    for k in range(1, 4):
        timestep = env.step(np.zeros(2))
        if free in est.estimate(timestep).state.boxes:
            seen_after = k
            break
    assert seen_after is not None and seen_after <= 3
    env.close()


# -- the estimator's kernels against their plain definitions -----------------

from hypothesis import given, settings, strategies as st  # noqa: E402
from hypothesis.extra.numpy import arrays  # noqa: E402
from scipy import ndimage  # noqa: E402

from hier_agents.estimators.camera_ears import EAR_OFFSET, match_ears  # noqa: E402
from hier_agents.estimators.colours import dilate3  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(arrays(bool, st.tuples(st.integers(1, 12), st.integers(1, 12)), elements=st.booleans()))
def test_dilate3_is_a_3x3_binary_dilation(mask):
    np.testing.assert_array_equal(
        dilate3(mask), ndimage.binary_dilation(mask, structure=np.ones((3, 3), bool))
    )


def _match_ears_plainly(centre, lateral, red, blue, occ, world, radius, offsets):
    """`match_ears` by its definition: every candidate centre, every
    visible pixel, distances computed directly."""
    vis = ~occ
    pts = world[vis]
    obs_r, obs_b = red[vis], blue[vis]
    dx, dy = np.meshgrid(offsets, offsets, indexing="ij")
    cands = np.asarray(centre)[None, :] + np.stack([dx.ravel(), dy.ravel()], 1)
    miss = []
    for c in cands:
        er, eb = c + EAR_OFFSET * lateral, c - EAR_OFFSET * lateral
        dr = ((pts - er) ** 2).sum(1)
        db = ((pts - eb) ** 2).sum(1)
        pred_r = (dr <= radius**2) & (dr <= db)
        pred_b = (db <= radius**2) & (db < dr)
        miss.append(int((pred_r != obs_r).sum() + (pred_b != obs_b).sum()))
    miss = np.asarray(miss)
    return cands[miss == miss.min()].mean(axis=0)


@pytest.mark.parametrize("seed", range(6))
def test_match_ears_equals_its_plain_definition(seed):
    # Ears drawn at a random true centre on a 0.05 m pixel grid, some pixels
    # hidden; started from a centre up to a pixel off.
    rng = np.random.default_rng(seed)
    h = w = 40
    ys, xs = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    world = np.stack([xs * 0.05, ys * 0.05], -1)
    heading = rng.uniform(-np.pi, np.pi)
    lateral = np.array([np.sin(heading), -np.cos(heading)])
    truth = np.array([1.0, 1.0]) + rng.uniform(-0.1, 0.1, 2)
    radius = 0.25
    dr = np.linalg.norm(world - (truth + EAR_OFFSET * lateral), axis=-1)
    db = np.linalg.norm(world - (truth - EAR_OFFSET * lateral), axis=-1)
    red, blue = (dr <= radius) & (dr <= db), (db <= radius) & (db < dr)
    occ = rng.random((h, w)) < 0.1
    start = truth + rng.uniform(-0.05, 0.05, 2)
    for offsets in (np.linspace(-0.05, 0.05, 17), np.linspace(-0.0075, 0.0075, 13)):
        fast = match_ears(start, lateral, red, blue, occ.copy(), world, radius, offsets)
        plain = _match_ears_plainly(start, lateral, red, blue, occ, world, radius, offsets)
        np.testing.assert_allclose(fast, plain, rtol=0, atol=1e-12)


WALL_LEVEL = """; 0
##########
#        #
#      @$#
#        #
#  .     #
#        #
#        #
#        #
#        #
##########
"""


@pytest.mark.parametrize("pegs", [False, True])
def test_a_box_against_a_wall_is_located_from_its_free_edge(tmp_path, pegs):
    """A box pushed flat against the outer wall, the walker on its other
    side: the walls' safety band cuts the box's far edge out of the frame
    and the walker is nearer the free edge. The centre comes from the free
    edge and the wall, within 0.03 cells (the cut edge put it 0.04 off)."""
    levels = tmp_path / "wall.txt"
    levels.write_text(WALL_LEVEL)
    env = _env("mujoban/level1-pegs" if pegs else "mujoban/level1", levels=levels)
    est = CameraEstimator(frame_every=1)
    timestep = env.reset()
    est.reset(env.description(), timestep)
    x, y = env.task.cell_to_world(2, 8)
    for shift in (0.098, 0.09, 0.08):  # flat against the wall, then 0.02 and 0.04 cells from it
        env.task.set_box_position(env.physics, 0, (x + shift, y))
        timestep = env.step(np.zeros(2))
        scene = est.estimate(timestep)
        _check_scene(env, scene, timestep, box_tol=0.03)
    env.close()
