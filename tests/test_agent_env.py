"""`hier_agents.baselines.impala.agent_env.AgentEnv`: inputs, action mapping, the auxiliary task."""

from __future__ import annotations


import numpy as np
import pytest
from fast_cover import cover

from abstract_planners.base import Subgoal
from abstract_planners.sokoban import DIRECTIONS
from hier_agents.baselines.impala.agent_env import (
    CONDITIONS,
    PLANNER_ACTIONS,
    AgentEnv,
    InputSpec,
    StepResult,
)
from skills.arm import ArmTouchSkill
from skills.ball import BallSkill


PROPRIO = {"mujoban": 25, "mujoxo": 39, "mujogo": 39}
CAMERAS = {
    "mujoban": ("top_camera", "walker/egocentric_camera"),
    "mujoxo": ("front_camera",),
    "mujogo": ("front_camera",),
}
CASES = (
    [("mujoban/level1", c, cams) for c in CONDITIONS for cams in (True, False)]
    + [("mujoxo/mixture", c, cams) for c in CONDITIONS for cams in (True, False)]
    + [
        ("mujogo/7x7", c, cams)  # these take the conftest's `gnugo` fixture
        for c, cams in (("vanilla", True), ("expert-planner", False), ("random-planner", False))
    ]
)


def _check_obs(env: AgentEnv, obs: dict) -> None:
    spec = env.input_spec
    expected = {"proprio"} | {name for name, _ in spec.images}
    if spec.planner_shape is not None:
        expected.add("planner")
    if spec.planner_action_dim:
        expected.add("planner_action")
    if spec.state_shape is not None:
        expected.add("state")
    assert set(obs) == expected
    assert obs["proprio"].shape == (spec.proprio_dim,) and obs["proprio"].dtype == np.float32
    assert np.all(np.isfinite(obs["proprio"]))
    for name, shape in spec.images:
        assert obs[name].shape == shape and obs[name].dtype == np.uint8
        assert obs[name].flags.c_contiguous and obs[name].any()
    if spec.planner_shape is not None:
        assert obs["planner"].shape == spec.planner_shape and obs["planner"].dtype == np.float32
        assert set(np.unique(obs["planner"])) <= {0.0, 1.0}
    if spec.planner_action_dim:
        one_hot = obs["planner_action"]
        assert one_hot.shape == (spec.planner_action_dim,) and one_hot.dtype == np.float32


@pytest.mark.parametrize(
    "name, condition, cameras",
    cover(CASES, lambda name, condition, cameras: [(name, cameras), ("condition", condition)]),
)
def test_input_spec_and_observations(name, condition, cameras, request):
    fam = name.split("/")[0]
    if fam == "mujogo":
        request.getfixturevalue("gnugo")
    with AgentEnv(name, condition, seed=0, cameras=cameras, image_size=32) as env:
        spec = env.input_spec
        assert isinstance(spec, InputSpec) and env.family == fam
        assert spec.images == (tuple((cam, (3, 32, 32)) for cam in CAMERAS[fam]) if cameras else ())
        assert spec.proprio_dim == PROPRIO[fam]
        assert spec.action_dim == (2 if fam == "mujoban" else 9)
        if condition == "vanilla":
            assert spec.planner_shape is None and spec.planner_action_dim == 0
            assert env.planner is None
        elif fam == "mujoban":
            assert spec.planner_shape == (8, 10, 10) and spec.planner_action_dim == 4
        else:
            n = 3 if fam == "mujoxo" else 7
            assert spec.planner_shape == (6, n, n) and spec.planner_action_dim == 0
        assert (env.gamma_env, env.gamma_abs) == ((0.99, 0.9) if fam == "mujoban" else (0.99, 0.98))
        obs = env.reset()
        _check_obs(env, obs)
        if condition != "vanilla":
            planes = obs["planner"]
            c = planes.shape[0] // 2
            if fam == "mujoban":  # walls and pads do not move; one player each half
                assert np.array_equal(planes[0:2], planes[c : c + 2])
                assert planes[2].sum() == planes[c + 2].sum() == 1
                assert obs["planner_action"].sum() == 1.0
            else:  # an empty board and the target with one own piece on it
                assert planes[0].all() and planes[1:3].sum() == 0
                assert planes[c + 1].sum() == 1 and planes[c + 2].sum() == 0
        result = env.step(np.zeros(spec.action_dim, np.float32))
        assert isinstance(result, StepResult)
        _check_obs(env, result.obs)
        assert not result.last and result.info == {}
        assert result.discount_env == pytest.approx(env.gamma_env)


