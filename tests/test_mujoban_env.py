"""Behaviour of the MuJoBan environment: rewards, pegs, abstract layers, seeds."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import envs
from envs.core import Environment
from envs.mujoban import sources
from envs.mujoban.levels import BOXOBAN_DIR, Level, LevelError, read_levels
from envs.mujoban.task import Mujoban, entity_layer_to_pixels

from driving import drive_to, push_box

NO_CAMERAS = dict(top_camera=None, egocentric_camera=None)


def make_env(text: str, *, pegs=False, seed=0, **kwargs) -> Environment:
    level = Level.from_text(text)
    task = Mujoban(
        sources.FixedLevels([level]),
        pegs=pegs,
        max_boxes=len(level.boxes),
        randomize_appearance=False,
        **{**NO_CAMERAS, **kwargs},
    )
    return Environment(task, seed=seed)


TWO_BOXES = """\
##########
#        #
#        #
#  $ .   #
#@       #
#  $ .   #
#        #
#        #
#        #
##########"""


def rewards_while(fn, env):
    seen = []
    fn(on_step=seen.append)
    return seen


def test_box_pushed_onto_pad_gives_plus_one_then_all_pads_give_bonus_and_end():
    # The crude scripted pushes of tests/driving.py leave boxes a few cm off
    # centre; the lenient tolerance keeps this a test of the reward rules.
    env = make_env(TWO_BOXES, pad_tolerance=0.3)
    env.reset()
    first = push_box(env, (3, 3), (0, 1))
    second = push_box(env, (3, 4), (0, 1))  # onto the pad at (3, 5)
    rewards = [ts.reward for ts in first + second]
    assert sorted(r for r in rewards if r) == [1.0]
    assert not (first + second)[-1].last()
    assert env.task.pads_covered.tolist().count(True) == 1

    steps = push_box(env, (5, 3), (0, 1)) + push_box(env, (5, 4), (0, 1))
    nonzero = [ts.reward for ts in steps if ts.reward]
    # The last box's +1 and the +10 bonus arrive on the final step, which ends the episode.
    assert nonzero == [11.0]
    assert steps[-1].last() and steps[-1].discount == 0.0
    assert env.task.solved


ON_TARGET = """\
#######
#     #
# @*  #
#     #
#  $. #
#     #
#######"""


def test_box_pushed_off_pad_gives_minus_one():
    env = make_env(ON_TARGET)
    env.reset()
    level = env.task.level
    on_target = sorted(level.boxes & level.targets)[0]
    steps = push_box(env, on_target, (0, 1))
    nonzero = [ts.reward for ts in steps if ts.reward]
    assert nonzero == [-1.0]
    assert not steps[-1].last()


OPEN = """\
##########
#        #
#        #
#        #
#   $    #
#        #
#@      .#
#        #
#        #
##########"""


@pytest.mark.parametrize("pegs", [False, True])
def test_pegs_block_a_diagonal_push_that_succeeds_without_them(pegs):
    env = make_env(OPEN, pegs=pegs)
    env.reset()
    task, physics = env.task, env.physics
    body = physics.bind(task.boxes[0].body).element_id
    start = task.box_positions()[0]
    for _ in range(20):  # a steady push towards the north-east
        physics.data.xfrc_applied[body, :2] = (120.0, 120.0)
        env.step([0.0, 0.0])
    physics.data.xfrc_applied[body] = 0.0
    for _ in range(10):
        env.step([0.0, 0.0])
    moved = task.box_positions()[0] - start
    if pegs:
        assert np.all(np.abs(moved) < 0.2), moved
    else:
        assert np.all(moved > 0.7), moved


def test_pegs_let_a_straight_push_through():
    env = make_env(OPEN, pegs=True)
    env.reset()
    start = env.task.box_positions()[0]
    push_box(env, (4, 4), (0, 1))
    moved = env.task.box_positions()[0] - start
    assert moved[0] > 0.7 and abs(moved[1]) < 0.1, moved


