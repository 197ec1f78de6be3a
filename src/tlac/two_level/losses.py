"""Pure loss functions of TL-AC's update (paper, Eq. 3 and Eq. 7, in their clipped form).

The paper's hyperparameter tables (clip range, target KL, epochs) show that its losses
``log pi(a|s) A(s, a)`` were optimised with PPO's clipped surrogate; both levels use the
SAME advantage from the shared critic (Eq. 6).

>>> import torch
>>> ratio_one = torch.zeros(2)
>>> float(clipped_policy_loss(ratio_one, ratio_one, torch.tensor([1.0, -1.0]), 0.2))
-0.0
"""

from __future__ import annotations

import math

import torch

MAX_LOG_RATIO = 20.0
"""Log-ratios are capped here before ``exp``. TL-AC's low level also trains on teachers'
actions (Eq. 3), whose old probability under pi_low can be ~exp(-1e4) (a Gaussian far from
a teacher's action): after one step the ratio overflows to inf and the loss to inf or NaN
(measured: hopper-bullet, paper variant with the agent-rows KL rule, 2 good + 1 noisy, NaN
gradients at 6e4 and 8e4 steps). A ratio above e^20 is far outside any clip range, so only
such rows change, and their gradient stops there instead of overflowing."""


def clipped_policy_loss(
    log_prob: torch.Tensor, old_log_prob: torch.Tensor, advantages: torch.Tensor, clip_range: float
) -> torch.Tensor:
    """``-mean(min(r A, clip(r, 1-eps, 1+eps) A))`` with ``r = exp(log_prob - old_log_prob)``."""
    ratio = torch.exp(torch.clamp(log_prob - old_log_prob, max=MAX_LOG_RATIO))
    unclipped = ratio * advantages
    clipped = torch.clamp(ratio, 1.0 - clip_range, 1.0 + clip_range) * advantages
    return -torch.min(unclipped, clipped).mean()


