"""Batched environments (`envs.vector`): each environment ends bit for bit
where stepping it alone would, gymnasium's autoreset rules, Stable-Baselines3
on the adapter, and the errors."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from envs import GymnasiumEnv
from envs.gymnasium_env import ActionRepeat
from envs.vector import BatchedVectorEnv, make
from envs.vector_sb3 import Sb3VecEnv, make_sb3

ROOT = Path(__file__).resolve().parents[1]
ENV = "mujoban/level1"
#: Half-second episodes: 10 control steps, so a few episodes end in 50 steps.
SHORT = {"time_limit": 0.5}


def _actions(steps: int, shape, seed: int = 0) -> np.ndarray:
    """Random actions in [-1, 1], float32 as the action space's samples."""
    return np.random.default_rng(seed).uniform(-1, 1, (steps, *shape)).astype(np.float32)


def _reference(name: str, n: int, seed: int, repeat: int = 1, mode=AutoresetMode.NEXT_STEP, **kw):
    """gymnasium's own vector env stepping ``n`` `GymnasiumEnv` s one after
    another, each seeded as `envs.vector` seeds environment i (episode i)."""

    def thunk():
        env = GymnasiumEnv(name, obs="state", **kw)
        return env if repeat == 1 else ActionRepeat(env, repeat)

    sync = SyncVectorEnv([thunk] * n, autoreset_mode=mode)
    for i, env in enumerate(sync.envs):
        env.unwrapped.dm_env.seed(seed, episode=i)
    return sync


def _physics_state(env: GymnasiumEnv) -> bytes:
    data = env.unwrapped.dm_env.physics.data
    return data.qpos.tobytes() + data.qvel.tobytes() + data.time.hex().encode()


def _same(a, b) -> bool:
    return data_equivalence(a, b, exact=True)


def _play_both(vec: BatchedVectorEnv, ref: SyncVectorEnv, actions: np.ndarray) -> tuple:
    """Steps both with ``actions``, asserting equal results and physics after
    every step; returns the batched env's terminated | truncated and rewards per step."""
    first, ref_first = vec.reset(), ref.reset()
    assert _same(first, ref_first)
    ends, rewards = [], []
    for t, action in enumerate(actions):
        got, want = vec.step(action), ref.step(action)
        for part, (x, y) in enumerate(zip(got, want)):
            assert _same(x, y), f"step {t}: part {part} differs: {x} != {y}"
        assert got[0].tobytes() == want[0].tobytes()
        for i in range(vec.num_envs):
            assert _physics_state(vec.envs[i]) == _physics_state(ref.envs[i]), (t, i)
        ends.append(got[2] | got[3])
        rewards.append(got[1])
    return ends, rewards


#: A box on its pad beside the walker: holding the action (1, -1) pushes it
#: off (reward -1) about 12 steps into an episode.
ON_PAD = """\
; 0
#######
#     #
# @*  #
#     #
#  $. #
#     #
#######
"""


@pytest.mark.parametrize("threads", [1, 2])
def test_each_env_ends_bit_for_bit_where_stepping_it_alone_would(threads, tmp_path):
    # 3 environments x 50 steps of 20-step episodes: 2 autoresets each;
    # observations, rewards (environment 0 pushes the box off its pad), flags,
    # infos, qpos, qvel and time equal after every step.
    levels = tmp_path / "on_pad.txt"
    levels.write_text(ON_PAD)
    options = {"levels": str(levels), "time_limit": 1.0}
    vec = make(ENV, num_envs=3, obs="state", seed=0, threads=threads, **options)
    ref = _reference(ENV, 3, seed=0, **options)
    try:
        actions = _actions(50, vec.action_space.shape)
        actions[:, 0] = [1.0, -1.0]
        ends, rewards = _play_both(vec, ref, actions)
    finally:
        vec.close()
        ref.close()
    assert np.sum(ends, axis=0).tolist() == [2, 2, 2]
    assert -1.0 in np.array(rewards)[:, 0]


def test_action_repeat_holds_each_action_as_the_wrapper_does():
    vec = make(ENV, num_envs=2, obs="state", seed=3, threads=2, action_repeat=3, **SHORT)
    ref = _reference(ENV, 2, seed=3, repeat=3, **SHORT)
    try:
        # 10-step episodes in holds of 3 steps: the 4th hold is cut to 1 step.
        ends, _ = _play_both(vec, ref, _actions(8, vec.action_space.shape, seed=1))
        assert [e.all() for e in ends] == [False] * 3 + [True] + [False] * 4
    finally:
        vec.close()
        ref.close()


def test_same_step_autoreset_matches_gymnasium():
    vec = make(ENV, num_envs=2, obs="state", seed=5, autoreset_mode="SameStep", **SHORT)
    ref = _reference(ENV, 2, seed=5, mode=AutoresetMode.SAME_STEP, **SHORT)
    try:
        assert vec.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
        _play_both(vec, ref, _actions(12, vec.action_space.shape, seed=2))
    finally:
        vec.close()
        ref.close()


