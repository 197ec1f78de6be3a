"""TL-AC's update (paper, Algorithm 1, lines 5-9), top to bottom: the schedules, the teachers'
advice on the rollout, the rows each level learns from, then epochs of minibatches, each one
loss (both levels' clipped surrogates, Eq. 3 and 7, with the SAME advantage from the shared
critic, Eq. 6; the critic's error, Eq. 5; the imitation and entropy terms) and one gradient
step, until the target-KL stop; and the logged summary. What only speeds this up is in
:mod:`tlac.two_level.fast`, each beside the plain formula it equals."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import torch
from stable_baselines3.common.vec_env import unwrap_vec_normalize

from tlac.algorithms.advice import away_to_agent, mask_logits, priced_logits
from tlac.two_level import fast, losses
from tlac.two_level.graduation import entropy_coefs
from tlac.two_level.labels import advice_on, charge_labels, store_labels, store_paid_labels
from tlac.two_level.rows import RowWeights, row_weights
from tlac.two_level.steps import gradient_step, gradient_step_per_level
from tlac.two_level.summary import UpdateLog, summarize_update

if TYPE_CHECKING:
    import numpy as np

    from tlac.algorithms.rollout import Rollout

Heads = tuple[torch.Tensor, torch.Tensor, torch.Tensor]  # high logits, low output, latent


def update(model: Any, ro: Rollout, progress_remaining: float) -> dict[str, float]:
    """Epochs of minibatch updates of both levels and the shared critic (lines 5-9) on the
    rollout ``ro``; returns the logged summary."""
    cfg, nets = model.config, model.nets
    clip, lr = model.clip_schedule(progress_remaining), model.lr_schedule(progress_remaining)
    target_kl = None if model.kl_schedule is None else model.kl_schedule(progress_remaining)
    for group in model.optimizer.param_groups:
        group["lr"] = lr
    data = ro.flat()
    n = data["obs"].shape[0]
    has_advice = bool(model.advice_buffer)
    buffer, teachers = model.advice_buffer, model.teachers
    teacher_obs = data["obs"] if unwrap_vec_normalize(model.env) is None else data["teacher_obs"]
    # a teacher whose led episodes show help but whose advice was never asked is asked once,
    # copied or not, and BEFORE the copy's weight is set: a teacher with nothing to copy must
    # not be trusted for its returns alone (graduation.SoloEpisodes.no_teacher_helps). Set
    # first, a random teacher's led returns opened the copy of an adversarial one beside it for
    # a whole update (Pendulum seed 5: the student's mean action at 1.5 of 2 after it, and
    # -1421 alone at the end where PPO alone reaches -986; issue 63)
    measured = None
    if (
        buffer is not None
        and not model.limited_advice
        and model.solo is not None
        and bool(model.solo.unmeasured_helpers.any())
    ):
        measured = advice_on(nets, teachers, teacher_obs)
        measured_information = nets.advice_information(measured)
        record_information(model, measured_information)
    # teachers whose led episodes show harm: left out of the copy (left_in)
    harmful = None if model.solo is None else model.solo.shown_harm
    # graduation (docs/graduation.md): what every teacher advises in every collected state,
    # imitated by the low level in proportion to the high level's trust in that teacher
    distill = model.distill_schedule(progress_remaining)
    if cfg.wean_imitation and model.solo is not None:
        distill *= 1.0 - model.solo.weaning
    imitates = buffer is not None and distill > 0
    silent = None  # low_level_data silent: the states where no teacher says anything
    if model.advice is not None and not model.limited_advice:  # counted only
        model.advice.count_unlimited(data["choices"].numpy(), imitates or measured is not None)
    if buffer is not None and model.limited_advice and not imitates:
        # nothing is copied now (the audition, a weaned copy): no label is asked, but the
        # answers already paid for (the teachers that acted) are kept, at no cost
        paid = charge_labels(model.advice, data, model.n_teachers, paid_only=True)
        information = store_paid_labels(nets, teachers, buffer, data, teacher_obs, paid)
        note_wasted_asks(model, data, information, paid)
    if imitates and model.limited_advice:
        labelled = charge_labels(model.advice, data, model.n_teachers)
        advice = advice_on(nets, teachers, teacher_obs, labelled)
        store_labels(buffer, data["obs"], labelled, advice)  # the states some teacher labelled
        information = nets.advice_information(advice)
        record_information(model, information, labelled.T)
        note_wasted_asks(model, data, information, labelled)
        if cfg.low_level_data == "silent":  # where no teacher asked says anything
            silent = losses.silent_information(left_in(information * labelled.T, harmful))
    elif imitates:
        if measured is None:
            advice = advice_on(nets, teachers, teacher_obs)
            information = nets.advice_information(advice)
            record_information(model, information)
        else:  # asked and recorded above
            advice, information = measured, measured_information
        buffer.add(data["obs"], advice)
        if cfg.low_level_data == "silent":
            silent = losses.silent_information(left_in(information, harmful))
    k, solo = model.n_teachers, model.solo is not None
    rows = row_weights(cfg, data, k, model.train_high, solo, has_advice, silent, model.greedy_solo)
    # what every minibatch reads, prepared once: the rollout's rows as the networks see
    # them, and the replayed rows (states, advice) of every minibatch the update may take
    x = nets.update_rows(data["obs"] if nets.normalizer is None else data["net_obs"])
    replay = None
    imitates = imitates and len(buffer) > 0  # limited advice: none asked yet
    if imitates:
        batches = cfg.n_epochs * -(-n // cfg.batch_size)
        replay = fast.replay_plan(
            nets, buffer, cfg.imitation_batch_size, batches, model._replay_generator
        )
        replay = dataclasses.replace(replay, information=left_in(replay.information, harmful))
    cols = fast.narrowed_columns(nets, model.optimizer, cfg.update_rule, x, replay)
    if cols is not None:  # the first layer on the input columns this update activates
        x = x[:, cols]
        if replay is not None and replay.x is not None:
            replay = dataclasses.replace(replay, x=replay.x[:, cols])
    with fast.first_layer_on(nets, model.optimizer, cols):
        log, running, heads = epochs(
            model, data, rows, clip, target_kl, distill if imitates else None, x, replay
        )
    if replay is not None:
        replay.draws.finish()  # the generator as if each minibatch had drawn its own rows
    out = summarize_update(log, rows.old_log_probs.shape[0])
    out["train/explained_variance"] = losses.explained_variance(data["values"], data["returns"])
    out["train/n_updates"] = model._n_updates
    with torch.no_grad():  # entropies of the last minibatch, for the logs
        for lv, h in zip(["low", "high"], nets.mean_entropies(*heads).tolist(), strict=False):
            out[f"train/entropy_{lv}"] = h
    if model.solo is not None:
        out["train/solo_probability"] = model.solo.probability
        out["train/competence"] = model.solo.competence
        if cfg.wean_imitation:  # the competence the imitation is weaned by
            out["train/weaning"] = model.solo.weaning
    if judges_asks(model):  # ask learned: the answers paid for that said nothing
        out["train/wasted_asks"] = float(data["wasted_ask"].sum()) if "wasted_ask" in data else 0.0
    if log.imitation:
        out["train/imitation_loss"] = float(torch.stack(log.imitation).mean())
        out["train/distill_coef"] = distill
    out["train/learning_rate"], out["train/clip_range"] = lr, clip
    out["train/stopped_early"] = float(log.stopped_early)
    if cfg.update_rule == "per_level":  # which levels the KL stop ended before the last epoch
        for lv, run in zip(["low", "high"], running.tolist(), strict=False):
            out[f"train/stopped_{lv}"] = float(not run)
    return out


def left_in(information: torch.Tensor, harmful: np.ndarray | None) -> torch.Tensor:
    """``information`` ``(n_teachers, ...)`` with the rows of the ``harmful`` teachers
    (graduation.SoloEpisodes.shown_harm) at 0: in the replayed states their trust goes to the
    others (losses.reweighted_trust, losses.informative_trust) and, where no other teacher says
    anything, nothing is copied; with ``low_level_data: silent`` such a state counts as silent,
    so the student's own policy gradient learns there."""
    if harmful is None or not harmful.any():
        return information
    kept = torch.as_tensor(~harmful, dtype=information.dtype)
    return information * kept.view((-1,) + (1,) * (information.dim() - 1))


