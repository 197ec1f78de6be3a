"""Which rows of a rollout each level of TL-AC learns from and estimates its KL on
(:func:`row_weights`): the low level's policy gradient (Eq. 3), the high level's (Eq. 7) and
the target-KL stop's estimate. :func:`tlac.two_level.update.update` reads them."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from tlac.two_level.config import TLACConfig


@dataclass(frozen=True)
class RowWeights:
    """Per level (row 0 the low level, row 1 the high level when it is trained) and per sample
    of the rollout: what each level's loss, KL estimate and the critic count."""

    old_log_probs: torch.Tensor
    """``(levels, n)``: log pi_low(a|s) and log pi_high(e|s) at collection time."""
    kl: torch.Tensor
    """``(levels, n)`` 0/1: the rows of each level's approximate KL (the target-KL stop)."""
    loss: torch.Tensor | None
    """``(levels, n)`` 0/1: the rows of each level's policy loss; None: every row."""


def row_weights(
    cfg: TLACConfig,
    data: dict[str, torch.Tensor],
    n_teachers: int,
    train_high: bool,
    solo: bool,
    has_advice: bool,
    silent: torch.Tensor | None = None,
    greedy_solo: bool = False,
) -> RowWeights:
    """The rows of an update (``data``: the flat rollout). ``solo``: some episodes are the
    student's alone (no high-level choice in them); ``has_advice``: the advice buffer already
    holds states from earlier updates (``kl_rows: high`` falls back to the agent's rows while
    it is empty, as on the very first update); ``silent`` ``(n,)`` 0/1: the rows where every
    teacher's advice is uniform, or for Box actions where every teacher's information is 0
    (losses.silent_states, losses.silent_information), for ``low_level_data: silent`` (None:
    no row is silent, so the imitation term alone trains the low level); ``greedy_solo``: the
    solo episodes' actions are pi_low's means, not samples of it, so its policy gradient and its
    KL estimate on the agent's rows leave them out (TLAC.greedy_solo).

    >>> cfg = TLACConfig.from_settings({"variant": "paper"})
    >>> data = {"log_prob_low": torch.zeros(3), "log_prob_high": torch.ones(3),
    ...         "choices": torch.tensor([0, 1, 1]), "solo": torch.zeros(3)}
    >>> rows = row_weights(cfg, data, 1, True, False, False)
    >>> rows.old_log_probs.tolist(), rows.kl.tolist(), rows.loss
    ([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], [[1.0, 1.0, 1.0], [1.0, 1.0, 1.0]], None)
    """
    n = data["choices"].shape[0]
    levels = 2 if train_high else 1
    old_log_probs = torch.stack([data["log_prob_low"], data["log_prob_high"]])[:levels]
    # The approximate KL of the target-KL stop is an expectation under the BEHAVIOUR policy:
    # with kl_rows "agent", the low level's is estimated on the rows where the agent acted (a
    # teacher's action is not a sample of pi_low; docs/reproduction.md, "The target-KL rule");
    # "all": every row, as an implementation on SB3's PPO computes it. The high level chose
    # on every row outside the student's solo episodes.
    agent_rows = (data["choices"] == n_teachers).float()
    high_rows = 1.0 - data["solo"]
    sampled_rows = high_rows * agent_rows if greedy_solo else agent_rows  # pi_low's samples
    rule = cfg.kl_rows if cfg.kl_rows != "high" or has_advice else "agent"
    low_kl_rows = {"agent": sampled_rows, "all": torch.ones(n), "high": torch.zeros(n)}[rule]
    kl = torch.stack([low_kl_rows, high_rows])[:levels]
    # the rows of the low level's policy gradient: "agent", only where it acted; "all", every
    # row; "silent": before the imitation term has advice to learn from (the first update, and
    # every update without teachers) the agent's rows, so it is PPO; after, the agent's rows in
    # the silent states (where no teacher knows the way, the student learns it from its own
    # returns), none elsewhere
    if cfg.low_level_data == "all":
        low_loss_rows = torch.ones(n)
    elif cfg.low_level_data == "agent" or not has_advice:
        low_loss_rows = sampled_rows
    elif silent is None:
        low_loss_rows = torch.zeros(n)
    else:
        low_loss_rows = sampled_rows * silent
    every_row = cfg.low_level_data == "all" and not solo  # the paper variant: no weights at all
    loss = None if every_row else torch.stack([low_loss_rows, high_rows])[:levels]
    return RowWeights(old_log_probs, kl, loss)
