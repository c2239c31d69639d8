"""The RL option layer (issue 15, item 3): `hier_agents.learning.train_options` and the
planner that plays its policy (`abstract_planners.learned_options`)."""

from __future__ import annotations

import json
import random

import numpy as np
import pytest
import torch

from abstract_planners.learned_options import (
    SHIPPED,
    OptionPolicyNet,
    OptionPolicyPlanner,
    encode_state,
    load_option_policy,
    policy_input,
    save_option_policy,
)
from abstract_planners.sokoban import MOVES, SokobanState
from envs.mujoban import generator
from hier_agents.learning import train_options
from hier_agents.learning.ppo import gae
from hier_agents.modular.components import PLANNERS, make_agent
from hier_agents.learning.option_env import encode_sokoban


def _random_states(count: int, seed: int = 0):
    """States of generated levels 1-5 (padded into the 10x10 arena) after
    random legal moves."""
    rng = np.random.default_rng(seed)
    pick = random.Random(seed)
    states = []
    while len(states) < count:
        level = generator.generate_level(int(rng.integers(1, 6)), rng=rng).padded(10, 10)
        state = SokobanState.from_level(level)
        for _ in range(pick.randrange(0, 30)):
            if state.is_solved() or not state.legal_moves():
                break
            state = state.apply(pick.choice(state.legal_moves()))
        if not state.is_solved() and state.legal_moves():
            states.append(state)
    return states