def test_next_step_autoreset_returns_the_first_observation_and_ignores_the_action():
    a = make(ENV, num_envs=2, obs="state", seed=1, threads=2, **SHORT)
    b = make(ENV, num_envs=2, obs="state", seed=1, threads=1, **SHORT)
    try:
        assert a.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
        a.reset()
        b.reset()
        actions = _actions(10, a.action_space.shape)
        for action in actions:
            out_a = a.step(action)
            assert _same(out_a, b.step(action))
        assert out_a[3].all() and not out_a[2].any()  # the time limit: truncated
        # The next step resets: its actions (different in a and b) are ignored.
        obs_a, reward, terminated, truncated, info = a.step(np.ones(a.action_space.shape))
        obs_b, *_ = b.step(-np.ones(b.action_space.shape))
        assert obs_a.tobytes() == obs_b.tobytes()
        assert reward.tolist() == [0.0, 0.0]
        assert not terminated.any() and not truncated.any()
        assert info == {}  # a reset's info, for both environments
        assert [env.dm_env.step_count for env in a.envs] == [0, 0]
        assert a.observation_space.contains(obs_a)
        # ... and the new episodes go on alike.
        assert _same(a.step(actions[0]), b.step(actions[0]))
        assert [_physics_state(e) for e in a.envs] == [_physics_state(e) for e in b.envs]
    finally:
        a.close()
        b.close()


def test_a_board_game_steps_in_a_batch():
    # MuJoXO with the opponent moving first: its replies run at every reset.
    options = {"agent_player": 1, "time_limit": 0.25}
    vec = make("mujoxo/random", num_envs=2, obs="state", seed=0, threads=2, **options)
    ref = _reference("mujoxo/random", 2, seed=0, **options)
    try:
        ends, _ = _play_both(vec, ref, _actions(12, vec.action_space.shape))
        assert np.array(ends).sum() >= 2
    finally:
        vec.close()
        ref.close()


def test_gymnasium_make_vec_builds_a_batch_and_gymnasium_wrappers_work():
    vec = gymnasium.make_vec(ENV, num_envs=2, obs="state", threads=2, seed=0, **SHORT)
    single = GymnasiumEnv(ENV, obs="state")
    try:
        assert isinstance(vec, BatchedVectorEnv) and vec.spec.id == ENV
        assert vec.single_observation_space == single.observation_space
        assert vec.single_action_space == single.action_space
        stats = gymnasium.wrappers.vector.RecordEpisodeStatistics(vec)
        obs, _ = stats.reset()
        assert obs.dtype == np.float32 and stats.observation_space.contains(obs)
        lengths = []
        for _ in range(11):
            obs, reward, terminated, truncated, info = stats.step(stats.action_space.sample())
            assert stats.observation_space.contains(obs) and reward.dtype == np.float64
            if "episode" in info:
                lengths += info["episode"]["l"][info["_episode"]].tolist()
        assert lengths == [10, 10]
    finally:
        vec.close()
        single.close()
    sync = gymnasium.make_vec(ENV, num_envs=2, obs="state", vectorization_mode="sync")
    assert isinstance(sync, SyncVectorEnv)
    sync.close()


def test_seeds_give_env_i_episode_i_of_the_run_and_lists_seed_each_env():
    vec = make(ENV, num_envs=2, obs="state", threads=2)
    alone = GymnasiumEnv(ENV, obs="state")
    try:
        first, _ = vec.reset(seed=11)
        alone.dm_env.seed(11, episode=1)
        assert first[1].tobytes() == alone.reset()[0].tobytes()
        again, _ = vec.reset(seed=[12, None])  # gymnasium's per-env seeds
        assert again[0].tobytes() == alone.reset(seed=12)[0].tobytes()
        kept, _ = vec.reset(options={"reset_mask": np.array([False, True])})
        assert kept[0].tobytes() == again[0].tobytes()
        assert [env.dm_env.step_count for env in vec.envs] == [0, 0]
    finally:
        vec.close()
        alone.close()


def test_sb3_adapter_matches_dummy_vec_env():
    from stable_baselines3.common.vec_env import DummyVecEnv

    sb3 = make_sb3(ENV, num_envs=2, obs="state", threads=2, **SHORT)
    dummy = DummyVecEnv([lambda: GymnasiumEnv(ENV, obs="state", **SHORT)] * 2)
    try:
        sb3.seed(4)
        dummy.seed(4)
        assert _same(sb3.reset(), dummy.reset())
        ends = []
        for t, action in enumerate(_actions(22, (2, *sb3.action_space.shape))):
            got, want = sb3.step(action), dummy.step(action)
            assert all(_same(x, y) for x, y in zip(got, want)), t
            ends += [t for info in got[3] if info["TimeLimit.truncated"]]
        assert ends == [9, 9, 19, 19]  # and their terminal observations were equal
    finally:
        sb3.close()
        dummy.close()


@pytest.mark.slow
def test_sb3_ppo_trains_on_the_adapter():
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    venv = VecMonitor(make_sb3(ENV, num_envs=4, obs="state", seed=0, threads=2, **SHORT))
    try:
        model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
        model.learn(total_timesteps=256)
        assert model.num_timesteps == 256
        assert len(model.ep_info_buffer) >= 4 * 2  # 10-step episodes ended in every env
    finally:
        venv.close()