def test_actions_are_clipped_and_mapped_onto_the_bounds():
    for name in ("mujoxo/mixture", "mujoban/level1"):
        with AgentEnv(name, seed=0, cameras=False) as env:
            seen = []
            inner = env.env.step

            def spy(action, inner=inner, seen=seen):
                seen.append(np.array(action, copy=True))
                return inner(action)

            env.env.step = spy
            env.reset()
            spec = env.env.action_spec()
            low, high = spec.minimum * np.ones(spec.shape), spec.maximum * np.ones(spec.shape)
            a = np.linspace(-3.0, 3.0, spec.shape[0]).astype(np.float32)
            env.step(a)
            clipped = np.clip(a.astype(np.float64), -1, 1)
            assert np.allclose(seen[-1], low + (clipped + 1) / 2 * (high - low))
            env.step(np.full(spec.shape, 7.0))
            assert np.allclose(seen[-1], high)
            env.step(-np.ones(spec.shape))
            assert np.allclose(seen[-1], low)
            env.step(np.zeros(spec.shape))
            assert np.allclose(seen[-1], (low + high) / 2)
            with pytest.raises(ValueError, match="shape"):
                env.step(np.zeros(spec.shape[0] + 1))


def _moved(state, move):
    """The player's and (for a push) the box's cells before and after ``move``."""
    dr, dc = DIRECTIONS[move]
    r, c = state.player
    ahead = (r + dr, c + dc)
    return ahead, ahead in state.boxes, (r + 2 * dr, c + 2 * dc)


# A walk, then pushes to the right: player at row 4, column 1, the box at
# column 3, its pad at column 7.
CORRIDOR_ROOM = """; 0
##########
#        #
#        #
#        #
#@ $   . #
#        #
#        #
#        #
#        #
##########
"""


def test_mujoban_expert_target_reached_by_the_ball_skill_pays_the_auxiliary_reward(tmp_path):
    levels = tmp_path / "room.txt"
    levels.write_text(CORRIDOR_ROOM)
    with AgentEnv(
        "mujoban/level1",
        "expert-planner",
        seed=0,
        cameras=False,
        t_abs=200,
        abs_reward=2.5,
        levels=str(levels),
    ) as env:
        obs = env.reset()
        for expect_push in (False, True):  # a walk, then a push
            state, subgoal = env.abstract_state, env.subgoal
            move = subgoal.action
            assert move == "R"
            assert obs["planner_action"].tolist() == [float(m == move) for m in PLANNER_ACTIONS]
            # The target half is the current half with exactly the move applied.
            cur, tgt = obs["planner"][:4], obs["planner"][4:]
            assert np.array_equal(cur[:2], tgt[:2])
            ahead, push, beyond = _moved(state, move)
            assert push == expect_push
            assert np.array_equal(np.argwhere(cur[2]), [state.player])
            assert np.array_equal(np.argwhere(tgt[2]), [ahead])
            diff_boxes = {tuple(x) for x in np.argwhere(cur[3] != tgt[3])}
            assert diff_boxes == ({ahead, beyond} if push else set())
            skill = BallSkill()
            scene = env.estimator.estimate(env.timestep)
            assert scene.state == state
            skill.reset(env.env.description(), subgoal, scene)
            for step in range(1, 201):  # noqa: B007 - read after the loop
                result = env.step(skill.act(env.timestep, env.estimator.estimate(env.timestep)))
                if result.discount_abs == 0.0:
                    break
                assert result.reward_abs == 0.0 and result.discount_abs == pytest.approx(0.9)
            assert not result.last
            assert result.reward_abs == 2.5 and step < 200
            boxes, player = env.env.task.abstract_cells
            assert player == subgoal.state.player and frozenset(boxes) == subgoal.state.boxes
            obs = result.obs
            assert env.abstract_state == subgoal.state  # the next sub-episode starts here
            assert np.array_equal(obs["planner"][:4], tgt)


