"""The IMPALA network: shapes for every environment's inputs, policy bounds, resets, act()."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from torch import nn

from hier_agents.baselines.impala.agent_env import InputSpec
from hier_agents.baselines.impala.network import (
    PLANNER_CHANNELS,
    ImpalaNet,
    NetOutput,
    PlannerEncoder,
    gaussian_entropy,
    gaussian_log_prob,
    net_for,
)

CAM = (3, 96, 96)
SPECS = {
    "mujoban-two-cameras": InputSpec(
        images=(("top_camera", CAM), ("egocentric_camera", CAM)),
        proprio_dim=25,
        planner_shape=(8, 10, 10),
        planner_action_dim=4,
        action_dim=2,
    ),
    "mujoban-one-camera": InputSpec(
        images=(("top_camera", CAM),),
        proprio_dim=25,
        planner_shape=(8, 10, 10),
        planner_action_dim=4,
        action_dim=2,
    ),
    "mujoban-no-camera": InputSpec(
        images=(), proprio_dim=25, planner_shape=(8, 10, 10), planner_action_dim=4, action_dim=2
    ),
    "mujoxo": InputSpec(
        images=(("front_camera", CAM),),
        proprio_dim=39,
        planner_shape=(6, 3, 3),
        planner_action_dim=0,
        action_dim=9,
    ),
    "mujogo-7x7": InputSpec(
        images=(), proprio_dim=39, planner_shape=(6, 7, 7), planner_action_dim=0, action_dim=9
    ),
    "vanilla": InputSpec(
        images=(("top_camera", CAM),),
        proprio_dim=25,
        planner_shape=None,
        planner_action_dim=0,
        action_dim=2,
    ),
}
#: A spec with every kind of input but small images (fast).
SMALL = InputSpec(
    images=(("cam", (3, 20, 28)),),
    proprio_dim=5,
    planner_shape=(4, 3, 3),
    planner_action_dim=4,
    action_dim=3,
)


def make_obs(spec: InputSpec, T: int, B: int, seed: int = 0) -> dict[str, torch.Tensor]:
    """Random observations ``[T, B, ...]`` matching ``spec``."""
    g = torch.Generator().manual_seed(seed)
    obs = {"proprio": 3.0 * torch.randn(T, B, spec.proprio_dim, generator=g)}
    for name, shape in spec.images:
        obs[name] = torch.randint(0, 256, (T, B, *shape), generator=g, dtype=torch.uint8)
    if spec.planner_shape is not None:
        obs["planner"] = (torch.rand(T, B, *spec.planner_shape, generator=g) < 0.3).float()
    if spec.planner_action_dim:
        idx = torch.randint(0, spec.planner_action_dim, (T, B), generator=g)
        obs["planner_action"] = nn.functional.one_hot(idx, spec.planner_action_dim).float()
    return obs


def _no_first(T: int, B: int) -> torch.Tensor:
    return torch.zeros(T, B, dtype=torch.bool)


@pytest.mark.parametrize("name", list(SPECS))
@pytest.mark.parametrize("two_values", [False, True])
def test_output_shapes_and_policy_bounds(name, two_values):
    torch.manual_seed(0)
    spec = SPECS[name]
    net = ImpalaNet(spec, two_values=two_values)
    T, B, A = 3, 2, spec.action_dim
    out, state = net(make_obs(spec, T, B), _no_first(T, B), net.initial_state(B))
    assert isinstance(out, NetOutput)
    assert out.mean.shape == out.std.shape == (T, B, A)
    assert out.value_env.shape == (T, B)
    if two_values:
        assert out.value_abs.shape == (T, B)
    else:
        assert out.value_abs is None
    assert [tuple(s.shape) for s in state] == [(B, 256), (B, 256), (B, 128), (B, 128)]
    assert [tuple(s.shape) for s in net.initial_state(B)] == [tuple(s.shape) for s in state]
    assert torch.all(out.mean.abs() <= 1.0)
    assert torch.all(out.std >= math.sqrt(0.1) - 1e-6) and torch.all(out.std <= 1.0 + 1e-6)
    assert all(torch.isfinite(x).all() for x in out if x is not None)


def test_policy_bounds_hold_when_the_heads_saturate():
    torch.manual_seed(0)
    net = ImpalaNet(SMALL, two_values=False)
    obs = make_obs(SMALL, 4, 3)
    for sign in (1.0, -1.0):
        with torch.no_grad():
            for head in (net.mean_head, net.variance_head):
                head.weight.fill_(0.0)
                head.bias.fill_(sign * 100.0)
        out, _ = net(obs, _no_first(4, 3))
        assert torch.allclose(out.mean, torch.full_like(out.mean, sign))
        expected_std = 1.0 if sign > 0 else math.sqrt(0.1)
        assert torch.allclose(out.std, torch.full_like(out.std, expected_std))


def test_the_resnet_follows_the_table_and_has_no_normalisation():
    net = ImpalaNet(SPECS["mujoban-two-cameras"], two_values=True)
    for encoder in net.image_encoders.values():
        assert encoder.feature_shape == (32, 12, 12)  # 96 -> 48 -> 24 -> 12
        convs = [m for m in encoder.resnet.modules() if isinstance(m, nn.Conv2d)]
        assert len(convs) == 3 * (1 + 2 * 2)  # per group: one conv + two blocks of two
        assert [c.out_channels for c in convs[::5]] == [16, 32, 32]
        assert all(c.kernel_size == (3, 3) for c in convs)
    norms = (nn.modules.batchnorm._NormBase, nn.LayerNorm, nn.GroupNorm, nn.LocalResponseNorm)
    for module in net.modules():
        assert not isinstance(module, norms), module
        assert "norm" not in type(module).__name__.lower(), module


def test_any_image_size_and_a_3x3_board_work():
    spec = InputSpec(
        images=(("cam", (3, 64, 80)),),
        proprio_dim=4,
        planner_shape=(6, 3, 3),
        planner_action_dim=0,
        action_dim=2,
    )
    net = ImpalaNet(spec, two_values=True)
    assert net.image_encoders["cam"].feature_shape == (32, 8, 10)
    out, _ = net(make_obs(spec, 2, 2), _no_first(2, 2))
    assert out.mean.shape == (2, 2, 2)


def test_planner_deduplication_is_exact():
    """Encoding only the distinct planner rows gives the same outputs and gradients."""
    torch.manual_seed(0)
    encoder = PlannerEncoder((4, 5, 5))
    distinct = (torch.rand(6, 4, 5, 5) < 0.4).float()
    planes = distinct[torch.randint(0, 6, (100,))]
    weights = torch.randn(100, 256)
    results = []
    for deduplicate in (True, False):
        encoder.deduplicate = deduplicate
        encoder.zero_grad()
        out = encoder(planes)
        (out * weights).sum().backward()
        results.append((out.detach(), [p.grad.clone() for p in encoder.parameters()]))
    (out_a, grads_a), (out_b, grads_b) = results
    torch.testing.assert_close(out_a, out_b)
    for a, b in zip(grads_a, grads_b):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5)


def test_first_resets_the_core_state_of_its_column_only():
    torch.manual_seed(0)
    net = ImpalaNet(SMALL, two_values=True)
    T, B, k = 6, 3, 3
    obs = make_obs(SMALL, T, B, seed=1)
    first = _no_first(T, B)
    first[k, 0] = True
    state = tuple(torch.randn_like(s) for s in net.initial_state(B))
    out, _ = net(obs, first, state)
    # Column 0 from step k equals a fresh run on obs[k:] (zero state).
    fresh, _ = net(
        {key: v[k:] for key, v in obs.items()}, _no_first(T - k, B), net.initial_state(B)
    )
    for full, new in zip(out, fresh):
        torch.testing.assert_close(full[k:, 0], new[:, 0], rtol=1e-5, atol=1e-6)
        # Column 1 was not reset: its carried state still matters.
        assert not torch.allclose(full[k:, 1], new[:, 1], atol=1e-4)


def test_forward_equals_stepping_one_observation_at_a_time():
    torch.manual_seed(0)
    net = ImpalaNet(SMALL, two_values=True)
    T, B = 5, 2
    obs = make_obs(SMALL, T, B, seed=2)
    first = _no_first(T, B)
    first[0] = True
    first[2, 1] = True
    out, final = net(obs, first, net.initial_state(B))
    state = tuple(torch.randn_like(s) for s in net.initial_state(B))  # reset at t=0 anyway
    for t in range(T):
        batch = {key: v[t].numpy() for key, v in obs.items()}
        actions, log_probs, state = net.act(batch, first[t].numpy(), state, deterministic=True)
        np.testing.assert_allclose(actions, out.mean[t].detach().numpy(), rtol=1e-5, atol=1e-6)
        expected = gaussian_log_prob(out.mean[t], out.std[t], out.mean[t]).detach().numpy()
        np.testing.assert_allclose(log_probs, expected, rtol=1e-5, atol=1e-5)
    for a, b in zip(state, final):
        torch.testing.assert_close(a, b.detach(), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("B", [1, 4])
def test_act_shapes_and_seeded_sampling(B):
    torch.manual_seed(0)
    net = ImpalaNet(SMALL, two_values=False)
    obs = {key: v[0].numpy() for key, v in make_obs(SMALL, 1, B, seed=3).items()}
    first = np.ones(B, dtype=bool)

    def sample(seed):
        generator = torch.Generator().manual_seed(seed)
        return net.act(obs, first, net.initial_state(B), generator=generator)

    a1, lp1, state = sample(7)
    a2, lp2, _ = sample(7)
    a3, _, _ = sample(8)
    assert a1.shape == (B, SMALL.action_dim) and a1.dtype == np.float32
    assert lp1.shape == (B,) and lp1.dtype == np.float32
    assert [tuple(s.shape) for s in state] == [(B, 256), (B, 256), (B, 128), (B, 128)]
    assert not any(s.requires_grad for s in state)
    np.testing.assert_array_equal(a1, a2)
    np.testing.assert_array_equal(lp1, lp2)
    assert not np.array_equal(a1, a3)
    # The log-probabilities are those of the sampled actions under the policy.
    out, _ = net(
        {k: torch.as_tensor(v)[None] for k, v in obs.items()}, torch.ones(1, B, dtype=torch.bool)
    )
    expected = gaussian_log_prob(out.mean[0], out.std[0], torch.from_numpy(a1))
    np.testing.assert_allclose(lp1, expected.detach().numpy(), rtol=1e-5, atol=1e-5)


def test_gaussian_helpers_match_torch_distributions():
    g = torch.Generator().manual_seed(0)
    mean = torch.randn(4, 3, 2, generator=g)
    std = 0.3 + torch.rand(4, 3, 2, generator=g)
    actions = torch.randn(4, 3, 2, generator=g)
    dist = torch.distributions.Normal(mean, std)
    torch.testing.assert_close(
        gaussian_log_prob(mean, std, actions), dist.log_prob(actions).sum(-1)
    )
    torch.testing.assert_close(gaussian_entropy(std), dist.entropy().sum(-1))


def test_a_spec_without_inputs_is_refused():
    with pytest.raises(ValueError, match="no input"):
        ImpalaNet(
            InputSpec(
                images=(), proprio_dim=0, planner_shape=None, planner_action_dim=0, action_dim=2
            ),
            two_values=False,
        )


def test_chained_value_core_equals_one_long_sequence():
    # Two consecutive unrolls of one stream in one batch (columns 0 and 1,
    # sharing the boundary observation) give the values of one long run.
    torch.manual_seed(0)
    net = ImpalaNet(SMALL, two_values=True)
    T = 4
    long_obs = make_obs(SMALL, 2 * T + 1, 1, seed=5)
    first = _no_first(2 * T + 1, 1)
    first[0] = True
    long_out, _ = net(long_obs, first, net.initial_state(1))
    _, policy_state = net({k: v[:T] for k, v in long_obs.items()}, first[:T], net.initial_state(1))
    obs = {k: torch.cat([v[: T + 1], v[T:]], dim=1) for k, v in long_obs.items()}
    state = tuple(torch.cat([z, p]) for z, p in zip(net.initial_state(1), policy_state))
    state = (
        torch.zeros(2, state[0].shape[1]),
        torch.zeros(2, state[1].shape[1]),
        state[2],
        state[3],
    )
    first2 = torch.cat([first[: T + 1], first[T:]], dim=1)
    out, new_state = net(obs, first2, state, value_state_after=T - 1, value_chain=[-1, 0])
    torch.testing.assert_close(out.value_env[:, 1], long_out.value_env[T:, 0])
    torch.testing.assert_close(out.value_abs[:, 0], long_out.value_abs[: T + 1, 0])
    torch.testing.assert_close(out.mean[:, 1], long_out.mean[T:, 0])
    # Without the chain the second column's values would differ.
    plain, _ = net(obs, first2, state)
    assert not torch.allclose(plain.value_env[:, 1], long_out.value_env[T:, 0])


def test_policy_only_act_matches_and_keeps_the_value_state():
    torch.manual_seed(1)
    net = ImpalaNet(SMALL, two_values=True)
    batch = {k: v[0].numpy() for k, v in make_obs(SMALL, 1, 3, seed=4).items()}
    state = tuple(torch.randn_like(s) for s in net.initial_state(3))
    first = np.zeros(3, bool)
    a_full, lp_full, s_full = net.act(batch, first, state, deterministic=True)
    a_pol, lp_pol, s_pol = net.act(batch, first, state, deterministic=True, policy_only=True)
    np.testing.assert_allclose(a_pol, a_full, rtol=1e-6)
    np.testing.assert_allclose(lp_pol, lp_full, rtol=1e-6)
    assert s_pol[0] is state[0] and s_pol[1] is state[1]
    torch.testing.assert_close(s_pol[2], s_full[2])


def test_the_planner_cache_follows_weight_updates():
    torch.manual_seed(2)
    net = ImpalaNet(SMALL, two_values=False)
    obs = make_obs(SMALL, 1, 2, seed=6)
    batch = {k: v[0].numpy() for k, v in obs.items()}
    state = net.initial_state(2)
    first = np.zeros(2, bool)
    before, _, _ = net.act(batch, first, state, deterministic=True)
    optimizer = torch.optim.SGD(net.parameters(), lr=0.5)
    out, _ = net(obs, torch.zeros(1, 2, dtype=torch.bool), state)
    out.mean.sum().backward()
    optimizer.step()
    after, _, _ = net.act(batch, first, state, deterministic=True)
    expected, _ = net(obs, torch.zeros(1, 2, dtype=torch.bool), state)
    np.testing.assert_allclose(after, expected.mean[0].detach().numpy(), rtol=1e-5, atol=1e-6)
    assert not np.allclose(after, before)


def test_state_channels_size_the_state_encoder_only():
    spec = InputSpec(
        images=(),
        proprio_dim=5,
        planner_shape=(4, 10, 10),
        planner_action_dim=4,
        action_dim=2,
        state_shape=(4, 10, 10),
    )
    slim = net_for(spec, {"condition": "expert-planner", "state_channels": 16})
    assert slim.state_encoder.conv.out_channels == 16
    assert slim.state_encoder.linear.in_features == 16 * 10 * 10
    assert slim.planner_encoder.conv.out_channels == PLANNER_CHANNELS  # the paper's
    assert slim.value_abs_head is not None
    obs = make_obs(spec, 3, 2)
    obs["state"] = (torch.rand(3, 2, 4, 10, 10) < 0.3).float()
    out, _ = slim(obs, _no_first(3, 2))
    assert out.mean.shape == (3, 2, 2)
    # A checkpoint's config from before the option: the paper's width, no auxiliary head.
    old = net_for(spec, {"condition": "vanilla"})
    assert old.state_encoder.conv.out_channels == PLANNER_CHANNELS
    assert old.value_abs_head is None
    with pytest.raises(ValueError, match="channels must be >= 1"):
        PlannerEncoder((4, 3, 3), channels=0)