def test_gymnasium_users_do_not_load_stable_baselines3():
    code = "import sys, gymnasium, envs.vector; print('torch' in sys.modules)"
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == "False"


def _physics_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("envs-physics")]


def test_close_stops_the_threads_and_closes_every_env():
    assert not _physics_threads()
    vec = make(ENV, num_envs=3, obs="state", threads=3, seed=0)
    vec.reset()
    vec.step(np.zeros(vec.action_space.shape))
    assert len(_physics_threads()) == 2  # and the calling thread
    vec.close()
    vec.close()  # idempotent
    assert all(env.dm_env.closed for env in vec.envs)
    assert not _physics_threads()


def test_a_step_that_raises_leaves_the_batch_needing_a_reset():
    vec = make(ENV, num_envs=3, obs="state", threads=2, seed=0)
    try:
        vec.reset()
        broken = vec.envs[1].dm_env

        def diverge():
            raise RuntimeError("diverged")

        broken._advance = diverge
        steps = [env.dm_env.step_count for env in vec.envs]
        with pytest.raises(RuntimeError, match="diverged"):
            vec.step(np.zeros(vec.action_space.shape))
        # The others finished their step.
        assert [env.dm_env.step_count for env in vec.envs] == [steps[0] + 1, 0, steps[2] + 1]
        with pytest.raises(RuntimeError, match="needs reset"):
            vec.step(np.zeros(vec.action_space.shape))
        del broken._advance
        vec.reset()
        vec.step(np.zeros(vec.action_space.shape))
    finally:
        vec.close()


def test_bad_arguments_fail_clearly_before_building():
    for bad, error in [(0, ValueError), (-2, ValueError), (2.0, TypeError), (True, TypeError)]:
        with pytest.raises(error, match="num_envs"):
            make(ENV, num_envs=bad)
        with pytest.raises(error, match="threads"):
            make(ENV, num_envs=1, threads=bad)
        with pytest.raises(error, match="action_repeat"):
            make(ENV, num_envs=1, action_repeat=bad)
    with pytest.raises(ValueError, match="autoreset_mode"):
        make(ENV, num_envs=1, autoreset_mode="later")
    with pytest.raises(ValueError, match="did you mean 'pixels'"):
        make(ENV, num_envs=1, obs="pixel")
    with pytest.raises(TypeError, match="valid keywords"):
        make(ENV, num_envs=1, colour="red")
    with pytest.raises(TypeError, match="seed"):
        make(ENV, num_envs=1, seed="0")
    with pytest.raises(TypeError, match="GymnasiumEnv"):
        BatchedVectorEnv([])
    with pytest.raises(TypeError, match="GymnasiumEnv"):
        Sb3VecEnv(["mujoban/level1"])


def test_bad_actions_fail_clearly_and_step_nothing():
    vec = make(ENV, num_envs=2, obs="state", seed=0, threads=2)
    try:
        with pytest.raises(RuntimeError, match="needs reset"):
            vec.step(np.zeros((2, 2)))
        vec.reset()
        with pytest.raises(ValueError, match=r"shape \(2, 2\) \(a row per env\), got \(2,\)"):
            vec.step(np.zeros(2))
        with pytest.raises(ValueError, match="finite"):
            vec.step(np.array([[0.0, np.nan], [0.0, 0.0]]))
        with pytest.raises(TypeError, match="numbers"):
            vec.step([["a", "b"], ["c", "d"]])
        with pytest.raises(ValueError, match="3 seeds for 2"):
            vec.reset(seed=[1, 2, 3])
        assert [env.dm_env.step_count for env in vec.envs] == [0, 0]
        vec.step(np.zeros((2, 2)))  # still usable
    finally:
        vec.close()


@pytest.mark.slow
def test_the_vector_speed_benchmark_measures_every_setup_in_rounds(tmp_path):
    out = tmp_path / "rows.json"
    sizes = ["--sizes", "1", "2", "--threads", "1", "2", "--processes", "2"]
    sizes += ["--async", "2", "--sync", "2"]
    subprocess.run(
        [sys.executable, "benchmarks/vector_speed.py", "--envs", ENV, *sizes]
        + ["--seconds", "0.05", "--rounds", "2", "--json", str(out)],
        check=True,
        cwd=ROOT,
        capture_output=True,
        timeout=600,
    )
    result = json.loads(out.read_text())
    assert {"command", "commit", "date", "machine"} <= set(result["provenance"])
    rows = {(r["setup"], r["num_envs"], r["threads"]): r for r in result["rows"]}
    assert list(rows) == [
        ("single", 1, None),
        ("processes", 2, None),
        ("async", 2, None),
        ("sync", 2, None),
        ("batched", 1, 1),
        ("batched", 1, 2),
        ("batched", 2, 1),
        ("batched", 2, 2),
    ]
    assert rows[("single", 1, None)]["x_single"] == rows[("async", 2, None)]["x_async2"] == 1.0
    for row in rows.values():
        assert row["steps_per_s"] > 0 and len(row["steps_per_s_rounds"]) >= 2
