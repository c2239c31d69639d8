"""V-trace against its definition, and the one- and two-head IMPALA losses."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hier_agents.baselines.impala.agent_env import InputSpec
from hier_agents.baselines.impala.network import (
    ImpalaNet,
    NetOutput,
    gaussian_entropy,
    gaussian_log_prob,
)
from hier_agents.baselines.impala.vtrace import impala_loss, vtrace


def reference_vtrace(
    log_rhos, discounts, rewards, values, bootstrap, clip_rho, clip_pg_rho, clip_c
):
    """The definition, term by term, with plain loops (float64 numpy).

    v_s = V(x_s) + sum_{t=s}^{T-1} (prod_{i=s}^{t-1} gamma_i c_i) rhobar_t
          (r_t + gamma_t V(x_{t+1}) - V(x_t)),
    pg_s = min(clip_pg_rho, rho_s) (r_s + gamma_s v_{s+1} - V(x_s)), v_T = V(x_T).
    """
    T, B = values.shape
    vs = np.zeros((T, B))
    pg = np.zeros((T, B))
    for b in range(B):
        v = list(values[:, b]) + [bootstrap[b]]
        rho = [float(np.exp(x)) for x in log_rhos[:, b]]
        for s in range(T):
            total = v[s]
            for t in range(s, T):
                weight = 1.0
                for i in range(s, t):
                    weight *= discounts[i, b] * min(clip_c, rho[i])
                delta = min(clip_rho, rho[t]) * (rewards[t, b] + discounts[t, b] * v[t + 1] - v[t])
                total += weight * delta
            vs[s, b] = total
        for s in range(T):
            v_next = vs[s + 1, b] if s + 1 < T else bootstrap[b]
            pg[s, b] = min(clip_pg_rho, rho[s]) * (rewards[s, b] + discounts[s, b] * v_next - v[s])
    return vs, pg


def random_inputs(T=7, B=5, seed=0):
    rng = np.random.default_rng(seed)
    log_rhos = rng.normal(0.0, 1.0, (T, B))
    discounts = rng.choice([0.0, 0.5, 0.9, 0.99], size=(T, B))
    rewards = rng.normal(0.0, 1.0, (T, B))
    values = rng.normal(0.0, 1.0, (T, B))
    bootstrap = rng.normal(0.0, 1.0, B)
    return log_rhos, discounts, rewards, values, bootstrap


@pytest.mark.parametrize("clips", [(1.0, 1.0, 1.0), (2.0, 1.5, 0.5), (0.8, 1.0, 1.2)])
def test_vtrace_matches_its_definition(clips):
    clip_rho, clip_pg_rho, clip_c = clips
    inputs = random_inputs(seed=int(10 * sum(clips)))
    log_rhos, discounts = inputs[0], inputs[1]
    rhos = np.exp(log_rhos)
    # The inputs exercise both sides of the clips and terminations.
    assert (rhos > max(clips)).any() and (rhos < min(clips)).any()
    assert (discounts == 0).any()
    result = vtrace(
        *(torch.tensor(x, dtype=torch.float32) for x in inputs),
        clip_rho=clip_rho,
        clip_pg_rho=clip_pg_rho,
        clip_c=clip_c,
    )
    vs, pg = reference_vtrace(*inputs, clip_rho, clip_pg_rho, clip_c)
    np.testing.assert_allclose(result.vs.numpy(), vs, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(result.pg_advantages.numpy(), pg, rtol=1e-5, atol=1e-5)


def test_on_policy_vtrace_is_the_bootstrapped_n_step_return():
    _, discounts, rewards, values, bootstrap = random_inputs(T=9, B=4, seed=3)
    T, B = values.shape
    result = vtrace(
        torch.zeros(T, B),
        *(torch.tensor(x, dtype=torch.float32) for x in (discounts, rewards, values, bootstrap)),
    )
    returns = np.zeros((T, B))
    for b in range(B):
        for s in range(T):
            ret, scale = 0.0, 1.0
            for t in range(s, T):
                ret += scale * rewards[t, b]
                scale *= discounts[t, b]
            returns[s, b] = ret + scale * bootstrap[b]
    np.testing.assert_allclose(result.vs.numpy(), returns, rtol=1e-5, atol=1e-5)
    next_returns = np.concatenate([returns[1:], bootstrap[None]], axis=0)
    np.testing.assert_allclose(
        result.pg_advantages.numpy(),
        rewards + discounts * next_returns - values,
        rtol=1e-5,
        atol=1e-5,
    )


def test_vtrace_passes_no_gradient():
    log_rhos, discounts, rewards, values, bootstrap = (
        torch.tensor(x, dtype=torch.float32, requires_grad=True) for x in random_inputs()
    )
    result = vtrace(log_rhos, discounts, rewards, values, bootstrap)
    assert not result.vs.requires_grad and not result.pg_advantages.requires_grad


# -- the loss ---------------------------------------------------------------------------------


def synthetic(T=6, B=4, A=2, seed=0):
    """Leaf tensors standing in for network outputs, plus a batch of experience."""
    g = torch.Generator().manual_seed(seed)

    def leaf(*shape, scale=1.0):
        return (scale * torch.randn(*shape, generator=g)).requires_grad_()

    out = NetOutput(
        mean=leaf(T, B, A, scale=0.5),
        std=(0.4 + 0.5 * torch.rand(T, B, A, generator=g)).requires_grad_(),
        value_env=leaf(T, B),
        value_abs=leaf(T, B),
    )
    bootstrap = NetOutput(None, None, torch.randn(B, generator=g), torch.randn(B, generator=g))
    batch = dict(
        actions=torch.randn(T, B, A, generator=g),
        behaviour_log_probs=torch.randn(T, B, generator=g) - 2.0,
        rewards_env=torch.randn(T, B, generator=g),
        discounts_env=0.99 * (torch.rand(T, B, generator=g) > 0.2).float(),
        rewards_abs=(torch.rand(T, B, generator=g) > 0.7).float(),
        discounts_abs=0.9 * (torch.rand(T, B, generator=g) > 0.3).float(),
    )
    return out, bootstrap, batch


def _loss(out, bootstrap, b, **kw):
    return impala_loss(
        out,
        bootstrap,
        b["actions"],
        b["behaviour_log_probs"],
        b["rewards_env"],
        b["discounts_env"],
        b["rewards_abs"],
        b["discounts_abs"],
        **kw,
    )


def test_single_head_loss_is_the_usual_impala_loss():
    out, bootstrap, b = synthetic()
    out = out._replace(value_abs=None)
    baseline_cost, entropy_cost = 0.7, 0.01
    loss, stats = _loss(out, bootstrap, b, baseline_cost=baseline_cost, entropy_cost=entropy_cost)
    log_probs = gaussian_log_prob(out.mean, out.std, b["actions"])
    targets = vtrace(
        log_probs - b["behaviour_log_probs"],
        b["discounts_env"],
        b["rewards_env"],
        out.value_env,
        bootstrap.value_env,
    )
    expected = (
        -(log_probs * targets.pg_advantages).mean()
        + 0.5 * baseline_cost * ((targets.vs - out.value_env) ** 2).mean()
        - entropy_cost * gaussian_entropy(out.std).mean()
    )
    torch.testing.assert_close(loss, expected)
    assert "baseline_loss_abs" not in stats
    assert stats["loss"] == pytest.approx(float(expected.detach()), rel=1e-5)
    # The baseline gradient: baseline_cost * (V - vs) / N; vs itself is a constant target.
    loss.backward()
    N = out.value_env.numel()
    expected_grad = baseline_cost * (out.value_env - targets.vs).detach() / N
    torch.testing.assert_close(out.value_env.grad, expected_grad)


def test_two_head_loss_sums_both_policy_terms_and_both_baselines():
    out, bootstrap, b = synthetic(seed=1)
    entropy_cost = 0.02
    two, stats = _loss(out, bootstrap, b, entropy_cost=entropy_cost)
    # Each stream as a single-head loss: env as is, abs with its head in the env slot.
    env_only, _ = _loss(out._replace(value_abs=None), bootstrap, b, entropy_cost=entropy_cost)
    abs_out = out._replace(value_env=out.value_abs, value_abs=None)
    abs_boot = bootstrap._replace(value_env=bootstrap.value_abs)
    abs_only, _ = impala_loss(
        abs_out,
        abs_boot,
        b["actions"],
        b["behaviour_log_probs"],
        b["rewards_abs"],
        b["discounts_abs"],
        entropy_cost=entropy_cost,
    )
    entropy_term = -entropy_cost * gaussian_entropy(out.std).mean()
    torch.testing.assert_close(two, env_only + abs_only - entropy_term)
    assert {
        "baseline_loss_env",
        "baseline_loss_abs",
        "advantage_env",
        "advantage_abs",
        "rho",
        "entropy",
        "std",
        "pg_loss",
    } <= set(stats)
    assert all(isinstance(v, float) for v in stats.values())
    # Same gradients too.
    grads_two = torch.autograd.grad(two, [out.mean, out.std, out.value_env, out.value_abs])
    grads_sum = torch.autograd.grad(
        env_only + abs_only - entropy_term, [out.mean, out.std, out.value_env, out.value_abs]
    )
    for g1, g2 in zip(grads_two, grads_sum):
        torch.testing.assert_close(g1, g2)


@pytest.mark.parametrize("two_values", [False, True])
def test_gradients_reach_every_network_parameter(two_values):
    torch.manual_seed(0)
    spec = InputSpec(
        images=(("cam", (3, 16, 16)),),
        proprio_dim=5,
        planner_shape=(4, 3, 3),
        planner_action_dim=4,
        action_dim=2,
    )
    net = ImpalaNet(spec, two_values=two_values)
    T, B = 4, 3
    g = torch.Generator().manual_seed(0)
    obs = {
        "cam": torch.randint(0, 256, (T + 1, B, 3, 16, 16), generator=g, dtype=torch.uint8),
        "proprio": torch.randn(T + 1, B, 5, generator=g),
        "planner": torch.rand(T + 1, B, 4, 3, 3, generator=g),
        "planner_action": torch.eye(4)[torch.randint(0, 4, (T + 1, B), generator=g)],
    }
    first = torch.zeros(T + 1, B, dtype=torch.bool)
    first[0] = True
    out, _ = net(obs, first, net.initial_state(B))
    steps = NetOutput(*(None if x is None else x[:-1] for x in out))
    boot = NetOutput(*(None if x is None else x[-1] for x in out))
    _, _, b = synthetic(T=T, B=B, A=2, seed=2)
    loss, _ = _loss(steps, boot, b)
    loss.backward()
    for name, p in net.named_parameters():
        assert p.grad is not None and p.grad.abs().sum() > 0, name
    assert (net.value_abs_head is not None) == two_values


# -- PPO's ingredients: the clipped surrogate, normalised advantages ---------------------------


def _single(out):
    return out._replace(value_abs=None)


def test_clipped_surrogate_is_ppos_objective_on_vtrace_advantages():
    out, bootstrap, b = synthetic(seed=3)
    out, eps = _single(out), 0.2
    g = torch.Generator().manual_seed(3)
    near = gaussian_log_prob(out.mean, out.std, b["actions"]).detach()
    b["behaviour_log_probs"] = near + 0.3 * torch.randn(near.shape, generator=g)
    loss, stats = _loss(out, bootstrap, b, clip_ratio=eps, entropy_cost=0.0, baseline_cost=0.0)
    log_probs = gaussian_log_prob(out.mean, out.std, b["actions"])
    log_rhos = log_probs.detach() - b["behaviour_log_probs"]
    # The advantages carry no importance weight: the ratio weighs them.
    targets = vtrace(
        log_rhos, b["discounts_env"], b["rewards_env"], out.value_env, bootstrap.value_env
    )
    unweighted = targets.pg_advantages / torch.clamp(torch.exp(log_rhos), max=1.0)
    ratio = torch.exp(log_probs - b["behaviour_log_probs"])
    expected = -torch.minimum(
        ratio * unweighted, torch.clamp(ratio, 1 - eps, 1 + eps) * unweighted
    ).mean()
    torch.testing.assert_close(loss, expected)
    clipped = ((ratio.detach() - 1).abs() > eps).float().mean()
    assert stats["ratio_clipped_fraction"] == pytest.approx(float(clipped))
    assert 0 < stats["ratio_clipped_fraction"] < 1  # the case covers both branches


def test_clipped_surrogate_stops_the_gradient_beyond_the_clip():
    out, bootstrap, b = synthetic(seed=4)
    out = _single(out)
    log_probs = gaussian_log_prob(out.mean, out.std, b["actions"]).detach()
    # The actors' policy is the learner's at half the steps (ratio 1: the
    # plain policy gradient) and far below it at the others (ratio e^3).
    far = torch.zeros_like(log_probs, dtype=torch.bool)
    far[::2] = True
    b["behaviour_log_probs"] = torch.where(far, log_probs - 3.0, log_probs)
    b["rewards_env"] = torch.full_like(b["rewards_env"], 5.0)  # advantages > 0
    with torch.no_grad():
        out.value_env.fill_(0.0)
    loss, _ = _loss(out, bootstrap, b, clip_ratio=0.2, entropy_cost=0.0, baseline_cost=0.0)
    (grad,) = torch.autograd.grad(loss, [out.mean])
    assert grad[far].abs().max() == 0  # ratio above 1 + eps, advantage > 0: no push
    assert grad[~far].abs().max() > 0
    # At ratio 1 the surrogate's gradient is the policy gradient's.
    near_loss, _ = _loss(out, bootstrap, b, entropy_cost=0.0, baseline_cost=0.0)
    (plain,) = torch.autograd.grad(near_loss, [out.mean])
    torch.testing.assert_close(grad[~far], plain[~far])


def test_normalized_advantages_make_the_policy_gradient_scale_free():
    out, bootstrap, b = synthetic(seed=5)
    out = _single(out)
    kw = dict(normalize_advantages=True, entropy_cost=0.0, baseline_cost=0.0)
    base, _ = _loss(out, bootstrap, b, **kw)
    (g1,) = torch.autograd.grad(base, [out.mean])
    scaled_out = out._replace(value_env=(10.0 * out.value_env).detach().requires_grad_())
    scaled_boot = bootstrap._replace(value_env=10.0 * bootstrap.value_env)
    scaled_b = dict(b, rewards_env=10.0 * b["rewards_env"])
    scaled, _ = _loss(scaled_out, scaled_boot, scaled_b, **kw)
    (g10,) = torch.autograd.grad(scaled, [out.mean])
    torch.testing.assert_close(g10, g1, rtol=1e-4, atol=1e-6)
    # Without normalising, the gradient grows with the rewards' scale.
    raw, _ = _loss(scaled_out, scaled_boot, scaled_b, entropy_cost=0.0, baseline_cost=0.0)
    (graw,) = torch.autograd.grad(raw, [out.mean])
    assert graw.abs().sum() > 5 * g1.abs().sum()