def test_mujoban_solved_abstract_state_has_no_target():
    # Seed 0's first level is one push; the box rounds onto its pad's cell a
    # few steps before it covers the pad and ends the episode.
    with AgentEnv("mujoban/level1", "expert-planner", seed=0, cameras=False) as env:
        env.reset()
        skill = BallSkill()
        skill.reset(env.env.description(), env.subgoal, env.estimator.estimate(env.timestep))
        rewards = []
        for _ in range(200):
            result = env.step(skill.act(env.timestep, env.estimator.estimate(env.timestep)))
            rewards.append(result.reward_abs)
            if env.subgoal is None and not result.last:
                planes = result.obs["planner"]
                assert np.array_equal(planes[:4], planes[4:])
                assert not result.obs["planner_action"].any()
            if result.last:
                break
        assert result.last and result.discount_abs == 0.0
        assert rewards.count(1.0) == 1
        info = result.info
        assert info["success"] and info["subgoals_issued"] == 1
        assert info["subgoals_reached"] == 1 and info["subgoals_unplanned"] == 1


def test_an_impossible_estimate_gives_no_target_instead_of_an_error(monkeypatch):
    # Random physics can round the walker onto a box's cell (or two boxes into
    # one); the estimator refuses such a board and the sub-episode has no target.
    rng = np.random.default_rng(0)
    with AgentEnv("mujoban/level1", "expert-planner", seed=2, cameras=False, t_abs=4) as env:
        env.reset()

        def refuse(*args, **kwargs):
            raise ValueError("player at (4, 4) is on a box")

        monkeypatch.setattr(env.estimator, "estimate", refuse)
        for _ in range(12):
            result = env.step(rng.uniform(-1, 1, 2))
            if result.last:
                break
        assert env.subgoal is None and env.abstract_state is None
        planes = result.obs["planner"]
        assert np.array_equal(planes[:4], planes[4:]) and not result.obs["planner_action"].any()
        assert result.reward_abs == 0.0


def test_subepisodes_time_out_after_t_abs_steps_with_random_actions():
    rng = np.random.default_rng(0)
    with AgentEnv(
        "mujoban/level1", "expert-planner", seed=1, cameras=False, t_abs=6, time_limit=1.5
    ) as env:
        env.reset()
        targets, results = [env.subgoal], []
        for _ in range(30):
            results.append(env.step(rng.uniform(-1, 1, 2)))
            targets.append(env.subgoal)
        assert results[-1].last
        for k, result in enumerate(results, start=1):
            assert result.reward_abs == 0.0
            if k % 6 == 0 or k == 30:
                assert result.discount_abs == 0.0
            else:
                assert result.discount_abs == pytest.approx(0.9)
                assert targets[k] is targets[k - 1]  # the target holds within a sub-episode
        info = results[-1].info
        assert info["subgoals_issued"] == 5 and info["subgoals_reached"] == 0
        assert info["episode_steps"] == 30 and info["truncated"]


def test_board_target_move_pays_the_auxiliary_reward_and_another_move_does_not():
    with AgentEnv(
        "mujoxo/mixture", "expert-planner", seed=0, cameras=False, t_abs=300, abs_reward=1.5
    ) as env:
        spec = env.env.action_spec()
        low, high = spec.minimum, spec.maximum
        task = env.env.task
        obs = env.reset()
        skill = ArmTouchSkill()

        def touch(action):
            state = env.abstract_state
            scene = env.estimator.estimate(env.timestep)
            skill.reset(env.env.description(), Subgoal(action, state.child(action)), scene)
            for _ in range(300):
                a = skill.act(env.timestep, env.estimator.estimate(env.timestep))
                result = env.step((a - (low + high) / 2) / ((high - low) / 2))
                if result.discount_abs == 0.0:
                    return result
                assert result.reward_abs == 0.0
                assert result.discount_abs == pytest.approx(0.98)
            raise AssertionError("no move registered")

        target = int(env.subgoal.action)
        assert obs["planner"][4][divmod(target, 3)] == 1.0  # own piece in the target half
        result = touch(target)
        assert task.moves_registered == 1 and task.moves[0] == target
        assert result.reward_abs == 1.5 and not result.last
        # The new sub-episode starts from the board with both replies on it.
        assert result.obs["planner"][1].sum() == 1 and result.obs["planner"][2].sum() == 1
        wrong = next(a for a in env.abstract_state.legal_actions() if a != int(env.subgoal.action))
        result = touch(wrong)
        assert task.moves[2] == wrong
        assert result.reward_abs == 0.0 and result.discount_abs == 0.0


