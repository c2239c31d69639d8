"""MuJoBan looks like the original, and the camera estimator reads every
appearance the environment draws."""

import numpy as np
import pytest

import envs
from fast_cover import cover
from envs.mujoban import arena as arena_lib
from hier_agents.estimators.camera import CameraEstimator
from hier_agents.estimators.grid import cells_of
from envs.mujoban.levels import BOXOBAN_DIR

#: Colours rendered by the original (physics_planning_games built from
#: ../shared/peer/, 199x199 top camera, measured 2026-11-25 with
#: benchmarks/original_env.py): a box, a pad; a box on a pad and the covered
#: pad's ring (its _BOX_PRESSED_RGBA and _PRESSED_TARGET_RGBA under the same
#: light), and the outside of the grid (its sky_03 skybox).
ORIGINAL_RGB = {
    "box": (242, 251, 84),
    "pad": (255, 0, 0),
    "box_on_pad": (0, 0, 255),
    "pad_covered": (0, 255, 0),
    "backdrop": (87, 165, 255),
}
#: Largest difference per channel allowed (0-255).
TOLERANCE = 2


def _count(frame, rgb):
    return int(np.all(np.abs(frame.astype(int) - rgb) <= TOLERANCE, axis=-1).sum())


def test_rendered_box_pad_and_covered_pad_colours_match_the_originals():
    env = envs.load(
        "mujoban/level1",
        seed=0,
        top_camera=(199, 199),
        egocentric_camera=None,
        levels=str(BOXOBAN_DIR / "unfiltered-valid-000.txt"),
    )
    frame = env.reset().observation["top_camera"]
    # A box's top is 0.8 cells (14.5 px), 13-14 px of its own colour with 4x multisampling.
    side = 13
    assert _count(frame, ORIGINAL_RGB["box"]) >= 4 * side * side
    assert _count(frame, ORIGINAL_RGB["pad"]) >= 4 * 0.8 * 18 * 18
    assert _count(frame, ORIGINAL_RGB["backdrop"]) > 1000
    assert _count(frame, ORIGINAL_RGB["box_on_pad"]) == 0
    # Push a box onto a pad: it turns blue, its pad's ring green.
    task = env.task
    target = sorted(task.level.targets)[0]
    task.set_box_position(env.physics, 0, task.cell_to_world(*target))
    frame = env.step(np.zeros(2)).observation["top_camera"]
    assert task.pads_covered.sum() == 1
    assert _count(frame, ORIGINAL_RGB["box_on_pad"]) >= side * side
    assert _count(frame, ORIGINAL_RGB["pad_covered"]) >= 20
    assert _count(frame, ORIGINAL_RGB["box"]) >= 3 * side * side
    env.close()


def test_description_looks_compute_the_rendered_colours():
    env = envs.load("mujoban/level1", seed=0, top_camera=None, egocentric_camera=None)
    looks = env.description().looks
    for name in ("box", "pad", "box_on_pad", "pad_covered"):
        np.testing.assert_allclose(
            looks.facing_rgb(getattr(looks, name)), ORIGINAL_RGB[name], atol=1.0
        )
    assert looks.box == arena_lib.BOX_RGBA
    assert env.description().top_camera.coverage_inset == pytest.approx(0.375)
    env.close()


def test_set_appearance_rejects_unknown_names():
    env = envs.load("mujoban/level1", seed=0, top_camera=None, egocentric_camera=None)
    env.reset()
    walls, floors = env.task.appearances()
    assert len(walls) == 8 and len(floors) == 6
    with pytest.raises(ValueError, match="unknown wall texture 'brick'; one of"):
        env.task.set_appearance("brick", floors[0])
    env.task.set_appearance(walls[-1], floors[-1])
    assert env.task.appearance == (walls[-1], floors[-1])
    env.close()


@pytest.mark.parametrize(
    "pegs, multisamples",  # multisamples: 0 the agent's camera, 4 the original's
    # The original's looks with pegs with the fast tests, all four with the slow ones.
    cover([("-pegs", 4), ("", 0), ("", 4), ("-pegs", 0)], lambda *case: ["looks"]),
)
def test_camera_estimator_reads_every_wall_and_floor_appearance(pegs, multisamples):
    env = envs.load(
        f"mujoban/level1{pegs}",
        seed=3,
        top_camera=(199, 199),
        egocentric_camera=None,
        levels=str(BOXOBAN_DIR / "medium-valid-000.txt"),
        multisamples=multisamples,
    )
    task = env.task
    walls, floors = env.task.appearances()
    timestep = env.reset()
    layer = np.asarray(timestep.observation["full_entity_layer"])
    for wall in walls:
        for floor in floors:
            task.set_appearance(wall, floor)
            timestep = env.step(np.zeros(2))
            estimator = CameraEstimator(frame_every=1, walker_every=1)
            estimator.reset(env.description(), timestep)
            scene = estimator.estimate(env.step(np.zeros(2)))
            assert estimator.walls == cells_of(layer[..., 0]), (wall, floor)
            assert estimator.targets == cells_of(layer[..., 1]), (wall, floor)
            boxes, player = task.abstract_cells
            assert scene.state.boxes == frozenset(boxes), (wall, floor)
            assert tuple(scene.state.player) == tuple(player), (wall, floor)
            assert np.linalg.norm(scene.walker_xy - task.walker_position()) < 0.03
    env.close()


def test_cheaper_look_without_multisampling_is_read_too():
    env = envs.load(
        "mujoban/level5-pegs", seed=2, top_camera=(199, 199), egocentric_camera=None, multisamples=0
    )
    assert env.description().top_camera.coverage_inset == 0.0
    estimator = CameraEstimator(frame_every=1, walker_every=1)
    timestep = env.reset()
    layer = np.asarray(timestep.observation["full_entity_layer"])
    estimator.reset(env.description(), timestep)
    rng = np.random.default_rng(0)
    for _ in range(30):
        timestep = env.step(rng.uniform(-1, 1, 2))
        scene = estimator.estimate(timestep)
        assert np.linalg.norm(scene.walker_xy - env.task.walker_position()) < 0.05
    assert estimator.walls == cells_of(layer[..., 0])
    env.close()


@pytest.mark.parametrize("name", ["mujoxo/mixture", "mujogo/7x7"])
def test_board_shadow_map_draws_the_originals_4096_texel_shadows_within_the_bound(name):
    """The original's board looks (shadows, 4 samples) drawn with the
    library's shadow map against MuJoCo's 4096-texel map, which the original
    leaves: the same 84x84 frame of a settled arm within `SHADOW_MAP_BOUND`."""
    from envs.boards import arena as board_arena
    from envs.rendering import Cameras

    env = envs.load(name, seed=0, shadows=True, multisamples=4)
    env.reset()
    rng = np.random.default_rng(0)
    for _ in range(5):
        env.step(rng.uniform(-1, 1, env.action_spec().shape))
    model, data = env.physics.model.ptr, env.physics.data.ptr
    frames = []
    for size in (board_arena.SHADOW_MAP_SIZE, 4096):
        model.vis.quality.shadowsize = size  # read when the rendering context is made
        cameras = Cameras(model)
        try:
            frames.append(cameras.render(data, "front_camera", 84, 84).astype(int))
        finally:
            cameras.close()
    env.close()
    assert board_arena.SHADOW_MAP_SIZE < 4096
    mean_bound, share_bound = board_arena.SHADOW_MAP_BOUND
    difference = np.abs(frames[0] - frames[1])
    assert difference.mean() <= mean_bound
    assert (difference.max(-1) > 8).mean() <= share_bound
    assert difference.any()  # the two maps are drawn (and differ on shadow edges)
