"""Gymnasium observations a standard learner takes: the ``obs=`` choices,
privileged keys named as such, ``info["is_success"]``, clear errors,
``module:id`` ids, vector environments and Stable-Baselines3."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import dm_env
import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import envs
from fast_cover import cover, family_and_game
from envs.gymnasium_env import OBSERVATIONS, PRIVILEGED_PREFIX, GymnasiumEnv
from arm_driving import touch_point
from child_env import child_env

ROOT = Path(__file__).resolve().parents[1]
SMALL = {
    "mujoban": {"top_camera": (32, 32), "egocentric_camera": (32, 32)},
    "mujoxo": {"front_camera": (32, 32)},
    "mujogo": {"front_camera": (32, 32)},
}
CHECKED = {"mujoban": "mujoban/level1-pegs", "mujoxo": "mujoxo/mixture", "mujogo": "mujogo/7x7"}


@pytest.fixture(scope="module", params=sorted(CHECKED))
def built(request):
    """One environment per family, wrapped below with every observation choice."""
    family = request.param
    if family == "mujogo":
        request.getfixturevalue("gnugo")
    env = envs.load(CHECKED[family], seed=0, lazy_cameras=True, **SMALL[family])
    yield env
    env.close()


@pytest.mark.parametrize("obs", list(OBSERVATIONS))
def test_every_observation_choice_passes_gymnasium_check_env(built, obs):
    gym_env = GymnasiumEnv(env=built, obs=obs, render_mode="rgb_array")
    check_env(gym_env, skip_render_check=True)
    space = gym_env.observation_space
    task = built.task
    privileged = built.privileged_observations
    observation, _ = gym_env.reset(seed=1)
    assert space.contains(observation)
    if obs == "sensors":
        assert set(space.spaces) == set(built.observation_spec()) - privileged
        assert set(task.camera_configs) <= set(space.spaces)
    elif obs == "full":
        assert {k for k in space.spaces if k.startswith(PRIVILEGED_PREFIX)} == {
            PRIVILEGED_PREFIX + k for k in privileged
        }
        assert len(space.spaces) == len(built.observation_spec())
    elif obs == "pixels":
        assert space.shape == (32, 32, 3) and space.dtype == np.uint8
        assert observation.std() > 5  # a picture, not a blank frame
    else:
        assert space.dtype == np.float32 and len(space.shape) == 1
        layout = gym_env.state_layout
        assert list(layout)[-len(task.state_observations) :] == list(task.state_observations)
        assert not set(layout) & set(task.camera_configs)
        state_key = task.state_observations[0]
        raw = built.task.observe(built.physics)[state_key]
        np.testing.assert_array_equal(observation[layout[state_key]], raw.ravel())
        assert observation.size == sum(s.stop - s.start for s in layout.values())


@pytest.mark.parametrize("name", cover(envs.names(), family_and_game))
def test_no_default_observation_holds_a_privileged_key(name):
    """Every registered id: the default Dict has no privileged key, and every
    key the task declares privileged is one of its observations (named with
    the prefix in ``obs="full"``)."""
    env = envs.load(name, **envs.no_cameras(name))
    try:
        declared = env.privileged_observations
        assert declared and declared <= set(env.observation_spec())
        default = GymnasiumEnv(env=env).observation_space.spaces
        assert not declared & set(default)
        assert not any(k.startswith(PRIVILEGED_PREFIX) for k in default)
        full = GymnasiumEnv(env=env, obs="full").observation_space.spaces
        assert {PRIVILEGED_PREFIX + k for k in declared} <= set(full)
    finally:
        env.close()


def test_render_frames_have_the_render_size_and_show_the_pegs():
    env = gymnasium.make(
        "mujoban/level5-pegs",
        render_mode="rgb_array",
        render_size=(200, 240),
        top_camera=(96, 96),
        egocentric_camera=None,
    )
    observation, _ = env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (200, 240, 3) and frame.dtype == np.uint8
    dm = env.unwrapped.dm_env
    plain = dm.render(markers=False)
    assert plain.shape == frame.shape
    # The peg discs: light pixels that only the marked frame has.
    marked = (frame.min(axis=-1) > 200) & (plain.min(axis=-1) < 200)
    assert marked.sum() >= 4 * 10  # >= 4 px for each of at least 10 visible pegs
    # The observed camera is untouched.
    again = dm.render("top_camera", 96, 96, markers=False)
    np.testing.assert_array_equal(observation["top_camera"], again)
    env.close()


def test_bad_obs_and_unknown_keywords_name_the_valid_values():
    with pytest.raises(
        ValueError,
        match=r"'pixel'.*did you mean 'pixels'.*sensors, pixels, "
        r"state, full",
    ):
        gymnasium.make("mujoban/level1", obs="pixel")
    with pytest.raises(TypeError, match=r"'rendr_size'.*did you mean 'render_size'.*obs"):
        gymnasium.make("mujoban/level1", rendr_size=(64, 64))
    with pytest.raises(ValueError, match="top_camera"):
        gymnasium.make("mujoban/level1", obs="pixels", top_camera=None, egocentric_camera=None)


def test_is_success_at_the_end_of_a_solved_and_of_a_truncated_mujoban_episode():
    env = gymnasium.make("mujoban/level1", top_camera=None, egocentric_camera=None, time_limit=0.25)
    env.reset(seed=0)
    info, truncated = {}, False
    while not truncated:
        _, _, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        assert not terminated
        assert ("is_success" in info) == truncated
    assert info["is_success"] is False
    env.reset(seed=0)
    task, physics = env.unwrapped.dm_env.task, env.unwrapped.dm_env.physics
    target = sorted(task.level.targets)[0]
    task.set_box_position(physics, 0, task.cell_to_world(*target))
    _, reward, terminated, _, info = env.step(np.zeros(2, np.float32))
    assert terminated and reward > 10 and info["is_success"] is True
    env.close()


class _GymAsDm:
    """The dm_env face `arm_driving` drives, stepping through a GymnasiumEnv."""

    def __init__(self, gym_env):
        self.gym = gym_env
        inner = gym_env.unwrapped.dm_env
        self.task, self.physics, self.action_spec = inner.task, inner.physics, inner.action_spec
        self.info = {}

    def step(self, action):
        obs, reward, terminated, truncated, self.info = self.gym.step(
            np.asarray(action, np.float32)
        )
        kind = dm_env.StepType.LAST if terminated or truncated else dm_env.StepType.MID
        return dm_env.TimeStep(kind, reward, 0.0 if terminated else 1.0, obs)


def test_is_success_when_the_agent_wins_a_board_game():
    env = gymnasium.make("mujoxo/optimal", front_camera=None)
    env.reset(seed=0)
    arm = _GymAsDm(env)
    arm.task.play_moves([0, 3, 1, 4])  # the agent (X) wins at 2
    timestep = touch_point(arm, arm.task.point_position(2))
    assert timestep.last() and timestep.reward == 1.0
    assert arm.info["is_success"] is True
    env.close()


def _episode_ends(vec, steps=4):
    """Steps `vec` (episodes of 3 steps); checks ``is_success`` where episodes
    end; returns how many ended."""
    ends = 0
    for _ in range(steps):
        obs, _, terminated, truncated, info = vec.step(vec.action_space.sample())
        done = terminated | truncated
        if done.any():
            assert (info["_is_success"] == done).all()
            assert not info["is_success"][done].any()
            ends += int(done.sum())
    return ends


def _make_short():
    return gymnasium.make(
        "mujoban/level1", top_camera=(16, 16), egocentric_camera=None, time_limit=0.15
    )


def test_sync_vector_env_reports_success_at_episode_ends():
    vec = gymnasium.vector.SyncVectorEnv([_make_short, _make_short])
    try:
        obs, _ = vec.reset(seed=0)
        assert obs["top_camera"].shape == (2, 16, 16, 3)
        assert not {"full_entity_layer", "pixel_layer"} & set(obs)
        assert _episode_ends(vec) == 2
    finally:
        vec.close()


FRESH_INTERPRETER = """
import gymnasium
import numpy as np
from test_gymnasium_observations import _episode_ends