def _random_policy(path, seed: int = 0):
    """A policy file with random weights and a confident (non-uniform) head."""
    torch.manual_seed(seed)
    net = OptionPolicyNet()
    torch.nn.init.normal_(net.policy.weight, std=1.0)
    save_option_policy(net, path, grid_shape=(10, 10), meta={"test": True})
    return path


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A few PPO updates: an abstract warm start, then OptionEnv (camera, learned ball)."""
    logdir = tmp_path_factory.mktemp("options_run")
    code = train_options.main(
        [
            "mujoban/level1",
            "--option-steps",
            "32",
            "--envs",
            "1",
            "--rollout",
            "16",
            "--sync",
            "--abstract-steps",
            "256",
            "--abstract-envs",
            "4",
            "--seed",
            "3",
            "--eval-episodes",
            "0",
            "--logdir",
            str(logdir),
        ]
    )
    assert code == 0
    return logdir


def test_tiny_run_writes_a_checkpoint_and_a_summary_with_its_counts(tiny_run):
    summary = json.loads((tiny_run / "summary.json").read_text())
    assert summary["option_steps"] == 32 and summary["abstract_steps"] == 256
    # Control frames are environment frames: at least one per option step.
    assert summary["control_frames"] >= summary["option_steps"]
    assert summary["cpu_s"] > 0 and summary["seed"] == 3
    assert summary["skill"]["name"] == "learned-ball"
    assert summary["skill"]["training_frames"] and summary["skill"]["training_frames"] > 0
    assert summary["estimator"] == "camera" and not summary["privileged"]
    assert "train_options" in summary["command"]
    data = torch.load(tiny_run / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert data["state"]["control_frames"] == summary["control_frames"]
    assert data["policy"]["meta"]["option_steps"] == 32
    rows = [json.loads(line) for line in (tiny_run / "scalars.jsonl").read_text().splitlines()]
    # One line per update: 256 // 64 abstract, then 32 // 16 option updates.
    assert [row["phase"] for row in rows] == ["abstract"] * 4 + ["options"] * 2
    assert [row["step"] for row in rows] == [64, 128, 192, 256, 272, 288]
    config = json.loads((tiny_run / "config.json").read_text())
    assert config["option_steps"] == 32 and config["seed"] == 3
    assert list(tiny_run.glob("events.out.tfevents.*")), "no TensorBoard event file"


def test_the_trained_policy_plays_a_level1_episode_as_a_planner(tiny_run):
    from hier_agents.run import run

    for path in (tiny_run, tiny_run / "option_policy.pt", tiny_run / "checkpoint.pt"):
        summary = run(
            "mujoban/level1",
            1,
            seed=5,
            planner=f"learned:{path}",
            skill="learned-ball",
            progress=False,
        )
        assert summary["planner"] == f"learned:{path}"
        assert summary["episodes"] == 1 and "error" not in summary["rows"][0]
        assert summary["subgoals"]["issued"] >= 1


@pytest.mark.slow
def test_resume_continues_counting_frames_and_cpu(tiny_run, tmp_path):
    import shutil

    logdir = tmp_path / "resumed"
    shutil.copytree(tiny_run, logdir)
    before = json.loads((logdir / "summary.json").read_text())
    # The default AsyncVectorEnv (one worker process) this time.
    assert (
        train_options.main(
            [
                "mujoban/level1",
                "--option-steps",
                "48",
                "--envs",
                "1",
                "--rollout",
                "16",
                "--abstract-steps",
                "256",
                "--resume",
                "--seed",
                "3",
                "--eval-episodes",
                "0",
                "--logdir",
                str(logdir),
            ]
        )
        == 0
    )
    after = json.loads((logdir / "summary.json").read_text())
    assert after["option_steps"] == 48 and after["abstract_steps"] == 256
    assert after["control_frames"] > before["control_frames"]
    assert after["cpu_s"] > before["cpu_s"]
    assert len(after["commands"]) == 2 and "--resume" in after["commands"][1]


def test_the_planner_only_ever_proposes_legal_moves(tmp_path):
    path = _random_policy(tmp_path / "policy.pt")
    greedy = OptionPolicyPlanner(path)
    sampled = OptionPolicyPlanner(path, greedy=False, seed=1)
    for state in _random_states(150):
        for planner in (greedy, sampled):
            subgoal = planner.plan(state)
            (move,) = subgoal.action
            assert state.is_legal(move)
            assert subgoal.state == state.apply(move) and subgoal.plan == ()
        probs = greedy.probabilities(state)
        for move, p in zip(MOVES, probs):
            assert state.is_legal(move) or p == 0.0
        assert probs.sum() == pytest.approx(1.0)


def test_sampling_is_seeded_and_greedy_is_deterministic(tmp_path):
    path = _random_policy(tmp_path / "policy.pt")
    states = _random_states(30, seed=2)
    a, b = (
        OptionPolicyPlanner(path, greedy=False, seed=4),
        OptionPolicyPlanner(path, greedy=False, seed=4),
    )
    assert [a.plan(s).action for s in states] == [b.plan(s).action for s in states]
    g = OptionPolicyPlanner(path)
    assert [g.plan(s).action for s in states] == [g.plan(s).action for s in states]


def test_bad_checkpoints_fail_with_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="no option-policy checkpoint"):
        OptionPolicyPlanner(tmp_path / "missing.pt")
    with pytest.raises(FileNotFoundError, match="no option_policy.pt"):
        OptionPolicyPlanner(tmp_path)  # an empty directory
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="not a readable torch checkpoint"):
        OptionPolicyPlanner(garbage)
    other = tmp_path / "other.pt"
    torch.save({"actor": {}, "meta": {}}, other)  # e.g. a ball-skill policy
    with pytest.raises(ValueError, match="not an option-policy checkpoint"):
        OptionPolicyPlanner(other)
    broken = tmp_path / "broken.pt"
    data = torch.load(_random_policy(tmp_path / "ok.pt"), weights_only=True)
    data["net"]["hidden"] = 64
    torch.save(data, broken)
    with pytest.raises(ValueError, match="do not fit"):
        OptionPolicyPlanner(broken)
    from envs import load

    env = load("mujoban/level1", top_camera=None, egocentric_camera=None)
    try:
        with pytest.raises(FileNotFoundError, match="missing.pt"):
            make_agent(
                "mujoban/level1", env.description(), planner=f"learned:{tmp_path / 'missing.pt'}"
            )
        with pytest.raises(ValueError, match="learned:PATH"):
            make_agent("mujoban/level1", env.description(), planner="learnt")
    finally:
        env.close()


def test_a_grid_the_policy_was_not_trained_on_is_refused(tmp_path):
    planner = OptionPolicyPlanner(_random_policy(tmp_path / "policy.pt"))
    small = SokobanState.from_level(generator.generate_level(2, rng=np.random.default_rng(0)))
    with pytest.raises(ValueError, match="trained on 10x10"):
        planner.plan(small)


def test_planner_names_resolve():
    table = PLANNERS["mujoban"]
    assert "learned" in table and "learned:/some/run" in table
    assert "learned:" not in table and "learnt" not in table
    assert "learned:/x" not in PLANNERS["mujoxo"]


@pytest.mark.skipif(not SHIPPED.exists(), reason="no shipped policy")
def test_the_shipped_policy_loads_and_is_small():
    net, data = load_option_policy(SHIPPED)
    assert SHIPPED.stat().st_size < 400_000
    assert data["meta"]["trained_with"].endswith("train_options")
    assert data["meta"]["control_frames"] > 0
    state = _random_states(1)[0]
    (move,) = OptionPolicyPlanner().plan(state).action
    assert state.is_legal(move)


def test_the_planner_encodes_states_as_option_env_does():
    for state in _random_states(20, seed=3):
        np.testing.assert_array_equal(
            encode_state(state, (10, 10)), encode_sokoban(state, (10, 10))
        )


def test_policy_input_is_centred_on_the_player_with_walls_off_the_grid():
    state = SokobanState.from_text("#####\n#@$.#\n#####")
    x = policy_input(encode_state(state, (3, 5)), radius=3)
    assert x.shape == (1, 5, 7, 7)
    assert x[0, 3, 3, 3] == 1.0  # the player in the centre
    assert x[0, 2, 3, 4] == 1.0 and x[0, 1, 3, 5] == 1.0  # box right, pad two right
    assert x[0, 0, 0, 0] == 1.0  # off the grid: wall
    assert x[0, 4].sum() == 0.0  # no box on a pad yet


def test_semi_mdp_gae_discounts_by_duration_and_stops_at_episode_ends():
    rewards = torch.tensor([[1.0], [0.0], [2.0]])
    values = torch.tensor([[0.5], [0.25], [1.0]])
    discounts = torch.tensor([[0.5], [0.9], [0.8]])  # gamma ** duration per option
    dones = torch.tensor([[0.0], [1.0], [0.0]])
    next_value = torch.tensor([3.0])
    adv, returns = gae(rewards, values, discounts, dones, next_value, lam=1.0)
    # lambda = 1: discounted returns; the episode ends after the second option.
    assert returns[2, 0].item() == pytest.approx(2.0 + 0.8 * 3.0)
    assert returns[1, 0].item() == pytest.approx(0.0)
    assert returns[0, 0].item() == pytest.approx(1.0 + 0.5 * 0.0)
    assert torch.allclose(adv, returns - values)


def test_shaping_potential_rewards_pushing_towards_a_pad():
    state = SokobanState.from_text("######\n#@$ .#\n######")
    nearer = state.apply("R")
    assert train_options.potential(nearer, 1.0, 0.1) > train_options.potential(state, 1.0, 0.1)
    solved = nearer.apply("R")
    assert solved.is_solved() and train_options.potential(solved, 1.0, 0.1) == 0.0


def test_dead_cells_and_pruned_pushes():
    from abstract_planners.learned_options import dead_push_mask, live_cells

    state = SokobanState.from_text("######\n#    #\n# @$.#\n#    #\n######")
    live = live_cells(state)
    # Only the pad's row: from anywhere else no push reaches it (walls behind).
    assert live == {(2, 2), (2, 3), (2, 4)}
    # Pushing the box up from below puts it on the dead top row: pruned.
    below = state.with_player((3, 3))
    legal = np.array([below.is_legal(m) for m in MOVES], np.float32)
    pruned = dead_push_mask(below, legal)
    assert legal[MOVES.index("U")] == 1 and pruned[MOVES.index("U")] == 0
    assert pruned[MOVES.index("L")] == 1 and pruned[MOVES.index("R")] == 1
    # Only moves left are dead pushes: the mask is left as it was.
    corridor = SokobanState.from_text("#####\n#@$ #\n###.#")
    legal = np.array([corridor.is_legal(m) for m in MOVES], np.float32)
    assert (dead_push_mask(corridor, legal) == legal).all()


def test_pruning_follows_the_checkpoint_and_never_proposes_dead_pushes(tmp_path):
    from abstract_planners.learned_options import live_cells

    path = _random_policy(tmp_path / "policy.pt")
    assert not OptionPolicyPlanner(path).prune_dead
    data = torch.load(path, weights_only=True)
    data["meta"]["prune_dead_pushes"] = True
    torch.save(data, tmp_path / "pruned.pt")
    planner = OptionPolicyPlanner(tmp_path / "pruned.pt")
    assert planner.prune_dead
    for state in _random_states(100, seed=5):
        subgoal = planner.plan(state)
        (move,) = subgoal.action
        assert state.is_legal(move)
        new_boxes = subgoal.state.boxes - state.boxes
        alternatives = [
            m
            for m in MOVES
            if state.is_legal(m)
            and not (
                state.is_push(m) and not (state.apply(m).boxes - state.boxes) <= live_cells(state)
            )
        ]
        if new_boxes and alternatives:
            assert new_boxes <= live_cells(state)


def test_help_shows_every_default_and_the_option_steps_budget(capsys):
    with pytest.raises(SystemExit):
        train_options.parse_args(["--help"])
    out = capsys.readouterr().out
    assert "--option-steps" in out and "--steps " not in out
    assert "(default: 64)" in out and "(default: 0.995)" in out


def test_the_shaped_wrapper_adds_the_semi_mdp_potential_difference():
    env = train_options.AbstractOptionEnv("mujoban/level1", seed=0, duration=18, gamma=0.9)
    shaped = train_options.Shaped(
        train_options.AbstractOptionEnv("mujoban/level1", seed=0, duration=18, gamma=0.9),
        1.0,
        0.1,
        "walk",
        gamma=0.9,
    )
    _, info = env.reset(seed=4)
    _, shaped_info = shaped.reset(seed=4)
    before = shaped_info["potential"]
    move = int(np.flatnonzero(info["action_mask"])[0])
    _, reward, terminated, _, _ = env.step(move)
    _, shaped_reward, _, _, after_info = shaped.step(move)
    after = 0.0 if terminated else after_info["potential"]
    assert shaped_reward == pytest.approx(reward + 0.9**18 * after - before)