def clipped_policy_losses(
    log_prob: torch.Tensor,
    old_log_prob: torch.Tensor,
    advantages: torch.Tensor,
    clip_range: float,
    weights: torch.Tensor | None = None,
    kl_weights: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The clipped loss and approximate KL of SEVERAL policies at once.

    ``log_prob`` and ``old_log_prob`` are ``(L, B)``: one row per level (TL-AC stacks the low
    level, Eq. 3, and the high level, Eq. 7), all sharing the advantages ``(B,)`` (Eq. 6).
    ``weights`` ``(L, B)`` (0/1) restricts a row's loss to some samples, ``kl_weights`` its KL
    estimate (default: ``weights``). Returns two ``(L,)`` tensors: each row's loss (as
    :func:`clipped_policy_loss`) and its :func:`approx_kl`.

    >>> lp = torch.log(torch.tensor([[1.5, 1.0], [1.0, 0.5]]))
    >>> loss, kl = clipped_policy_losses(lp, torch.zeros(2, 2), torch.tensor([1.0, -1.0]), 0.2)
    >>> [round(v, 6) for v in loss.tolist()]  # row 0: -(1.2 - 1) / 2 ; row 1: -(1 - 0.8) / 2
    [-0.1, -0.1]
    """
    log_ratio = torch.clamp(log_prob - old_log_prob, max=MAX_LOG_RATIO)
    ratio = torch.exp(log_ratio)
    surrogate = torch.min(
        ratio * advantages, torch.clamp(ratio, 1.0 - clip_range, 1.0 + clip_range) * advantages
    )
    kl_terms = ((ratio - 1) - log_ratio).detach()
    loss = -_weighted_mean(surrogate, weights)
    return loss, _weighted_mean(kl_terms, weights if kl_weights is None else kl_weights)


def clip_fractions(
    log_prob: torch.Tensor,
    old_log_prob: torch.Tensor,
    clip_range: float,
    weights: torch.Tensor | None = None,
) -> torch.Tensor:
    """``(L,)``: per level, the share of (weighted) samples whose ratio left the clip range,
    ``|ratio - 1| > clip_range`` (SB3's ``train/clip_fraction``).

    >>> lp = torch.log(torch.tensor([[1.5, 1.0], [1.1, 0.5]]))
    >>> clip_fractions(lp, torch.zeros(2, 2), 0.2).tolist()
    [0.5, 0.5]
    """
    ratio = torch.exp(torch.clamp(log_prob - old_log_prob, max=MAX_LOG_RATIO))
    outside = (torch.abs(ratio - 1.0) > clip_range).float()
    return _weighted_mean(outside.detach(), weights)


def explained_variance(values: torch.Tensor, returns: torch.Tensor) -> float:
    """``1 - Var(returns - values) / Var(returns)`` (SB3's ``train/explained_variance``: 1 is a
    perfect critic, 0 no better than a constant; NaN when the returns do not vary).

    >>> explained_variance(torch.tensor([1.0, 2.0, 3.0]), torch.tensor([1.0, 2.0, 4.0]))
    0.8571428656578064
    """
    var = torch.var(returns)
    return float("nan") if var == 0 else float(1.0 - torch.var(returns - values) / var)


def _weighted_mean(x: torch.Tensor, weights: torch.Tensor | None) -> torch.Tensor:
    """Mean over the last axis, over the rows' weighted samples (0 where a row has none)."""
    if weights is None:
        return x.mean(dim=1)
    return (x * weights).sum(dim=1) / weights.sum(dim=1).clamp(min=1.0)


def informative_trust(
    trust: torch.Tensor, distributions: torch.Tensor, information: torch.Tensor | None = None
) -> torch.Tensor:
    """``(B, K)``: ``trust`` re-weighted by how much each teacher's advice says in each state.

    ``distributions`` ``(K, B, A)``: each teacher's distribution over the ``A`` actions. A
    teacher's information in a state is ``1 - H(pi_k(.|s)) / log A``: 1 for a point mass, 0 for
    the uniform distribution (a random teacher, a partial teacher outside its region), which
    says nothing about which action is right. ``trust[s, k] * info[k, s]`` is rescaled so that
    each state keeps its total trust; a state where every trusted teacher is uniform gets no
    imitation at all. ``information`` ``(K, B)``: :func:`advice_information` of
    ``distributions`` when the caller has it already (the update computes it once for all the
    states it replays).

    >>> uniform, point = torch.full((3,), 1 / 3), torch.tensor([0.0, 1.0, 0.0])
    >>> dists = torch.stack([torch.stack([point, uniform]), torch.stack([uniform, uniform])])
    >>> informative_trust(torch.tensor([[0.2, 0.8], [0.2, 0.8]]), dists).tolist()
    [[1.0, 0.0], [0.0, 0.0]]
    """
    if distributions.shape[-1] < 2:
        return trust
    if information is None:
        information = advice_information(distributions)
    return reweighted_trust(trust, information)


def reweighted_trust(trust: torch.Tensor, information: torch.Tensor) -> torch.Tensor:
    """``(B, K)``: ``trust[s, k] * information[k, s]``, rescaled so that each state keeps its
    total trust (0 where every trusted teacher's information is 0). Discrete actions: the
    information of :func:`advice_information`; Box actions: the weight of each teacher's
    informative part (tlac.teachers.base.advice_actions: 0 for a random teacher, 0.8 for a
    good one, 1 for a deterministic one).

    >>> reweighted_trust(torch.tensor([[0.5, 0.25]]), torch.tensor([[0.8], [0.0]])).tolist()
    [[0.75, 0.0]]
    """
    weighted = trust * information.T  # (B, K)
    total = weighted.sum(1, keepdim=True)
    scale = torch.where(total > 0, trust.sum(1, keepdim=True) / total.clamp_min(1e-12), 0.0)
    return weighted * scale


def advice_information(distributions: torch.Tensor) -> torch.Tensor:
    """``(K, B)``: how much each teacher's advice says in each state, ``1 - H(pi_k(.|s)) / log
    A`` for its distribution ``(K, B, A)`` over the ``A`` actions: 1 for a point mass, 0 for the
    uniform distribution (a random teacher, a partial teacher outside its region).

    >>> uniform, point = torch.full((3,), 1 / 3), torch.tensor([0.0, 1.0, 0.0])
    >>> advice_information(torch.stack([torch.stack([point, uniform])])).tolist()
    [[1.0, 0.0]]
    """
    n_actions = distributions.shape[-1]
    if n_actions < 2:
        return torch.ones(distributions.shape[:-1])
    entropy = -(distributions * torch.log(distributions.clamp_min(1e-12))).sum(-1)
    return (1.0 - entropy / math.log(n_actions)).clamp_min(0.0)


SILENT_INFORMATION = 1e-3
"""A state's advice is silent where no teacher's information exceeds this (``1 - H / log A``):
every teacher is uniform there, as a random teacher everywhere or a partial one outside its
region, up to rounding."""


def advice_labels(distributions: torch.Tensor) -> torch.Tensor:
    """``(K, B, A)``: each teacher's advice with its uniform floor removed, the label the
    student copies. A distribution is read as ``w * q + (1 - w) / A``, an informative part ``q``
    mixed with uniform noise: the paper's good and noisy teachers are exactly that (their base
    with probability 0.8 / 0.2, else a uniformly random action; appendix A.1.1), and the student
    copies ``q = (pi - min_a pi) / (1 - A min_a pi)``, their base. A point mass is its own
    label; a uniform distribution (``w`` below :data:`SILENT_INFORMATION`) is left as it is (it
    gets no trust: :func:`informative_trust`). Why: a noisy teacher's distribution, 0.33 on its
    base's action and 0.13 on each other, leaves a student fitted to it with margins of a few
    hundredths, and its greedy action loops wherever one of them flips.

    >>> noisy = torch.tensor([[[0.6, 0.2, 0.2]]])  # base action 0 with probability 0.4
    >>> [round(x, 6) for x in advice_labels(noisy)[0, 0].tolist()]
    [1.0, 0.0, 0.0]
    """
    n_actions = distributions.shape[-1]
    floor = distributions.min(-1, keepdim=True).values
    share = 1.0 - n_actions * floor
    labels = (distributions - floor) / share.clamp_min(SILENT_INFORMATION)
    return torch.where(share > SILENT_INFORMATION, labels, distributions)


def silent_states(distributions: torch.Tensor) -> torch.Tensor:
    """``(B,)``: 1.0 where every teacher's advice is uniform (information at most
    :data:`SILENT_INFORMATION`), 0.0 where at least one says something.
    ``low_level_data: silent`` trains the student's policy gradient on those states only.

    >>> uniform, good = torch.full((3,), 1 / 3), torch.tensor([0.1, 0.8, 0.1])
    >>> dists = torch.stack([torch.stack([good, uniform]), torch.stack([uniform, uniform])])
    >>> silent_states(dists).tolist()   # state 0: teacher 0 says something; state 1: nobody
    [0.0, 1.0]
    """
    return silent_information(advice_information(distributions))


def silent_information(information: torch.Tensor) -> torch.Tensor:
    """``(B,)``: 1.0 where no teacher's information ``(K, B)`` exceeds
    :data:`SILENT_INFORMATION`, 0.0 elsewhere (:func:`silent_states` for discrete advice; Box
    advice gives its information directly).

    >>> silent_information(torch.tensor([[1.0, 0.0], [0.0, 0.0]])).tolist()
    [0.0, 1.0]
    """
    return (information.max(0).values <= SILENT_INFORMATION).float()


def imitation_loss(neg_log_likelihoods: torch.Tensor, trust: torch.Tensor) -> torch.Tensor:
    """The graduate variant's imitation term: ``mean_s sum_k trust[s, k] * nll[k, s]``.

    ``neg_log_likelihoods`` ``(K, B)``: how far the low level is from teacher ``k``'s action in
    state ``s``; ``trust`` ``(B, K)``: the high level's probability of choosing teacher ``k``
    in ``s`` (no gradient). The agent's own probability weighs nothing, so the imitation of a
    state fades as the high level hands it to the agent (docs/graduation.md).

    >>> nll = torch.tensor([[2.0, 1.0], [4.0, 3.0]])   # 2 teachers, 2 states
    >>> trust = torch.tensor([[0.5, 0.25], [0.0, 1.0]])
    >>> float(imitation_loss(nll, trust))   # ((0.5*2 + 0.25*4) + (0*1 + 1*3)) / 2
    2.5
    """
    return (trust.T * neg_log_likelihoods).sum(0).mean()


def scaled_squared_error(
    mean: torch.Tensor,
    targets: torch.Tensor,
    half_width: torch.Tensor | None,
    saturated: tuple[torch.Tensor, torch.Tensor] | None = None,
) -> torch.Tensor:
    """``(K, B)``: ``0.5 * mean_d ((mean - targets[k]) / half_width)^2`` for Box actions: the
    negative log-likelihood, up to a constant, of a unit-variance Gaussian in units of the
    action box's half-width. With ``saturated`` ``(low, high)``, the error of the action the
    environment executes (it clips actions to the box): a target at or above ``high`` is met by
    any mean above it, one at or below ``low`` by any mean below it.

    >>> m = torch.tensor([[0.0, 1.0]])
    >>> t = torch.tensor([[[1.0, 1.0]], [[0.0, -1.0]]])
    >>> scaled_squared_error(m, t, torch.tensor([1.0, 2.0])).tolist()   # 0.5*(1+0)/2, 0.5*(0+1)/2
    [[0.25], [0.25]]
    >>> saturated = (torch.tensor([-0.9, -0.9]), torch.tensor([0.9, 0.9]))
    >>> m = torch.tensor([[1.5, 0.5]])   # past the first target (1.0, saturated), short of 1.0
    >>> scaled_squared_error(m, t[:1], torch.tensor([1.0, 1.0]), saturated).tolist()  # (0+0.25)/4
    [[0.0625]]
    """
    error = mean.unsqueeze(0) - targets
    if saturated is not None:
        low, high = saturated
        error = torch.where(targets >= high, error.clamp(max=0.0), error)
        error = torch.where(targets <= low, error.clamp(min=0.0), error)
    scale = 1.0 if half_width is None else half_width
    return 0.5 * ((error / scale) ** 2).mean(-1)


def value_loss(values: torch.Tensor, returns: torch.Tensor) -> torch.Tensor:
    """Squared error of the shared critic against the GAE returns (Eq. 5).

    >>> value_loss(torch.tensor([1.0, 0.0]), torch.tensor([3.0, 1.0])).item()
    2.5
    """
    return ((returns - values) ** 2).mean()


def approx_kl(log_prob: torch.Tensor, old_log_prob: torch.Tensor) -> torch.Tensor:
    """``E[(r - 1) - log r]``, the low-variance KL estimate SB3 uses for target-KL stopping."""
    log_ratio = log_prob - old_log_prob
    return ((torch.exp(log_ratio) - 1) - log_ratio).mean()


def wasted_asks(
    choices: torch.Tensor, information: torch.Tensor, labelled: torch.Tensor
) -> torch.Tensor:
    """``(n,)`` 0/1: the rows where the high level chose a teacher (``choices`` ``(n,)``, ``K``:
    the agent) whose answer, paid for, said nothing there (its :func:`advice_information`
    ``(K, n)`` at most :data:`SILENT_INFORMATION`, ``labelled`` ``(n, K)`` True): a random
    teacher anywhere, a partial one outside the region it knows.

    >>> info = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # teacher 0 speaks in row 0
    >>> asked = torch.tensor([[True, False], [True, False], [False, False]])
    >>> wasted_asks(torch.tensor([0, 0, 2]), info, asked).tolist()
    [0.0, 1.0, 0.0]
    """
    k = information.shape[0]
    rows = torch.arange(len(choices))
    chosen = choices.clamp(max=k - 1)
    said_nothing = information[chosen, rows] <= SILENT_INFORMATION
    return ((choices < k) & labelled[rows, chosen] & said_nothing).float()


def wasted_ask_loss(
    high_logits: torch.Tensor, choices: torch.Tensor, wasted: torch.Tensor
) -> torch.Tensor:
    """The unlikelihood of the asks that said nothing, ``-log(1 - pi_high(e|s))`` summed over
    the ``wasted`` rows (:func:`wasted_asks`) and divided by the minibatch's rows: it lowers
    the high level's choice of that teacher in those states only, so a teacher is asked where
    its answers say something (ask learned under a budget; docs/advice.md).

    >>> logits = torch.log(torch.tensor([[0.5, 0.5], [0.5, 0.5]]))
    >>> round(float(wasted_ask_loss(logits, torch.tensor([0, 1]), torch.tensor([1.0, 0.0]))), 4)
    0.3466
    """
    p = torch.softmax(high_logits, -1).gather(1, choices.view(-1, 1)).squeeze(1)
    return -(torch.log1p(-p.clamp(max=1 - 1e-6)) * wasted).sum() / len(choices)


def normalize(advantages: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    if advantages.numel() < 2:
        return advantages
    return (advantages - advantages.mean()) / (advantages.std() + eps)
