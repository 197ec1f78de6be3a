"""TL-AC's speed-ups (tlac.two_level.fast), each against the plain formula it equals: the
foreach optimisers and gradient clip (bit for bit), the first layer stepped on its active
columns (up to rounding), the replayed rows drawn and planned once per update (the same rows
and generator state as one draw per minibatch)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike

from tlac import TLAC
from tlac.algorithms.nets import StackedMLP
from tlac.two_level import fast, losses


def test_foreach_rmsprop_and_clip_are_sb3s_and_torchs_bit_for_bit():
    """ForeachRMSpropTFLike and optim.clip_grad_norm compute exactly what SB3's RMSpropTFLike
    and torch's clip_grad_norm_ do (the golden digests rely on it), with SB3's state_dict."""
    ForeachRMSpropTFLike, clip_grad_norm = fast.ForeachRMSpropTFLike, fast.clip_grad_norm

    torch.manual_seed(0)
    shapes = [(3, 20, 8), (3, 1, 8), (3, 8, 4), (4,)]
    ref = [torch.nn.Parameter(torch.randn(s)) for s in shapes]
    new = [torch.nn.Parameter(p.detach().clone()) for p in ref]
    opts = [RMSpropTFLike(ref, lr=0.01, alpha=0.99, eps=1e-5)]
    opts.append(ForeachRMSpropTFLike(new, lr=0.01, alpha=0.99, eps=1e-5))
    for _ in range(5):
        grads = [torch.randn(s) for s in shapes]
        for p, g in zip(ref, grads, strict=True):
            p.grad = g.clone()
        for p, g in zip(new, grads, strict=True):
            p.grad = g.clone()
        norm = torch.nn.utils.clip_grad_norm_(ref, 0.5, foreach=True)
        assert torch.equal(norm, clip_grad_norm([p.grad for p in new], 0.5))
        for opt in opts:
            opt.step()
        assert all(torch.equal(a, b) for a, b in zip(ref, new, strict=True))
    sb3, ours = (opt.state_dict()["state"] for opt in opts)
    assert all(torch.equal(sb3[i]["square_avg"], ours[i]["square_avg"]) for i in sb3)
    assert [sb3[i]["step"] for i in sb3] == [ours[i]["step"] for i in ours]


def test_foreach_adam_is_torchs_adam_bit_for_bit():
    """ForeachAdam.step_unhooked computes exactly what torch.optim.Adam(foreach=True) does (the
    user preset's CartPole and Pendulum digests rely on it): same weights and state after steps
    at a changing learning rate, over gradients of many scales, with a parameter that has no
    gradient in some steps (its own step count stays behind); options it does not compute itself
    (amsgrad) take torch's step."""
    from tlac.two_level.fast import ForeachAdam

    shapes = [(3, 6, 8), (3, 1, 8), (3, 8, 2), (5,)]
    for options in ({}, {"amsgrad": True}):
        torch.manual_seed(0)
        ref = [torch.nn.Parameter(torch.randn(s)) for s in shapes]
        new = [torch.nn.Parameter(p.detach().clone()) for p in ref]
        torch_adam = torch.optim.Adam(ref, lr=3e-4, eps=1e-5, foreach=True, **options)
        ours = ForeachAdam(new, lr=3e-4, eps=1e-5, foreach=True, **options)
        for step in range(60):
            for k, (a, b) in enumerate(zip(ref, new, strict=True)):
                skipped = k == 3 and step % 7 == 0
                grad = None if skipped else torch.randn(a.shape) * 10.0 ** (step % 9 - 4)
                a.grad, b.grad = grad, None if grad is None else grad.clone()
            for opt in (torch_adam, ours):
                opt.param_groups[0]["lr"] = 3e-4 * (1 - step / 60)
            torch_adam.step()
            ours.step_unhooked()
            assert all(torch.equal(a, b) for a, b in zip(ref, new, strict=True))
        theirs, mine = torch_adam.state_dict()["state"], ours.state_dict()["state"]
        for i in theirs:
            assert theirs[i].keys() == mine[i].keys()
            assert all(torch.equal(theirs[i][k], mine[i][k]) for k in theirs[i])
        assert mine[3]["step"] < mine[0]["step"]


def test_the_first_layer_stepped_on_its_active_columns_steps_as_the_whole_layer():
    """stepping_rows + StackedMLP.first_layer_as, on inputs that are zero outside some columns
    (a padded first layer, statistics already moved by a step on every column, two updates on
    other columns): each update's two clipped RMSprop steps on those rows of the first layer
    give the weights and optimiser statistics that two steps on the whole layer give (up to
    rounding: the matmul sums over fewer columns); the other rows' weights stay as they were
    and their square averages decay exactly as a step with zero gradient decays them."""
    import copy

    from tlac.two_level.fast import (
        ForeachRMSpropTFLike,
        active_columns,
        clip_grad_norm,
        stepping_rows,
    )

    torch.manual_seed(0)
    whole = StackedMLP(10, [[8, 8], [6, 6], [8, 8]], [3, 5, 1], [True] * 3, [0.01, 0.01, 1.0])
    assert whole._layers[0][2] is not None  # the first layer carries a width mask
    narrow = copy.deepcopy(whole)

    def steps(net, opt, inputs, n):
        for _ in range(n):
            params = opt.param_groups[0]["params"]
            for p in params:
                p.grad = None
            out, _ = net(inputs)
            out.sin().sum().backward()
            clip_grad_norm([p.grad for p in params], 0.5)
            opt.step()

    opts = [
        ForeachRMSpropTFLike(net.parameters(), lr=0.01, alpha=0.9, eps=1e-5)
        for net in (whole, narrow)
    ]
    dense = torch.randn(6, 10)
    for net, opt in zip((whole, narrow), opts, strict=True):  # every column moves once
        steps(net, opt, dense, 1)
    first = narrow.weights[0]
    for active in ([1, 4, 7], [0, 2, 5, 9]):
        x = torch.zeros(6, 10)
        x[:, active] = torch.randn(6, len(active))
        cols = active_columns(x)
        assert cols.tolist() == active
        idle = [c for c in range(10) if c not in active]
        weights_before = first.detach().clone()
        squares_before = opts[1].state[first]["square_avg"].clone()
        steps(whole, opts[0], x, 2)
        with stepping_rows(opts[1], first, cols, dim=1) as part, narrow.first_layer_as(part, cols):
            steps(narrow, opts[1], x[:, cols], 2)
        for a, b in zip(whole.parameters(), narrow.parameters(), strict=True):
            torch.testing.assert_close(a, b, rtol=0, atol=1e-7)
            state_a, state_b = opts[0].state[a], opts[1].state[b]
            assert state_a["step"] == state_b["step"]
            torch.testing.assert_close(
                state_a["square_avg"], state_b["square_avg"], rtol=0, atol=1e-7
            )
        assert torch.equal(first.detach()[:, idle], weights_before[:, idle])
        decayed = squares_before[:, idle].mul_(0.9).mul_(0.9)
        assert torch.equal(opts[1].state[first]["square_avg"][:, idle], decayed)
        assert opts[1].param_groups[0]["params"][0] is first and part not in opts[1].state
    assert opts[1].state[first]["step"] == 5
    # a new leaf in every update: the step's scratch buffers stay one per parameter
    assert len(opts[1]._scratch_buffers[0]) == len(list(narrow.parameters()))


@pytest.mark.parametrize("seed", range(5))
def test_active_columns_are_the_columns_nonzero_in_some_row(seed):
    """active_columns(*xs) == the columns where some row of some x is nonzero (NaN counts)."""
    rng = np.random.default_rng(seed)
    xs = []
    for rows in (7, 3):
        x = rng.standard_normal((rows, 40)) * (rng.random((rows, 40)) < 0.1)
        xs.append(torch.tensor(x, dtype=torch.float32))
    xs[1][0, 5] = float("nan")
    plain = (torch.cat(xs) != 0).any(0).nonzero().squeeze(1)
    assert torch.equal(fast.active_columns(*xs), plain)


@pytest.mark.parametrize("taken", [0, 1, 3, 5])
def test_replay_draws_are_one_draw_per_minibatch(taken):
    """ReplayDraws: the rows of every minibatch taken and the generator's state afterwards are
    those of one torch.randint draw per minibatch (AdviceBuffer.sample's)."""
    generator, plain = torch.Generator().manual_seed(7), torch.Generator().manual_seed(7)
    draws = fast.ReplayDraws(size=50, batch_size=6, max_batches=5, generator=generator)
    rows = [draws.idx[draws.next()] for _ in range(taken)]
    draws.finish()
    for got in rows:
        assert torch.equal(got, torch.randint(50, (6,), generator=plain))
    assert torch.equal(generator.get_state(), plain.get_state())


def test_the_replay_plan_is_the_buffers_own_sample_per_minibatch():
    """replay_plan: each minibatch's planned rows, labels and information equal those of the
    advice buffer's own sample for that minibatch, made as the update makes them."""
    model = TLAC("doorkey", teachers=["optimal", "random"], seed=0)
    buffer = model.advice_buffer
    states = torch.from_numpy(model.nets.flat_rows(model.env.reset()))
    advice = torch.softmax(torch.randn(2, len(states), model.action_space.n), -1)
    for _ in range(3):
        buffer.add(states, advice)
    planned, plain = torch.Generator().manual_seed(3), torch.Generator().manual_seed(3)
    plan = fast.replay_plan(model.nets, buffer, 4, 3, planned)
    for _ in range(3):
        rows = plan.draws.next()
        obs, sampled = buffer.sample(4, plain)
        assert torch.equal(plan.x[rows], model.nets.replay_rows(obs))
        assert torch.equal(plan.advice[:, rows], losses.advice_labels(sampled))
        assert torch.equal(plan.information[:, rows], losses.advice_information(sampled))
    plan.draws.finish()
    assert torch.equal(planned.get_state(), plain.get_state())


def test_the_entropy_coefficients_once_per_update_are_each_minibatchs(monkeypatch):
    """update_entropy_coefs: the coefficients the update works out once are those that
    graduation.entropy_coefs gives before each of its minibatches (the hand-over bonus of a
    graduate student mid-training included), and the minibatch loss is the same with them."""
    import gymnasium as gym

    from tlac.two_level import update as update_module
    from tlac.two_level.graduation import entropy_coefs
    from tlac.two_level.summary import UpdateLog

    env = gym.make("CartPole-v1")
    model = TLAC(env, teachers=[lambda obs: int(obs[2] > 0)], seed=0, n_steps=256)
    model.learn(1024)
    assert model._use_entropy and model._handover
    seen = []

    def each_minibatch(*args, **kwargs):
        given = args[9] if len(args) > 9 else kwargs["ent_coefs"]
        seen.append((given, entropy_coefs(model._ent_coefs, model.solo, model._handover)))
        return real(*args, **kwargs)

    real = update_module.minibatch_loss
    monkeypatch.setattr(update_module, "minibatch_loss", each_minibatch)
    model.learn(512, reset_num_timesteps=False)
    assert seen and all(torch.equal(given, plain) for given, plain in seen)
    assert seen[-1][0][0] > 0  # the hand-over bonus on the low level
    monkeypatch.undo()
    ro = model.collect()
    data, idx = ro.flat(), torch.arange(64)
    rows = update_module.row_weights(
        model.config, data, model.n_teachers, model.train_high, True, False, None, False
    )
    coefs = fast.update_entropy_coefs(model)
    plain = update_module.minibatch_loss(model, data, idx, rows, 0.2, None, UpdateLog())[0]
    hoisted = update_module.minibatch_loss(
        model, data, idx, rows, 0.2, None, UpdateLog(), ent_coefs=coefs
    )[0]
    assert torch.equal(plain, hoisted)


def test_the_normalizers_tensors_follow_its_statistics():
    """Normalizer.obs_torch, its tensors made when first needed, normalises as obs_numpy does
    after every update of the statistics."""
    from tlac.algorithms.normalization import Normalizer

    norm = Normalizer(3, 1, gamma=0.99, obs=True, reward=False)
    rng = np.random.default_rng(0)
    for _ in range(5):
        norm.update_obs(rng.normal(size=(1, 3)).astype(np.float32))
        obs = rng.normal(size=(4, 3)).astype(np.float32)
        assert np.array_equal(norm.obs_torch(torch.from_numpy(obs)).numpy(), norm.obs_numpy(obs))