def judges_asks(model: Any) -> bool:
    """Whether the high level's asks are judged by what their answers said (note_wasted_asks):
    ask learned under a budget, with an advice buffer (the paper variant keeps none: its
    answers are acted on, never measured) and discrete actions. A Box teacher's information is
    measured from the rows it answered in a rollout (teachers.base.self_agreement_information),
    and the few rows a budget pays for cannot tell a noisy teacher from a random one: both
    would read as saying nothing."""
    return (
        model.advice is not None
        and model.advice.paced
        and model.train_high
        and model.advice_buffer is not None
        and model.nets.discrete
    )


def note_wasted_asks(
    model: Any, data: dict[str, torch.Tensor], information: torch.Tensor, labelled: torch.Tensor
) -> None:
    """ask learned under a budget: mark in ``data`` the rows where the high level paid for an
    answer that said nothing (losses.wasted_asks), for its unlikelihood term (minibatch_loss)."""
    if judges_asks(model):
        wasted = losses.wasted_asks(data["choices"], information, labelled)
        if bool(wasted.any()):  # (none: the update is exactly as without the term)
            data["wasted_ask"] = wasted


def record_information(
    model: Any, information: torch.Tensor, asked: torch.Tensor | None = None
) -> None:
    """Give the solo statistics (if any) how much each teacher's advice said on the rows it
    was asked (graduation.SoloEpisodes.record_information)."""
    if model.solo is not None:
        model.solo.record_information(information.numpy(), None if asked is None else asked.numpy())


