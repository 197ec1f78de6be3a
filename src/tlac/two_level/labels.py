"""The teachers' advice as TL-AC's imitation term reads it: every teacher asked on a batch of
states (:func:`advice_on`), the labels paid for under limited advice (:func:`charge_labels`,
the ledger of :func:`make_advice_ledger`), and the labelled states kept in the advice buffer
(:func:`store_labels`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from tlac.algorithms.advice import (
    AdviceLedger,
    acting_teachers,
    per_teacher,
    per_teacher_values,
)
from tlac.errors import ConfigError
from tlac.teachers.base import advice_actions, advice_probabilities, take_rows
from tlac.two_level.graduation import AdviceBuffer

if TYPE_CHECKING:
    from tlac.teachers.base import Teacher
    from tlac.two_level.config import AdviceSettings, TLACConfig
    from tlac.two_level.networks import Networks


def advice_on(
    nets: Networks, teachers: list[Teacher], obs: torch.Tensor, asked: torch.Tensor | None = None
) -> torch.Tensor:
    """Every teacher's advice in every row of ``obs`` (stored flat rows), each teacher asked
    once for the whole batch. Discrete actions: its distribution over them,
    ``(n_teachers, n, n_actions)`` (tlac.teachers.base.advice_probabilities: a point mass where
    a teacher cannot tell). Box actions: ``(n_teachers, n, act_dim + 1)``, the action it means
    and, in the last column, its information (tlac.teachers.base.advice_actions: its own action
    and 1 where a teacher cannot tell). ``asked`` ``(n, n_teachers)`` (limited advice): each
    teacher is asked on its rows only; elsewhere its advice is a placeholder that says nothing
    (the uniform distribution; a zero action with information 0)."""
    raw = nets.teacher_rows(obs.numpy())
    n = obs.shape[0]
    space = nets.action_space
    if asked is not None:
        return advice_where_asked(nets, teachers, raw, n, asked.numpy())
    if nets.discrete:
        return torch.from_numpy(
            np.stack([advice_probabilities(t, raw, space) for t in teachers]).astype(np.float32)
        )
    out = []
    for teacher in teachers:
        actions, information = advice_actions(teacher, raw, space)
        out.append(np.concatenate([actions.reshape(n, -1), information[:, None]], axis=1))
    return torch.from_numpy(np.stack(out).astype(np.float32))


def advice_where_asked(
    nets: Networks, teachers: list[Teacher], raw: Any, n: int, asked: np.ndarray
) -> torch.Tensor:
    """:func:`advice_on` where each teacher is asked on the rows ``asked[:, k]`` only."""
    space = nets.action_space
    if nets.discrete:
        n_actions = int(space.n)
        out = np.full((len(teachers), n, n_actions), 1.0 / n_actions)
    else:
        out = np.zeros((len(teachers), n, nets.advice_width))
    for k, teacher in enumerate(teachers):
        rows = np.flatnonzero(asked[:, k])
        if not len(rows):
            continue
        batch = take_rows(raw, rows)
        if nets.discrete:
            out[k, rows] = advice_probabilities(teacher, batch, space)
        else:
            actions, information = advice_actions(teacher, batch, space)
            out[k, rows, :-1] = actions.reshape(len(rows), -1)
            out[k, rows, -1] = information
    return torch.from_numpy(out.astype(np.float32))


def charge_labels(
    ledger: AdviceLedger, data: dict[str, torch.Tensor], n_teachers: int, paid_only: bool = False
) -> torch.Tensor:
    """``(n, K)`` bool: the teachers asked for a label in each row of the rollout ``data``:
    those present where the student asked, while the budget holds (rollout order); a teacher
    that acted in a row labels it with the answer already paid for. ``paid_only``: only those."""
    paid = acting_teachers(data["choices"].numpy(), n_teachers)
    if "corrected" in data:  # mistake correcting: a label only where the teacher disagreed
        paid &= data["corrected"].numpy()[:, None]
    wanted = paid if paid_only else data["askable"].numpy() | paid
    return torch.from_numpy(ledger.charge(wanted, paid))


def store_labels(
    buffer: AdviceBuffer, obs: torch.Tensor, labelled: torch.Tensor, advice: torch.Tensor
) -> None:
    """Add to the advice buffer the states ``obs`` that some teacher labelled, with their
    labels ``advice`` ``(K, n, ...)``. Only those: a state no teacher was asked in would dilute
    the imitation term's mean (it weighs 0) and push asked states out of the ring (under a
    budget of 1e3 answers over 1e5 steps, 99% of it)."""
    keep = labelled.any(dim=1)
    if bool(keep.any()):
        buffer.add(obs[keep], advice[:, keep], labelled[keep])


def store_paid_labels(
    nets: Networks,
    teachers: list[Teacher],
    buffer: AdviceBuffer,
    data: dict[str, torch.Tensor],
    teacher_obs: torch.Tensor,
    labelled: torch.Tensor,
) -> torch.Tensor:
    """:func:`store_labels` for the answers already paid for (``labelled``), asked here on the
    labelled states alone (``teacher_obs``: the rollout's states as the teachers see them).
    Returns how much each answer said, ``(K, n)`` (``nets.advice_information``; 0 in the rows
    not labelled)."""
    keep = labelled.any(dim=1)
    information = torch.zeros(labelled.shape[1], labelled.shape[0])
    if bool(keep.any()):
        advice = advice_on(nets, teachers, teacher_obs[keep], labelled[keep])
        buffer.add(data["obs"][keep], advice, labelled[keep])
        information[:, keep] = nets.advice_information(advice).to(information.dtype)
    return information


def make_advice_ledger(
    terms: AdviceSettings, teacher_names: list[str], n_envs: int, seed: int, discrete: bool
) -> AdviceLedger | None:
    """The ledger of advice as it costs (tlac.algorithms.advice): answers are counted whenever
    there are teachers; limited (a budget, availability, an asking rule) only where the
    settings ``terms`` say. None without teachers, costs or availabilities."""
    if not (teacher_names or terms.teacher_cost or terms.availability):
        return None
    if terms.ask in ("importance", "uncertainty", "mistake") and not discrete:
        raise ConfigError(
            f"TL-AC setting ask {terms.ask!r} reads the student's action logits and "
            "needs discrete actions; use always or early with Box actions"
        )
    if terms.ask == "learned" and terms.ask_threshold is not None and not discrete:
        raise ConfigError(
            "TL-AC setting ask_threshold under ask 'learned' gates the asks by the student's "
            "action logits and needs discrete actions; leave it unset with Box actions"
        )
    return AdviceLedger(
        per_teacher(terms.teacher_cost, teacher_names, "teacher_cost", 1.0),
        per_teacher_values(terms.availability, teacher_names, "availability", 1.0),
        terms.advice_budget,
        n_envs,
        seed,
        terms.ask,
        terms.ask_threshold,
        names=teacher_names,
        discrete=discrete,
    )


def make_advice_buffer(cfg: TLACConfig, nets: Networks, track_labels: bool) -> AdviceBuffer | None:
    """The imitation term's advice buffer: per state, every teacher's advice (``track_labels``:
    limited advice, which teachers were asked); None without teachers or without imitation."""
    if not (nets.n_teachers and cfg.distill_coef != 0):
        return None
    layout = nets.obs_layout
    return AdviceBuffer(
        cfg.imitation_buffer_size,
        nets.obs_dim,
        (nets.n_teachers, nets.advice_width),
        torch.float32,
        None if layout is None else layout.storage_dtype,
        track_labels=track_labels,
    )
