"""Hand-checked math of TL-AC: GAE, the clipped losses, schedules, UCB1, the stacked network."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike

from tlac.algorithms.nets import StackedMLP, gaussian_log_prob, np_gaussian_log_prob, np_log_softmax
from tlac.algorithms.rollout import compute_gae
from tlac.errors import ConfigError
from tlac.presets import make_schedule
from tlac.selectors import UCB1Selector, ucb1_scores
from tlac.two_level import losses


def test_gae_lambda_zero_is_the_papers_one_step_advantage():
    # Eq. 2: A = r + gamma V(s') - V(s); the episode ends after step 1 (no bootstrap there)
    rewards = np.array([[1.0], [0.0], [2.0]])
    values = np.array([[0.5], [1.0], [0.2]])
    dones = np.array([[0.0], [1.0], [0.0]])
    last = np.array([3.0])
    adv, ret = compute_gae(rewards, values, dones, last, gamma=0.9, gae_lambda=0.0)
    expected = [1 + 0.9 * 1.0 - 0.5, 0 + 0 - 1.0, 2 + 0.9 * 3.0 - 0.2]
    np.testing.assert_allclose(adv[:, 0], expected, rtol=1e-6)
    np.testing.assert_allclose(ret[:, 0], np.array(expected) + values[:, 0], rtol=1e-6)


def test_gae_with_lambda_by_hand():
    rewards = np.array([[1.0], [1.0]])
    values = np.array([[0.0], [0.0]])
    dones = np.zeros((2, 1))
    adv, _ = compute_gae(rewards, values, dones, np.array([1.0]), gamma=0.5, gae_lambda=0.5)
    d1 = 1 + 0.5 * 1.0 - 0.0  # delta at t=1
    d0 = 1 + 0.5 * 0.0 - 0.0  # delta at t=0
    np.testing.assert_allclose(adv[:, 0], [d0 + 0.25 * d1, d1], rtol=1e-6)


def test_gae_done_cuts_the_trace():
    rewards = np.array([[0.0], [1.0]])
    values = np.array([[0.0], [0.0]])
    dones = np.array([[1.0], [0.0]])
    adv, _ = compute_gae(rewards, values, dones, np.array([0.0]), gamma=1.0, gae_lambda=1.0)
    assert adv[0, 0] == 0.0 and adv[1, 0] == 1.0


def test_clipped_policy_loss_by_hand():
    old = torch.zeros(4)
    ratios = torch.tensor([1.5, 0.5, 1.5, 0.5])
    adv = torch.tensor([1.0, 1.0, -1.0, -1.0])
    loss = losses.clipped_policy_loss(torch.log(ratios), old, adv, clip_range=0.2)
    # min(r A, clip(r) A): 1.2, 0.5, -1.5, -0.8 -> mean -0.15, loss = 0.15
    assert float(loss) == pytest.approx(-(1.2 + 0.5 - 1.5 - 0.8) / 4)


def test_stacked_losses_equal_separate_ones_and_respect_weights():
    torch.manual_seed(0)
    lp, old = torch.randn(2, 6), torch.randn(2, 6)
    adv = torch.randn(6)
    per_level, kls = losses.clipped_policy_losses(lp, old, adv, 0.2)
    for level in range(2):
        assert float(per_level[level]) == pytest.approx(
            float(losses.clipped_policy_loss(lp[level], old[level], adv, 0.2))
        )
        assert float(kls[level]) == pytest.approx(float(losses.approx_kl(lp[level], old[level])))
    mask = torch.tensor([1.0, 0, 1, 0, 1, 0])
    weighted, _ = losses.clipped_policy_losses(
        lp, old, adv, 0.2, torch.stack([mask, torch.ones(6)])
    )
    keep = mask.bool()
    assert float(weighted[0]) == pytest.approx(
        float(losses.clipped_policy_loss(lp[0][keep], old[0][keep], adv[keep], 0.2))
    )


def test_value_loss_and_approx_kl():
    assert float(
        losses.value_loss(torch.tensor([1.0, 2.0]), torch.tensor([2.0, 0.0]))
    ) == pytest.approx(2.5)
    assert float(losses.approx_kl(torch.zeros(3), torch.zeros(3))) == 0.0
    r = 2.0
    assert float(losses.approx_kl(torch.tensor([math.log(r)]), torch.zeros(1))) == pytest.approx(
        r - 1 - math.log(r)
    )


def test_linear_schedule_and_bad_schedule():
    s = make_schedule({"linear": [0.3, 0.1]})
    assert (
        s(1.0) == pytest.approx(0.3)
        and s(0.0) == pytest.approx(0.1)
        and s(0.5) == pytest.approx(0.2)
    )
    with pytest.raises(ConfigError, match="linear"):
        make_schedule("lin_0.3")


def test_ucb1_scores_by_hand():
    sums, counts = np.array([2.0, 0.0, 0.0]), np.array([2, 1, 0])
    scores = ucb1_scores(sums, counts, c=1.0, value_range=1.0)
    assert scores[2] == math.inf
    assert scores[0] == pytest.approx(1.0 + math.sqrt(2 * math.log(3) / 2))
    assert scores[1] == pytest.approx(0.0 + math.sqrt(2 * math.log(3) / 1))


def test_ucb1_selector_plays_each_arm_then_exploits():
    sel = UCB1Selector(n_choices=3, n_envs=1, seed=0, c=0.1)
    played = []
    for _ in range(3):
        arm = int(sel.select(None, np.array([True]))[0])
        played.append(arm)
        sel.episode_end(0, {0: 0.1, 1: 0.9, 2: 0.2}[arm])
    assert sorted(played) == [0, 1, 2]
    # mid-episode the choice is kept; at the next start the best arm (1) wins
    assert int(sel.select(None, np.array([True]))[0]) == 1
    assert int(sel.select(None, np.array([False]))[0]) == 1


def test_stacked_mlp_members_equal_their_own_mlps_even_with_different_widths():
    torch.manual_seed(0)
    net = StackedMLP(5, [[8, 4], [6, 6], [3, 7]], [3, 2, 1], [True, False, True], [0.01, 0.01, 1.0])
    x = torch.randn(4, 5)
    out, _ = net(x)
    for m, (hidden, n_out) in enumerate(zip([[8, 4], [6, 6], [3, 7]], [3, 2, 1], strict=True)):
        widths = [5, *hidden, n_out]
        h = x
        for layer, w in enumerate(net.weights):
            weight = w[m, : widths[layer], : widths[layer + 1]]
            bias = net.biases[layer][m, 0, : widths[layer + 1]]
            h = h @ weight + bias
            if layer < len(net.weights) - 1:
                h = torch.tanh(h)
        torch.testing.assert_close(out[m, :, :n_out], h)
    np.testing.assert_allclose(
        net.forward_numpy(x.numpy())[0], out.detach().numpy(), rtol=1e-5, atol=1e-6
    )
    # a gradient step leaves the padded weights at exactly zero
    opt = RMSpropTFLike(net.parameters(), lr=0.1)
    net(x)[0].sum().backward()
    opt.step()
    assert float(net.weights[0].detach()[2, :, 3:].abs().sum()) == 0.0


def test_stacked_mlp_masks_only_the_layers_whose_widths_differ():
    # equal hidden widths: only the output layer (3 vs 2 vs 1 outputs) is padded
    net = StackedMLP(5, [[8, 8], [8, 8], [8, 8]], [3, 2, 1], [True] * 3, [0.01, 0.01, 1.0])
    assert [mask is None for _, _, mask in net._layers] == [True, True, False]
    assert sorted(k for k in net.state_dict() if k.startswith("mask")) == ["mask2"]


def test_numpy_and_torch_log_probs_agree():
    rng = np.random.default_rng(0)
    a, mean, log_std = rng.normal(size=(3, 2)), rng.normal(size=(3, 2)), rng.normal(size=(3, 2))
    t = gaussian_log_prob(*(torch.tensor(v) for v in (a, mean, log_std)))
    np.testing.assert_allclose(np_gaussian_log_prob(a, mean, log_std), t.numpy(), rtol=1e-10)
    logits = rng.normal(size=(4, 5))
    np.testing.assert_allclose(
        np_log_softmax(logits), torch.log_softmax(torch.tensor(logits), -1).numpy(), rtol=1e-10
    )


def test_clipped_losses_stay_finite_when_a_teacher_action_was_improbable() -> None:
    """A teacher's action with old log-probability -1e4 under pi_low, now -10: the raw ratio
    exp(9990) is inf; the capped one keeps loss, KL and gradient finite."""
    from tlac.two_level.losses import MAX_LOG_RATIO, clipped_policy_losses

    log_prob = torch.tensor([[-10.0, -1.0]], requires_grad=True)
    old = torch.tensor([[-1e4, -1.0]])
    loss, kl = clipped_policy_losses(log_prob, old, torch.tensor([-1.0, 1.0]), 0.2)
    loss.sum().backward()
    assert torch.isfinite(loss).all() and torch.isfinite(kl).all()
    assert torch.isfinite(log_prob.grad).all()
    assert float(kl[0]) > 1e6  # a KL stop still sees the row as moved far
    # below the cap nothing changes: ratio 1.5 is clipped exactly as before
    loss2, _ = clipped_policy_losses(
        torch.log(torch.tensor([[1.5]])), torch.zeros(1, 1), torch.tensor([1.0]), 0.2
    )
    assert abs(float(loss2[0]) + 1.2) < 1e-6 and MAX_LOG_RATIO == 20.0


def test_selectors_share_one_protocol_and_registry() -> None:
    """Every high level answers select / episode_end / evaluation_choices, and the registry is
    the one list of names (TLACConfig, RunSpec and the CLI read it)."""
    from tlac.selectors import SELECTOR_NAMES, make_selector

    assert SELECTOR_NAMES == ("learned", "random", "ucb1")
    logits = np.array([[0.0, 5.0, 0.0], [3.0, 0.0, 0.0]])
    learned = make_selector("learned", 3, 1, 0, np.random.default_rng(0))
    assert learned.evaluation_choices(logits, deterministic=True).tolist() == [1, 0]
    ucb = make_selector("ucb1", 3, 1, 0, np.random.default_rng(0))
    ucb.sums[:], ucb.counts[:] = [1.0, 6.0, 2.0], [1, 2, 1]  # means 1, 3, 2
    assert ucb.evaluation_choices(logits, deterministic=False).tolist() == [1, 1]
    rand = make_selector("random", 3, 1, 0, np.random.default_rng(0))
    assert set(rand.evaluation_choices(np.zeros((200, 3)), deterministic=True)) == {0, 1, 2}
    assert [s.trains_high_level for s in (learned, rand, ucb)] == [True, False, False]


@pytest.mark.parametrize("env", ["doorkey", "hopper"])
def test_per_level_step_clips_each_network_alone_and_leaves_a_stopped_level_untouched(env):
    """update_rule per_level (the paper variant's): each member's gradient is clipped to
    max_grad_norm on its own (as torch's clip_grad_norm_ over that member's parameters alone),
    and a stopped level keeps its weights and optimiser statistics exactly."""
    from tlac import TLAC
    from tlac.algorithms.nets import CRITIC, HIGH, LOW

    model = TLAC(env, teachers=["optimal", "random"], seed=1, variant="paper")
    assert model.config.update_rule == "per_level"
    model.learn(2 * model.config.n_steps * model.n_envs, progress_bar=False)  # optimiser state
    ro = model.collect()
    data = ro.flat()
    idx = torch.arange(min(16, data["obs"].shape[0]))
    from tlac.two_level.rows import row_weights
    from tlac.two_level.steps import gradient_step_per_level, moments
    from tlac.two_level.summary import UpdateLog
    from tlac.two_level.update import minibatch_loss

    rows = row_weights(model.config, data, model.n_teachers, True, False, False)

    def loss():
        return minibatch_loss(model, data, idx, rows, 0.2, None, UpdateLog())[0]

    def member(m):  # every tensor of member m: weights and optimiser statistics
        out = []
        for p in model.nets.net.parameters():
            out += [p.data[m].clone()] + [v[m].clone() for v in moments(model.optimizer, p)]
        if m == LOW and model.nets.log_std is not None:
            out += [model.nets.log_std.data.clone()] + [
                v.clone() for v in moments(model.optimizer, model.nets.log_std)
            ]
        return out

    # each member's gradient, clipped alone, by hand
    model.optimizer.zero_grad()
    loss().backward()
    raw = {
        m: torch.sqrt(sum(p.grad[m].pow(2).sum() for p in model.nets.net.parameters()))
        for m in (HIGH, LOW, CRITIC)
    }
    if model.nets.log_std is not None:
        raw[LOW] = torch.sqrt(raw[LOW] ** 2 + model.nets.log_std.grad.pow(2).sum())
    before = {m: member(m) for m in (HIGH, LOW, CRITIC)}
    running = torch.tensor([False, True])  # the low level stopped
    max_norm, step = model.config.max_grad_norm, model.num_timesteps
    gradient_step_per_level(model.nets, model.optimizer, loss(), running, max_norm, step)
    after = {m: member(m) for m in (HIGH, LOW, CRITIC)}
    assert all(torch.equal(a, b) for a, b in zip(before[LOW], after[LOW], strict=True))
    for m in (HIGH, CRITIC):
        assert not all(torch.equal(a, b) for a, b in zip(before[m], after[m], strict=True))
        clipped = torch.sqrt(sum(p.grad[m].pow(2).sum() for p in model.nets.net.parameters()))
        expected = min(float(raw[m]), model.config.max_grad_norm)
        assert clipped.item() == pytest.approx(expected, rel=1e-4)
