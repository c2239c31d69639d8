"""The registry (`envs.load`, `envs.names`) and the gymnasium interface."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import envs
from fast_cover import cover, family_and_game
from envs.mujoban.levels import BOXOBAN_DIR, read_levels

MUJOBAN_NAMES = sorted(
    [f"mujoban/level{d}{p}" for d in range(1, 6) for p in ("", "-pegs")]
    + ["mujoban/curriculum", "mujoban/curriculum-pegs"]
)


def test_names_lists_every_mujoban_variant():
    assert [n for n in envs.names() if n.startswith("mujoban/")] == MUJOBAN_NAMES


def test_unknown_name_lists_the_known_ones():
    with pytest.raises(KeyError) as info:
        envs.load("mujoban/level9")
    message = str(info.value)
    assert "mujoban/level9" in message
    for name in MUJOBAN_NAMES:
        assert name in message


def test_unknown_override_lists_the_valid_ones():
    with pytest.raises(TypeError, match="valid overrides"):
        envs.load("mujoban/level1", colour="red")


def test_false_switches_a_camera_off_as_none_does():
    # TOML has no null: a spec's env_options say false.
    env = envs.load("mujoban/level1", egocentric_camera=False, top_camera=[16, 16])
    try:
        keys = set(env.observation_spec())
    finally:
        env.close()
    assert "top_camera" in keys and "egocentric_camera" not in keys
    envs.check("mujoxo/optimal", front_camera=False)
    with pytest.raises(TypeError, match=r"got True; None \(false in TOML\) switches it off"):
        envs.check("mujoban/level1", top_camera=True)


def _facets(name: str) -> list[tuple]:
    """A MuJoBan name's facets (`family_and_game`: its pegs) and whether it
    samples a curriculum; names that differ only in difficulty run with the
    slow tests."""
    return [*family_and_game(name), ("curriculum", "curriculum" in name)]


@pytest.mark.parametrize("name", cover(MUJOBAN_NAMES, _facets))
def test_every_name_passes_gymnasium_check_env(name):
    # render() at the default size (256 x 256) for the first name, at the
    # cameras' for the others: one renderer per environment, not two.
    size = (256, 256) if name == MUJOBAN_NAMES[0] else (32, 32)
    env = gymnasium.make(
        name,
        render_mode="rgb_array",
        top_camera=(32, 32),
        egocentric_camera=(32, 32),
        **({} if size == (256, 256) else {"render_size": size}),
    )
    check_env(env.unwrapped, skip_render_check=False)
    frame = env.unwrapped.render()
    assert frame.shape == (*size, 3) and frame.dtype == np.uint8
    env.close()


def test_gymnasium_episode_reports_termination_and_truncation():
    env = gymnasium.make("mujoban/level1", top_camera=None, egocentric_camera=None, time_limit=0.5)
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    steps, truncated, terminated = 0, False, False
    while not (truncated or terminated):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        steps += 1
    assert truncated and not terminated and steps == 10
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.step(env.action_space.sample())


def test_gymnasium_reset_with_seed_is_reproducible():
    env = gymnasium.make("mujoban/curriculum", top_camera=(16, 16), egocentric_camera=None)
    first, _ = env.reset(seed=11)
    level = env.unwrapped.dm_env.task.level
    env.reset(seed=12)
    again, _ = env.reset(seed=11)
    assert env.unwrapped.dm_env.task.level == level
    for key in first:
        np.testing.assert_array_equal(first[key], again[key])


def test_levels_override_plays_the_file_in_order():
    path = BOXOBAN_DIR / "medium-valid-000.txt"
    expected = read_levels(path)[:3]
    env = envs.load("mujoban/level2", levels=str(path), top_camera=None, egocentric_camera=None)
    played = []
    for _ in range(3):
        env.reset()
        played.append(env.task.level)
    assert played == expected
    env.seed(0)  # reseeding restarts the file
    env.reset()
    assert env.task.level == expected[0]