def test_walls_stop_the_walker():
    env = make_env(ON_TARGET)
    env.reset()
    # The level is padded by one cell, so its west wall is column 1; east face:
    x_face = env.task.cell_to_world(4, 1)[0] + 0.5
    drive_to(env, (x_face - 2.0, env.task.walker_position()[1]), max_steps=80)
    assert env.task.walker_position()[0] > x_face + 0.15


@pytest.mark.parametrize("filename", ["unfiltered-valid-000.txt", "medium-valid-000.txt"])
def test_full_entity_layer_matches_real_boxoban_levels_at_reset(filename):
    path = BOXOBAN_DIR / filename
    levels = read_levels(path)[:15]
    env = envs.load("mujoban/level5", seed=0, levels=str(path), **NO_CAMERAS)
    for level in levels:
        obs = env.reset().observation
        np.testing.assert_array_equal(obs["full_entity_layer"], level.entity_layers())
        np.testing.assert_array_equal(
            obs["pixel_layer"], entity_layer_to_pixels(level.entity_layers())
        )
        assert env.task.level == level


def test_estimate_follows_the_walker_and_the_pushed_box():
    env = make_env(TWO_BOXES)
    env.reset()
    push_box(env, (3, 3), (0, 1))
    layer = env.task.observe(env.physics)["full_entity_layer"]
    boxes = set(zip(*np.nonzero(layer[..., 3])))
    assert (3, 4) in boxes and (3, 3) not in boxes
    player = list(zip(*np.nonzero(layer[..., 2])))
    assert len(player) == 1 and player[0] not in boxes


def test_same_seed_same_levels_and_same_first_100_observations():
    def run(seed):
        env = envs.load("mujoban/level3", seed=seed, top_camera=(32, 32), egocentric_camera=None)
        rng = np.random.default_rng(123)
        out = [env.reset().observation]
        for _ in range(99):
            out.append(env.step(rng.uniform(-1, 1, 2)).observation)
        return env.task.level, out

    level_a, obs_a = run(7)
    level_b, obs_b = run(7)
    level_c, _ = run(8)
    assert level_a == level_b
    assert level_a != level_c
    for a, b in zip(obs_a, obs_b):
        assert a.keys() == b.keys()
        for key in a:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_time_limit_truncates_with_discount_one():
    env = make_env(TWO_BOXES, time_limit=1.0)
    ts = env.reset()
    steps = 0
    while not ts.last():
        ts = env.step([0.0, 0.0])
        steps += 1
    assert steps == 20 and ts.discount == 1.0


def test_default_time_limit_is_900_control_steps_of_50ms():
    env = envs.load("mujoban/level1", **NO_CAMERAS)
    assert env.task.time_limit_steps == 900
    assert env.control_timestep == pytest.approx(0.05)


def test_cameras_are_observed_at_their_size_and_can_be_switched_off():
    env = envs.load("mujoban/level2", seed=1, top_camera=(48, 40), egocentric_camera=(24, 32))
    obs = env.reset().observation
    assert obs["top_camera"].shape == (48, 40, 3) and obs["top_camera"].dtype == np.uint8
    assert obs["walker/egocentric_camera"].shape == (24, 32, 3)
    assert obs["top_camera"].std() > 5  # an image, not a blank buffer
    off = envs.load("mujoban/level2", seed=1, **NO_CAMERAS).reset().observation
    assert "top_camera" not in off and "walker/egocentric_camera" not in off
    assert envs.no_cameras("mujoban/level2") == NO_CAMERAS
    assert envs.no_cameras("mujoxo/mixture") == {"front_camera": None}
    for key in (
        "walker/joints_pos",
        "walker/joints_vel",
        "walker/sensors_touch",
        "walker/sensors_accelerometer",
        "walker/sensors_gyro",
        "walker/sensors_velocimeter",
        "walker/orientation",
        "full_entity_layer",
        "pixel_layer",
    ):
        assert key in off


