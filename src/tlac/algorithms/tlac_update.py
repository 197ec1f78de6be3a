"""The pieces of TL-AC's update that need no network: which rows each level learns from and
estimates its KL on (:func:`row_weights`), the statistics gathered over the minibatches
(:class:`UpdateLog`), and the logged summary of an update (:func:`summarize_update`).
:meth:`tlac.algorithms.two_level.TLAC.update` composes them with the losses."""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from tlac.algorithms.tlac_config import TLACConfig


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


@dataclass
class UpdateLog:
    """What one update gathers over its minibatches for the logs."""

    losses_and_kls: list[torch.Tensor] = field(default_factory=list)
    """Per minibatch: [policy loss per level, value loss, approximate KL per level]."""
    clip_fractions: list[torch.Tensor] = field(default_factory=list)
    imitation: list[torch.Tensor] = field(default_factory=list)
    stopped_early: bool = False


def summarize_update(log: UpdateLog, levels: int) -> dict[str, float]:
    """The means over an update's minibatches of the losses, KLs and clip fractions, under
    SB3's names where SB3 has one (the low level is the student's policy).

    >>> log = UpdateLog([torch.tensor([1.0, 2.0, 0.1]), torch.tensor([3.0, 4.0, 0.3])],
    ...                 [torch.tensor([0.5])])
    >>> summary = summarize_update(log, 1)
    >>> (summary["train/policy_loss_low"], summary["train/value_loss"],
    ...  summary["train/clip_fraction"])
    (2.0, 3.0, 0.5)
    """
    names = ["low", "high"][:levels]
    keys = [f"policy_loss_{lv}" for lv in names] + ["value_loss"]
    keys += [f"approx_kl_{lv}" for lv in names]
    means = torch.stack(log.losses_and_kls).mean(0).tolist()
    out = {f"train/{k}": v for k, v in zip(keys, means, strict=True)}
    fractions = torch.stack(log.clip_fractions).mean(0).tolist()
    out["train/clip_fraction"] = fractions[0]
    if len(fractions) > 1:
        out["train/clip_fraction_high"] = fractions[1]
    return out


class ReplayDraws:
    """The imitation term's replayed rows for a whole update, drawn in one call.

    Every minibatch of an update replays ``batch_size`` rows of the advice buffer drawn
    uniformly with replacement (:meth:`tlac.algorithms.graduation.AdviceBuffer.sample`). Drawing
    them one minibatch at a time cost a draw, two gathers and an encoding per minibatch; here
    the rows of every minibatch the update may take are drawn at once, from a copy of the
    generator, and :meth:`finish` then advances the generator itself by the draws of the
    minibatches actually taken (the KL stop may end an update early). ``torch.randint`` on the
    CPU draws its values one after the other, so ``k`` draws of ``n`` rows are the first
    ``k * n`` values of one draw: the rows and the generator's state are exactly those of one
    draw per minibatch.

    >>> g = torch.Generator().manual_seed(0)
    >>> draws = ReplayDraws(size=100, batch_size=4, max_batches=3, generator=g)
    >>> rows = draws.idx[draws.next()]
    >>> draws.finish()   # one minibatch taken: the generator moves by its 4 draws only
    >>> ref = torch.Generator().manual_seed(0)
    >>> (torch.equal(rows, torch.randint(100, (4,), generator=ref)),
    ...  g.get_state().equal(ref.get_state()))
    (True, True)
    """

    def __init__(self, size: int, batch_size: int, max_batches: int, generator: torch.Generator):
        self.size, self.batch_size, self.generator = size, batch_size, generator
        self.max_batches = max_batches
        peek = torch.Generator().set_state(generator.get_state())
        self.idx = torch.randint(size, (batch_size * max_batches,), generator=peek)
        self.taken = 0

    def next(self) -> slice:
        """The positions in :attr:`idx` of the next minibatch's rows."""
        if self.taken == self.max_batches:
            raise RuntimeError(f"only {self.max_batches} minibatches of rows were drawn")
        start = self.taken * self.batch_size
        self.taken += 1
        return slice(start, start + self.batch_size)

    def finish(self) -> None:
        """Advance the generator by the rows of the minibatches taken, as their own draws did."""
        if self.taken:
            torch.randint(self.size, (self.taken * self.batch_size,), generator=self.generator)


@dataclass(frozen=True)
class ReplayPlan:
    """The replayed rows of an update's minibatches (TLAC._replay_plan): which rows, as the
    networks take them, and their advice and its information, gathered once for all of them."""

    draws: ReplayDraws
    x: torch.Tensor | None
    """``(rows, ...)``: the drawn states as the update's passes take them, in draw order
    (normalised with the statistics of the update, then encoded as TLAC._update_rows does);
    None where they would be too large to hold (each minibatch then makes its own)."""
    advice: torch.Tensor
    """``(n_teachers, rows, ...)``: the labels copied in every drawn row, in draw order
    (discrete actions: losses.advice_labels of the advice; Box actions: the actions meant)."""
    information: torch.Tensor
    """``(n_teachers, rows)``: how much each teacher's advice says in each row (discrete
    actions: losses.advice_information of the advice before its labels were taken; Box
    actions: the information the teachers gave, tlac.teachers.base.advice_actions)."""


def active_columns(*inputs: torch.Tensor) -> torch.Tensor:
    """The columns that are nonzero in some row of the 2-D ``inputs``: the input columns whose
    first-layer weights an update's gradients can reach (tlac.algorithms.optim.stepping_rows).

    >>> active_columns(torch.tensor([[0.0, 1.0, 0.0]]), torch.tensor([[0.0, 0.0, 2.0]])).tolist()
    [1, 2]
    """
    magnitude = sum(x.abs().sum(0) for x in inputs)  # a sixth of the time of (x != 0).any(0)
    return (magnitude != 0).nonzero().squeeze(1)  # != keeps a column holding a NaN