def test_vanilla_has_no_auxiliary_task_and_ends_episodes_with_discount_zero():
    with AgentEnv("mujoban/level1", "vanilla", seed=0, cameras=False, time_limit=1.0) as env:
        with pytest.raises(RuntimeError, match="reset"):
            env.step(np.zeros(2))
        obs = env.reset()
        assert set(obs) == {"proprio"}
        rng = np.random.default_rng(0)
        for k in range(1, 21):
            result = env.step(rng.uniform(-1, 1, 2))
            assert result.reward_abs == 0.0 and result.discount_abs == 0.0
            if k < 20:
                assert not result.last and result.discount_env == pytest.approx(0.99)
        assert result.last and result.discount_env == 0.0
        info = result.info
        assert info["episode_steps"] == 20 and info["truncated"] and not info["success"]
        assert set(info) >= {"episode_return", "episode_steps", "success"}
        assert "subgoals_issued" not in info
        with pytest.raises(RuntimeError, match="reset"):
            env.step(np.zeros(2))
        env.reset()
        assert not env.step(np.zeros(2)).last


def test_same_seed_same_observations():
    def run(seed):
        rng = np.random.default_rng(5)
        out = []
        with AgentEnv(
            "mujoban/level1", "random-planner", seed=seed, cameras=False, t_abs=4, time_limit=0.75
        ) as env:
            out.append(env.reset())
            for _ in range(25):  # crosses an episode boundary (15 steps)
                result = env.step(rng.uniform(-1, 1, 2))
                out.append(result.obs)
                if result.last:
                    out.append(env.reset())
        return out

    a, b = run(3), run(3)
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x.keys() == y.keys()
        for k in x:
            assert np.array_equal(x[k], y[k])


def test_a_held_action_renders_one_frame_and_sees_what_rendering_every_step_sees(monkeypatch):
    """Camera frames render only when the agent reads them (``lazy_cameras``,
    `AgentEnv`'s default): with each action held 3 control steps, one frame
    per agent step, and the same observations as rendering at every step."""
    from envs.core import Environment

    renders = {"count": 0}
    original = Environment._render_camera

    def counted(self, name, stamp):
        renders["count"] += 1
        return original(self, name, stamp)

    monkeypatch.setattr(Environment, "_render_camera", counted)

    def run(**overrides):
        rng = np.random.default_rng(2)
        with AgentEnv(
            "mujoban/level1",
            "vanilla",
            seed=4,
            image_size=16,
            action_repeat=3,
            **{"egocentric_camera": None, **overrides},
        ) as env:
            out = [env.reset()]
            out += [env.step(rng.uniform(-1, 1, 2)).obs for _ in range(6)]
        return out

    lazy = run()
    assert renders["count"] == 7  # the first observation and one per agent step
    eager = run(lazy_cameras=False)
    assert renders["count"] == 7  # rendered as each step's observation was built instead
    for x, y in zip(lazy, eager, strict=True):
        assert x.keys() == y.keys() and "top_camera" in x
        for k in x:
            assert np.array_equal(x[k], y[k]), k


def test_unknown_condition_or_family_raises_value_error():
    with pytest.raises(ValueError, match="expert-planner") as error:
        AgentEnv("mujoban/level1", "oracle")
    for condition in CONDITIONS:
        assert condition in str(error.value)
    with pytest.raises(ValueError, match="mujoban"):
        AgentEnv("cartpole/swingup")