def test_appearance_changes_between_episodes_and_follows_the_seed():
    def appearances(seed):
        env = envs.load(
            "mujoban/level1",
            seed=seed,
            levels=str(BOXOBAN_DIR / "unfiltered-valid-000.txt"),
            **NO_CAMERAS,
        )
        out = []
        for _ in range(8):
            env.reset()
            out.append(env.task.appearance)
        env.close()
        return out

    first = appearances(0)
    assert len(set(first)) > 1
    walls = {w for w, _ in first}
    floors = {f for _, f in first}
    assert walls <= set(arena_lib_styles()[0]) and floors <= set(arena_lib_styles()[1])
    assert appearances(0) == first  # the same seed draws the same looks
    assert appearances(1) != first


def arena_lib_styles():
    from labmaze import assets

    return (assets.get_wall_texture_paths("style_01"), assets.get_floor_texture_paths("style_01"))


def test_level_larger_than_the_arena_is_a_level_error(tmp_path):
    big = "\n".join(["#" * 12] + ["#@$.       #"] + ["#" * 12]) + "\n"
    path = tmp_path / "big.txt"
    path.write_text("; 0\n" + big)
    with pytest.raises(LevelError) as info:
        envs.load("mujoban/level1", levels=str(path))
    error = info.value
    assert "big.txt" in str(error) and "larger than the arena" in str(error)
    assert (error.index, error.line, error.column) == (0, 2, 11)


def test_too_many_boxes_for_the_arena_is_a_level_error():
    level = Level.from_text("#####\n#@$.#\n#$. #\n#####")
    task = Mujoban(sources.FixedLevels([level]), max_boxes=1, **NO_CAMERAS)
    env = Environment(task)
    with pytest.raises(LevelError, match="at most 1"):
        env.reset()