def epochs(
    model: Any,
    data: dict[str, torch.Tensor],
    rows: RowWeights,
    clip: float,
    target_kl: float | None,
    distill: float | None,
    x: torch.Tensor,
    replay: fast.ReplayPlan | None,
) -> tuple[UpdateLog, torch.Tensor, Heads]:
    """The update's epochs of minibatch gradient steps, until the target-KL stop: what they
    logged, which levels still ran at the end (``[low, high]``; update_rule per_level) and the
    heads of the last minibatch."""
    cfg = model.config
    n = x.shape[0]
    log = UpdateLog()
    per_level = cfg.update_rule == "per_level"
    running = torch.ones(rows.old_log_probs.shape[0], dtype=torch.bool)  # [low, high]
    heads: Heads | None = None
    # the entropy coefficients, once: nothing they read (the solo episodes' competence)
    # changes during an update
    coefs = fast.update_entropy_coefs(model)
    for _epoch in range(cfg.n_epochs):
        model._n_updates += 1  # epochs begun, as SB3's train/n_updates counts them
        perm = torch.randperm(n, generator=model.generator)
        for start in range(0, n, cfg.batch_size):
            idx = perm[start : start + cfg.batch_size]
            loss, kls, heads = minibatch_loss(
                model, data, idx, rows, clip, distill, log, x, replay, coefs
            )
            # SB3's rule: stop before a step that moves too far (per level, or all at once)
            too_far = kls > 1.5 * target_kl if target_kl is not None else torch.zeros_like(running)
            if per_level:
                running &= ~too_far
                log.stopped_early = log.stopped_early or bool(too_far.any())
                if not running.any():
                    break
                gradient_step_per_level(
                    model.nets,
                    model.optimizer,
                    loss,
                    running,
                    cfg.max_grad_norm,
                    model.num_timesteps,
                )
                continue
            if bool(too_far.any()):
                log.stopped_early = True
                break
            gradient_step(model.optimizer, loss, cfg.max_grad_norm, model.num_timesteps)
        if (not running.any()) if per_level else log.stopped_early:
            break
    assert heads is not None
    return log, running, heads