def make():
    return gymnasium.make("envs:mujoban/level1", top_camera=(16, 16), egocentric_camera=None,
                          time_limit=0.15)

if __name__ == "__main__":
    e = gymnasium.make("envs:mujoban/level1", obs="state", top_camera=None,
                       egocentric_camera=None)
    print(e.observation_space.shape)
    o = gymnasium.make("hier_agents.learning:options/ball-push", seed=1)
    print(type(o.unwrapped).__name__)
    vec = gymnasium.vector.AsyncVectorEnv([make, make])  # the default context: fork
    obs, _ = vec.reset(seed=0)
    print(obs["top_camera"].shape, _episode_ends(vec))
    vec.close()
"""


@pytest.mark.slow
def test_module_id_form_and_async_vector_env_in_a_fresh_interpreter(tmp_path):
    """``envs:`` and ``hier_agents.learning:`` ids import their registering
    modules; CleanRL's ``AsyncVectorEnv(...)`` with the default (fork)
    context steps environments with cameras."""
    script = tmp_path / "fresh.py"
    script.write_text(FRESH_INTERPRETER)
    env = child_env(ROOT / "tests")
    out = subprocess.run(
        [sys.executable, str(script)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=180,
        env=env,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.splitlines()[:3] == ["(425,)", "SkillEnv", "(2, 16, 16, 3) 2"]


# -- Stable-Baselines3 -----------------------------------------------------------------

POLICIES = {"sensors": "MultiInputPolicy", "state": "MlpPolicy", "pixels": "CnnPolicy"}
SB3_ENVS = {
    "mujoban/level1": {"top_camera": (48, 48), "egocentric_camera": (48, 48)},
    "mujoxo/mixture": {"front_camera": (48, 48)},
}


def _learn_and_evaluate(name, obs, tmp_path, **cameras):
    """PPO learns 128 steps; EvalCallback records two evaluations of two
    episodes' ``is_success`` each."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import EvalCallback

    def make():
        return gymnasium.make(name, obs=obs, time_limit=0.5, **{**SB3_ENVS[name], **cameras})

    env, eval_env = make(), make()
    try:
        callback = EvalCallback(
            eval_env, n_eval_episodes=2, eval_freq=64, log_path=str(tmp_path), verbose=0
        )
        model = PPO(
            POLICIES[obs],
            env,
            n_steps=64,
            batch_size=64,
            n_epochs=1,
            seed=0,
            device="cpu",
            verbose=0,
        )
        model.learn(total_timesteps=128, callback=callback)
        assert model.num_timesteps == 128
        assert len(callback.evaluations_successes) == 2
        assert all(len(s) == 2 for s in callback.evaluations_successes)
        saved = np.load(tmp_path / "evaluations.npz")
        assert saved["successes"].shape == (2, 2)
        assert np.isin(saved["successes"], (0.0, 1.0)).all()
    finally:
        env.close()
        eval_env.close()


def test_stable_baselines3_learns_on_the_default_observation(tmp_path):
    # NatureCNN takes frames of 36x36 pixels and more; one camera keeps it quick.
    _learn_and_evaluate(
        "mujoban/level1", "sensors", tmp_path, top_camera=(36, 36), egocentric_camera=None
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    "name, obs",
    [(n, o) for n in SB3_ENVS for o in POLICIES if (n, o) != ("mujoban/level1", "sensors")],
)
def test_stable_baselines3_learns_on_every_observation_choice(name, obs, tmp_path):
    _learn_and_evaluate(name, obs, tmp_path)