def test_bad_actions_are_rejected_with_a_clear_error():
    env = envs.load("mujoban/level1", **NO_CAMERAS)
    env.reset()
    with pytest.raises(ValueError, match="shape"):
        env.step([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        env.step([np.nan, 0.0])


def test_closing_one_environment_leaves_another_ones_frames_intact():
    import gc

    first = envs.load("mujoban/level1", seed=0, top_camera=(32, 32), egocentric_camera=None)
    first.reset()
    second = envs.load("mujoban/level1", seed=1, top_camera=(32, 32), egocentric_camera=None)
    before = second.reset().observation["top_camera"]
    del first
    gc.collect()
    second.seed(1)
    after = second.reset().observation["top_camera"]
    np.testing.assert_array_equal(before, after)


def test_walls_look_the_same_when_drawn_cell_by_cell():
    text = read_levels(BOXOBAN_DIR / "unfiltered-valid-000.txt")[0].to_text()
    frames = []
    for slabs in (32, 2):  # 2 slabs cannot cover the level: per-cell fallback
        env = make_env(text, top_camera=(64, 64), wall_slabs=slabs)
        frame = env.reset().observation["top_camera"].astype(float)
        # Compare 4x4-pixel block means: the wall texture's fine noise is not
        # aligned between a merged slab and single cells, the layout must be.
        frames.append(frame.reshape(16, 4, 16, 4, 3).mean(axis=(1, 3)))
    assert np.abs(frames[0] - frames[1]).mean() < 3.0
    assert np.abs(frames[0] - frames[1]).max() < 40.0


def test_sleep_is_on_by_default_and_the_originals_setting_is_one_option_away():
    sleep_bit = int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    assert envs.load("mujoban/level1", **NO_CAMERAS).physics.model.opt.enableflags & sleep_bit
    assert envs.original_options("mujoban/level1-pegs") == {"sleep": False}
    original = envs.load("mujoban/level1", **envs.original_options("mujoban/level1"), **NO_CAMERAS)
    assert not original.physics.model.opt.enableflags & sleep_bit
    with pytest.raises(TypeError, match="sleep"):
        envs.load("mujoban/level1", sleep="yes", **NO_CAMERAS)
    # What differs from the original's settings, as a comparison's jobs name it.
    assert envs.deviations("mujoban/level1") == {"sleep": True}
    assert envs.deviations("mujoban/level1", {"sleep": False}) == {}
    assert envs.deviations("mujoban/level1", {"top_camera": False, "time_limit": 45.0}) == {
        "sleep": True,
        "top_camera": None,
    }
    assert envs.deviations("mujoban/level1", {"egocentric_camera": [96, 96]}) == {"sleep": True}
    assert envs.original_options("mujoxo/optimal") == envs.deviations("mujoxo/optimal") == {}
    # A run records the deviating defaults; a record without them meant the original's.
    assert envs.explicit_options("mujoban/level1", {"time_limit": 5.0}) == {
        "sleep": True,
        "time_limit": 5.0,
    }
    assert envs.recorded_options("mujoban/level1", {}) == {"sleep": False}
    assert envs.recorded_options("mujoban/level1", {"sleep": True}) == {"sleep": True}


def test_with_sleep_the_walls_and_pads_of_every_level_are_drawn_where_they_are():
    """The layout moves world geoms (wall slabs, pads) at each reset; MuJoCo
    with sleeping enabled never recomputes their poses, so the camera would
    show the compiled model's parked slabs and no pads."""
    frames = {}
    for sleep in (False, True):
        env = envs.load("mujoban/level5", seed=0, sleep=sleep, egocentric_camera=None)
        frames[sleep] = []
        for _ in range(2):  # two levels
            env.reset()
            for _ in range(10):
                timestep = env.step(np.zeros(2))
            frames[sleep].append(timestep.observation["top_camera"])
        env.close()
    for awake, asleep in zip(frames[False], frames[True]):
        np.testing.assert_array_equal(awake, asleep)


@pytest.mark.parametrize("bad", [-1, 2.5, "5", True, None])
def test_bad_noslip_iterations_is_a_value_error_naming_it(bad):
    with pytest.raises((ValueError, TypeError), match="noslip_iterations"):
        envs.load("mujoban/level1", noslip_iterations=bad, **NO_CAMERAS)


# -- the original task's values (physics_planning_games' MuJoBan) -----------------


def test_defaults_are_the_original_1ms_physics_and_0_1_cell_pad_tolerance():
    env = envs.load("mujoban/level1", **NO_CAMERAS)
    assert env.physics.model.opt.timestep == pytest.approx(0.001)
    assert env.task.physics_steps_per_control_step == 50
    assert env.task.pad_tolerance == pytest.approx(0.1)
    # composer's base arena, which the original's maze arena inherits
    assert env.physics.model.opt.noslip_iterations == 5
    assert env.physics.model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC


def test_explicit_options_restore_5ms_physics_and_a_0_3_cell_pad_tolerance():
    env = envs.load(
        "mujoban/level1",
        physics_timestep=0.005,
        pad_tolerance=0.3,
        noslip_iterations=0,
        **NO_CAMERAS,
    )
    assert env.physics.model.opt.noslip_iterations == 0
    assert env.physics.model.opt.timestep == pytest.approx(0.005)
    assert env.task.physics_steps_per_control_step == 10
    assert env.task.pad_tolerance == pytest.approx(0.3)
    assert env.control_timestep == pytest.approx(0.05)


def _place_box_next_to_pad(env, offset):
    """Puts the box of TWO_BOXES' row 3 at ``offset`` (m) from the pad at (3, 5)."""
    task = env.task
    index = task.abstract_cells[0].index((3, 3))
    px, py = task.cell_to_world(3, 5)
    task.set_box_position(env.physics, index, (px + offset[0], py + offset[1]))
    return env.step([0.0, 0.0])


@pytest.mark.parametrize("offset", [(0.09, 0.0), (0.0, -0.09), (-0.09, 0.09)])
def test_box_within_0_09_m_of_its_pad_covers_it_rewards_and_turns_pad_green_box_blue(offset):
    env = make_env(TWO_BOXES)
    env.reset()
    timestep = _place_box_next_to_pad(env, offset)
    assert timestep.reward == 1.0
    assert env.task.pads_covered.tolist().count(True) == 1
    from envs.mujoban import arena as arena_lib

    rgba = env.physics.model.geom_rgba
    pad_ids = [env.physics.bind(g).element_id for g in env.task.arena.pads]
    covered = [np.allclose(rgba[i], arena_lib.PAD_COVERED_RGBA, atol=1e-3) for i in pad_ids[:2]]
    assert covered.count(True) == 1
    # The original's colours: the covering box blue, the other box yellow.
    box_ids = [env.physics.bind(b.geom).element_id for b in env.task.boxes[:2]]
    index = env.task.abstract_cells[0].index(env.task.world_to_cell(env.task.cell_to_world(3, 5)))
    for k, i in enumerate(box_ids):
        want = arena_lib.BOX_ON_PAD_RGBA if k == index else arena_lib.BOX_RGBA
        np.testing.assert_allclose(rgba[i], want, atol=1e-6)


@pytest.mark.parametrize("offset", [(0.11, 0.0), (0.0, 0.11), (0.09, -0.11)])
def test_box_0_11_m_off_its_pad_does_not_cover_it(offset):
    env = make_env(TWO_BOXES)
    env.reset()
    timestep = _place_box_next_to_pad(env, offset)
    assert timestep.reward == 0.0
    assert not env.task.pads_covered.any()


def test_lenient_pad_tolerance_option_counts_a_box_0_25_m_off():
    env = make_env(TWO_BOXES, pad_tolerance=0.3)
    env.reset()
    assert _place_box_next_to_pad(env, (0.25, 0.0)).reward == 1.0


@pytest.mark.parametrize("pegs", [False, True])
def test_walker_driven_at_a_peg_at_full_speed_stays_on_its_side(pegs):
    env = make_env(OPEN, pegs=pegs)
    env.reset()
    task, physics = env.task, env.physics
    # The peg at the top-left corner of cell (6, 4): drive along its grid line.
    cx, cy = task.cell_to_world(6, 4)
    peg = np.array([cx - 0.5, cy + 0.5])
    root_x, root_y = task._walker_root_qpos[:2]  # pylint: disable=protected-access
    physics.data.qpos[[root_x, root_y]] = peg - (2.0, 0.0)
    physics.forward()
    closest, passed = np.inf, False
    for _ in range(60):  # 3 s: full roll towards +x, heading held on +x
        err = (-task.walker_heading() + np.pi) % (2 * np.pi) - np.pi
        roll = -1.0 if abs(err) < 0.3 else 0.0
        env.step([roll, float(np.clip(-4.0 * err, -1, 1))])
        delta = task.walker_position() - peg
        closest = min(closest, float(np.hypot(*delta)))
        passed |= bool(delta[0] > 0.3 and abs(delta[1]) < 0.3)
    if pegs:
        # Ball radius 0.2 m, peg corner 0.05 m from its axis: it never overlaps.
        assert closest > 0.2 and not passed
    else:
        assert closest < 0.1 and passed


def test_lazy_cameras_render_only_frames_that_are_read_and_refuse_stale_ones():
    from envs.core import LazyObservation, StaleObservationError

    eager = envs.load("mujoban/level2", seed=4, top_camera=(48, 48), egocentric_camera=None)
    lazy = envs.load(
        "mujoban/level2", seed=4, top_camera=(48, 48), egocentric_camera=None, lazy_cameras=True
    )
    a, b = eager.reset(), lazy.reset()
    assert isinstance(b.observation, LazyObservation)
    assert set(b.observation) == set(a.observation)
    assert not b.observation.rendered("top_camera")
    np.testing.assert_array_equal(b.observation["top_camera"], a.observation["top_camera"])
    assert b.observation.rendered("top_camera")
    for _ in range(3):
        a, b2 = eager.step([0.5, 0.2]), lazy.step([0.5, 0.2])
    np.testing.assert_array_equal(b2.observation["top_camera"], a.observation["top_camera"])
    np.testing.assert_array_equal(
        b2.observation["walker/orientation"], a.observation["walker/orientation"]
    )
    unread = lazy.step([0.5, 0.2])
    lazy.step([0.5, 0.2])
    unread.observation["walker/orientation"]  # computed eagerly: still readable
    with pytest.raises(StaleObservationError, match="lazy_cameras"):
        unread.observation["top_camera"]
    with pytest.raises(TypeError, match="lazy_cameras"):
        envs.load("mujoban/level1", lazy_cameras="yes")
    eager.close()
    lazy.close()