def minibatch_loss(
    model: Any,
    data: dict[str, torch.Tensor],
    idx: torch.Tensor,
    rows: RowWeights,
    clip: float,
    distill: float | None,
    log: UpdateLog,
    x: torch.Tensor | None = None,
    replay: fast.ReplayPlan | None = None,
    ent_coefs: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, Heads]:
    """One minibatch's loss (both levels' clipped surrogates, the critic's error, and the
    graduate variant's terms), each level's approximate KL ``[low, high]``, and the heads it
    used. ``x``: the rollout's rows as ``Networks.heads`` takes them (None: made here);
    ``replay``: the update's replayed rows (None: planned here, for one minibatch);
    ``ent_coefs``: the update's entropy coefficients (None: worked out here)."""
    cfg, nets = model.config, model.nets
    if x is None:
        x = nets.update_rows(data["obs"] if nets.normalizer is None else data["net_obs"])
    adv = data["advantages"][idx]  # one advantage for both levels (Eq. 6)
    adv = losses.normalize(adv) if cfg.normalize_advantage else adv
    replayed = None  # this minibatch's replayed rows, in the same pass as its own
    if distill is not None:
        assert model.advice_buffer is not None
        one_off = replay is None  # planned here, for this minibatch alone
        if replay is None:
            replay = fast.replay_plan(
                nets, model.advice_buffer, cfg.imitation_batch_size, 1, model._replay_generator
            )
        replayed = replay.draws.next()
        if one_off:
            replay.draws.finish()
    b = len(idx)
    if replayed is None:
        heads = nets.heads(x[idx])
    else:
        assert replay is not None and model.advice_buffer is not None
        again = fast.replayed_rows(nets, model.advice_buffer, replay, replayed)
        heads = nets.heads(torch.cat([x[idx], again]))
    high_logits, low_out, values, latent = (h[:b] for h in heads)
    # ask learned: the high level acted with the price each answer had in this row; its
    # entropy bonus reads its preferences without the price (below)
    acting_logits = None
    if "high_shift" in data:
        acting_logits = priced_logits(high_logits, data["high_shift"][idx])
        away = data["high_away"][idx]
        if bool(away.any()):  # a teacher away: choosing it was the agent acting
            high_logits = away_to_agent(high_logits, away)
            acting_logits = away_to_agent(acting_logits, away)
    if "high_mask" in data:  # limited advice: the choices the high level had in each row
        high_logits = mask_logits(high_logits, data["high_mask"][idx])
        if acting_logits is not None:
            acting_logits = mask_logits(acting_logits, data["high_mask"][idx])
    if acting_logits is None:
        acting_logits = high_logits
    # low level, Eq. 3: log pi_low(a|s) A(s, a) on the EXECUTED actions
    lp_low = nets.low_log_prob(low_out, latent, data["actions"][idx])
    log_probs = lp_low[None]
    if model.train_high:  # high level, Eq. 7: log pi_high(e|s) A(s, a), the SAME advantage
        lp_high = torch.log_softmax(acting_logits, -1)
        lp_high = lp_high.gather(1, data["choices"][idx].view(-1, 1))
        log_probs = torch.stack([lp_low, lp_high.squeeze(1)])
    old = rows.old_log_probs[:, idx]
    weights = None if rows.loss is None else rows.loss[:, idx]
    policy_losses, kls = losses.clipped_policy_losses(
        log_probs, old, adv, clip, weights, rows.kl[:, idx]
    )
    vf_loss = losses.value_loss(values, data["returns"][idx])  # Eq. 5
    loss = policy_losses.sum() + cfg.vf_coef * vf_loss
    if "wasted_ask" in data:  # ask learned under a budget: not again where it said nothing
        loss = loss + losses.wasted_ask_loss(
            high_logits, data["choices"][idx], data["wasted_ask"][idx]
        )
    if replayed is not None:  # the imitation term on the replayed rows
        assert replay is not None and distill is not None
        advice, information = replay.advice[:, replayed], replay.information[:, replayed]
        imitation = nets.imitation_term(
            heads[0][b:], heads[1][b:], heads[3][b:], advice, information
        )
        loss = loss + distill * imitation
        log.imitation.append(imitation.detach())
    if model._use_entropy:  # skipped when both coefficients are 0 (Table 5)
        # (ask learned: on the logits without the price. On the priced ones, nearly all on
        # the agent, the bonus pushed the teachers' logits up against the price, which
        # chased them (278 after 3e5 DoorKey steps), and its gradient, p_k |log p_k| for a
        # rare teacher, favoured the likeliest one: 960 of 1,000 answers to one random
        # teacher, results/advice-budget/NOTES.md)
        entropies = nets.mean_entropies(high_logits, low_out, latent, cfg.ent_cap_high or None)
        coefs = ent_coefs
        if coefs is None:
            coefs = entropy_coefs(model._ent_coefs, model.solo, model._handover)
        loss = loss - (coefs[: len(entropies)] * entropies).sum()
    log.losses_and_kls.append(torch.cat([policy_losses.detach(), vf_loss.detach()[None], kls]))
    log.clip_fractions.append(losses.clip_fractions(log_probs, old, clip, weights))
    return loss, kls.detach(), (high_logits, low_out, latent)
