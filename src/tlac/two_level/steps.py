"""TL-AC's optimiser, its schedules and its gradient steps: one clipped step of all three
networks together (update_rule joint, the graduate variant's), or each network's gradient
clipped on its own with a stopped level left as it was (update_rule per_level, the paper
variant's)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import torch
from torch import nn

from tlac.algorithms.common import stop_if_not_finite
from tlac.algorithms.nets import HIGH, LOW, clip_coefficients, member_grad_norms
from tlac.presets import make_schedule
from tlac.two_level.fast import ForeachAdam, ForeachRMSpropTFLike, clip_grad_norm, optimizer_step

Schedule = Callable[[float], float]

if TYPE_CHECKING:
    from tlac.two_level.config import TLACConfig
    from tlac.two_level.networks import Networks


def make_optimizer(cfg: TLACConfig, params: list[nn.Parameter]) -> torch.optim.Optimizer:
    """The optimiser of all three networks: SB3's RMSpropTFLike (the paper's Table 5) or Adam,
    at the learning rate's starting value (``learn`` sets it per update from its schedule),
    each stepped with one call per operation (tlac.two_level.fast)."""
    lr0 = make_schedule(cfg.learning_rate, "learning_rate")(1.0)
    if cfg.optimizer == "adam":
        return ForeachAdam(params, lr=lr0, eps=cfg.optimizer_eps, foreach=True)
    return ForeachRMSpropTFLike(params, lr=lr0, alpha=0.99, eps=cfg.optimizer_eps)  # A2C's alpha


def make_schedules(cfg: TLACConfig) -> tuple[Schedule, Schedule, Schedule, Schedule | None]:
    """The update's schedules of the progress remaining (1 -> 0): learning rate, clip range,
    imitation coefficient, target KL (None: no KL stop)."""
    return (
        make_schedule(cfg.learning_rate, "learning_rate"),
        make_schedule(cfg.clip_range, "clip_range"),
        make_schedule(cfg.distill_coef, "distill_coef"),
        None if cfg.target_kl is None else make_schedule(cfg.target_kl, "target_kl"),
    )


def gradient_step(
    optimizer: torch.optim.Optimizer, loss: torch.Tensor, max_grad_norm: float, step: int
) -> None:
    """``loss``'s gradient, clipped to ``max_grad_norm`` over every parameter together, and one
    optimiser step (``step``: the step count, for the error on a non-finite norm)."""
    # what the optimiser steps: the model's parameters, with the first layer's active rows in
    # place of the whole weight while fast.first_layer_on is open
    params = [p for group in optimizer.param_groups for p in group["params"]]
    for p in params:  # the optimiser's zero_grad(set_to_none=True), without its hooks
        p.grad = None
    loss.backward()
    grads = [p.grad for p in params if p.grad is not None]
    norm = clip_grad_norm(grads, max_grad_norm)  # clip_grad_norm_'s arithmetic
    stop_if_not_finite(norm, "TL-AC", step, "gradient norm")
    optimizer_step(optimizer)


def gradient_step_per_level(
    nets: Networks,
    optimizer: torch.optim.Optimizer,
    loss: torch.Tensor,
    running: torch.Tensor,
    max_grad_norm: float,
    step: int,
) -> None:
    """update_rule per_level: each network's gradient clipped to max_grad_norm on its own,
    then one optimiser step that leaves a stopped level's weights and optimiser statistics
    as they were (``running``: ``[low, high]``; the critic steps while either runs). The
    optimiser is element-wise, so this is the step of separate optimisers per network
    (Adam's step count aside, which its state shares over the stack)."""
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    stacked = [p for p in nets.net.parameters() if p.grad is not None]
    log_std_grad = None if nets.log_std is None else nets.log_std.grad
    own = {} if log_std_grad is None else {LOW: [log_std_grad]}  # the low level's own
    norms = member_grad_norms([p.grad for p in stacked], nets.net.members, own)
    stop_if_not_finite(norms, "TL-AC", step, "gradient norm")
    coefs = clip_coefficients(norms, max_grad_norm)
    stopped = [m for m, run in zip((LOW, HIGH), running.tolist(), strict=False) if not run]
    coefs[stopped] = 0.0  # no gradient reaches a stopped level's optimiser statistics
    for p in stacked:
        p.grad.mul_(coefs.view(-1, *[1] * (p.grad.dim() - 1)))
    for m, grads in own.items():
        for g in grads:
            g.mul_(coefs[m])
    if nets.extractor_params:  # the shared CNN: its own clip; it steps while a level runs
        norm = nn.utils.clip_grad_norm_(nets.extractor_params, max_grad_norm)
        stop_if_not_finite(norm, "TL-AC", step, "gradient norm")
    kept = member_state(nets, optimizer, stopped)
    optimizer_step(optimizer)
    for live, saved in kept:
        live.copy_(saved)


@torch.no_grad()
def member_state(
    nets: Networks, optimizer: torch.optim.Optimizer, members: list[int]
) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """(live tensor, copy) pairs of the given members' weights and optimiser statistics, to
    put back after a step: a slice of each stacked tensor, the whole log std for LOW."""
    pairs: list[tuple[torch.Tensor, torch.Tensor]] = []
    for m in members:
        for p in nets.net.parameters():
            pairs += [(t[m], t[m].clone()) for t in [p.data, *moments(optimizer, p)]]
        if m == LOW and nets.log_std is not None:
            p = nets.log_std
            pairs += [(t, t.clone()) for t in [p.data, *moments(optimizer, p)]]
    return pairs


def moments(optimizer: torch.optim.Optimizer, p: torch.Tensor) -> list[torch.Tensor]:
    """The optimiser's per-element statistics of ``p`` (square averages, momenta)."""
    state = optimizer.state[p].values()
    return [v for v in state if isinstance(v, torch.Tensor) and v.shape == p.shape]