@pytest.mark.parametrize(
    "name, key", [("mujoban/level1", "full_entity_layer"), ("mujoxo/mixture", "board_state")]
)
@pytest.mark.parametrize("condition", ["vanilla", "expert-planner"])
def test_state_input_is_the_current_abstract_state_at_every_step(name, key, condition):
    with AgentEnv(name, condition, seed=3, cameras=False, state=True) as env:
        obs = env.reset()
        _check_obs(env, obs)
        c = env.input_spec.state_shape[0]
        rng = np.random.default_rng(0)
        for _ in range(60):
            truth = env.timestep.observation[key].transpose(2, 0, 1)
            assert obs["state"].shape == (c, *truth.shape[1:]) and obs["state"].dtype == np.float32
            np.testing.assert_array_equal(obs["state"], truth)
            result = env.step(rng.uniform(-1, 1, env.input_spec.action_dim))
            obs = result.obs
            if result.last:
                obs = env.reset()
    with AgentEnv(name, condition, seed=3, cameras=False) as env:
        assert env.input_spec.state_shape is None and "state" not in env.reset()


def test_action_repeat_holds_each_action_until_the_episode_or_subepisode_ends():
    rng = np.random.default_rng(3)
    kwargs = dict(seed=0, cameras=False, time_limit=1.0)  # 20 control steps
    with (
        AgentEnv("mujoban/level1", "vanilla", action_repeat=3, **kwargs) as held,
        AgentEnv("mujoban/level1", "vanilla", **kwargs) as single,
    ):
        held.reset(), single.reset()
        for k in range(7):  # 6 holds of 3 control steps, the last cut to 2 by the episode's end
            action = rng.uniform(-1, 1, 2)
            result = held.step(action)
            steps = [single.step(action) for _ in range(min(3, 20 - 3 * k))]
            assert result.reward_env == pytest.approx(sum(s.reward_env for s in steps))
            np.testing.assert_array_equal(result.obs["proprio"], steps[-1].obs["proprio"])
            assert result.last == (k == 6)
        assert result.discount_env == 0.0 and result.info["episode_steps"] == 20
    with AgentEnv("mujoban/level1", "expert-planner", t_abs=4, action_repeat=3, **kwargs) as env:
        env.reset()
        first = env.subgoal
        assert env.step(np.zeros(2)).discount_abs == pytest.approx(0.9)
        assert env.env.step_count == 3 and env.subgoal is first
        assert env.step(np.zeros(2)).discount_abs == 0.0  # the sub-episode's 4th step
        assert env.env.step_count == 4 and env.subgoal is not first
    with pytest.raises(ValueError, match="action_repeat"):
        AgentEnv("mujoban/level1", action_repeat=0, cameras=False)


@pytest.mark.parametrize(
    "name, condition", [("mujoban/level1", "expert-planner"), ("mujoxo/optimal", "vanilla")]
)
def test_stepping_all_at_once_gives_what_stepping_each_gives(name, condition):
    """`step_all` with two physics threads: the `StepResult` s of each
    environment's own `AgentEnv.step`, action repeat, auxiliary sub-episode
    ends and episode ends (a 3 s time limit) included."""
    from envs.vector import PhysicsPool
    from hier_agents.baselines.impala.agent_env import step_all

    def build():
        return [
            AgentEnv(
                name,
                condition,
                seed=s,
                cameras=False,
                state=True,
                action_repeat=3,
                t_abs=7,
                time_limit=3.0,
            )
            for s in range(3)
        ]

    alone, together, pool = build(), build(), PhysicsPool(2)
    rng = np.random.default_rng(0)
    try:
        for env in alone + together:
            env.reset()
        ends = 0
        for _ in range(40):
            actions = rng.uniform(-1, 1, (3, alone[0].input_spec.action_dim))
            expected = [env.step(a) for env, a in zip(alone, actions)]
            got = step_all(together, actions, pool)
            for e, g in zip(expected, got):
                assert (e.reward_env, e.discount_env, e.reward_abs, e.discount_abs, e.last) == (
                    g.reward_env,
                    g.discount_env,
                    g.reward_abs,
                    g.discount_abs,
                    g.last,
                )
                assert e.info == g.info
                for key in e.obs:
                    np.testing.assert_array_equal(e.obs[key], g.obs[key])
            for i, result in enumerate(expected):
                if result.last:
                    ends += 1
                    alone[i].reset()
                    together[i].reset()
        assert ends >= 3
        with pytest.raises(RuntimeError, match="reset"):
            fresh = build()
            try:
                step_all(fresh, actions, pool)
            finally:
                for env in fresh:
                    env.close()
    finally:
        pool.close()
        for env in alone + together:
            env.close()
