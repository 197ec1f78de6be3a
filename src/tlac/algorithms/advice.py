"""Advice that costs (issue 66): a run's query budget, each teacher's cost per answer and its
availability, and the rules that decide in which states the student asks (docs/advice.md).

The paper's TL-AC, and tlac's default, treat every teacher as always there and every answer as
free: the default asks every teacher in every collected state. Here a teacher is asked only
where its answer is used, and each answer is paid for:

* **An answer** is one teacher consulted in one collected state. It is counted once, whether it
  is used to act (the teacher the high level chose, or the one leading a teacher-led
  episode), stored as an imitation label, or both.
* **The budget** (``advice_budget``, in cost units) is spent answer by answer, in the order of
  the rollout; an answer whose cost does not fit in what is left is not asked, so the budget
  is never exceeded. Once nothing fits, no teacher is asked again: the student acts alone.
* **Availability**: each teacher is present in an episode with its probability, drawn per
  episode and environment from this module's own random stream (acting is otherwise
  untouched); a probability may change with the step (a schedule or a function:
  tlac.presets.make_availability), and one of 0 means the teacher has left. An absent
  teacher can neither be chosen (its high-level logit is masked) nor give a label; under
  ask learned, choosing it is asking nobody: its probability goes to the agent
  (:func:`away_to_agent`).
* **Asking rules** (:data:`ASK_RULES`) decide, state by state, whether the student asks at all
  (:func:`ask_gate`): the baselines of the action-advising literature, Torrey & Taylor 2013
  ("Teaching on a Budget") and Amir et al. 2016 ("Interactive Teaching Strategies for Agent
  Training"), read from the student's own policy so that teachers need expose no Q-values.

>>> logits = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
>>> ask_gate("importance", logits, 1.0).tolist(), ask_gate("uncertainty", logits, 0.5).tolist()
([False, True], [True, False])
>>> grant_in_order(np.ones((2, 2), bool), np.array([1.0, 2.0]), remaining=4.0)[0].tolist()
[[True, True], [True, False]]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

ASK_RULES = ("always", "early", "importance", "uncertainty", "learned", "mistake")
"""The asking rules (``ask``): which states the student asks its teachers in."""

DEFAULT_THRESHOLDS = {"importance": 1.0, "uncertainty": 0.5, "mistake": 1.0, "learned": 1.0}
"""``ask_threshold`` where it is left unset: importance (and mistake correcting, which checks
in the states importance flags), a spread of 1 nat between the student's most and least likely
actions (the best e times likelier than the worst); uncertainty, half of the largest possible
entropy; learned, importance's, where answers are scarce (:func:`learned_threshold`)."""

PACING_STEP = 0.5
"""How far the price of an answer moves (in high-level logits per unit of cost) when a
:data:`PACING_HORIZON` steps' worth of the even pace is overspent (or left unspent)."""

PACING_HORIZON = 2048
"""The steps over which a deviation from the even pace moves the price by :data:`PACING_STEP`
(SB3 PPO's rollout): a 16-step rollout moves it by 16/2048 of that, so that the price follows
the spending of many rollouts rather than the noise of one."""

MASKED_LOGIT = -1e9
"""The high-level logit of a teacher that cannot answer: a probability of exactly 0 in float32
and float64, while log-softmax and entropies stay finite (``-inf`` would give ``0 * inf``)."""


def logit_spread(logits: np.ndarray) -> np.ndarray:
    """``(n,)``: the spread ``max_a - min_a`` of the student's action logits in each row.
    Torrey & Taylor 2013 measure a state's importance by the spread of its Q-values, ``max_a
    Q(s, a) - min_a Q(s, a)``: how much the choice of action matters there. A softmax policy's
    logits are its Q-values up to a per-state constant and a temperature (an entropy-regularised
    policy is ``softmax(Q / tau)``), so their spread is that importance read from the student's
    own policy, without asking the teacher for anything.

    >>> logit_spread(np.array([[1.0, -1.0, 0.5], [0.0, 0.0, 0.0]])).tolist()
    [2.0, 0.0]
    """
    return logits.max(axis=-1) - logits.min(axis=-1)


def normalized_entropy(logits: np.ndarray) -> np.ndarray:
    """``(n,)``: the entropy of ``softmax(logits)`` over ``log A``, in [0, 1]: 1 where the
    student has no preference (every action equally likely), 0 where it is certain.

    >>> normalized_entropy(np.array([[0.0, 0.0], [50.0, 0.0]])).round(6).tolist()
    [1.0, 0.0]
    """
    n_actions = logits.shape[-1]
    if n_actions < 2:
        return np.zeros(logits.shape[0])
    z = logits - logits.max(axis=-1, keepdims=True)
    log_p = z - np.log(np.exp(z).sum(axis=-1, keepdims=True))
    entropy = -(np.exp(log_p) * log_p).sum(axis=-1)
    return np.clip(entropy / math.log(n_actions), 0.0, 1.0)


def ask_gate(rule: str, logits: np.ndarray, threshold: float | None = None) -> np.ndarray:
    """``(n,)`` bool: whether the student asks its teachers in each row, by ``rule``, from its
    own action ``logits`` ``(n, A)`` (discrete actions).

    * ``always``: in every state (tlac's default, the paper's TL-AC).
    * ``early``: in every state while the budget lasts: Torrey & Taylor 2013's *early
      advising*. The decision is always's; the name says what a budget makes of it: the
      answers go to the first states the student meets.
    * ``importance``: where the spread of the student's logits is at least ``threshold``
      (:func:`logit_spread`): the student asks where the choice of action matters, Amir et al.
      2016's student-initiated *ask important*, on Torrey & Taylor 2013's importance measure.
    * ``uncertainty``: where the normalised entropy of the student's policy is at least
      ``threshold`` (:func:`normalized_entropy`): the student asks where it does not know what
      to do, Amir et al. 2016's *ask uncertain* (their Q-values close together, here its policy
      near uniform).
    * ``learned``: the high level's choice of a teacher is the ask, and its price
      (:func:`paced_price`) is charged in the high level's logits (:func:`priced_logits`): in
      every state, or, with a ``threshold``, only where importance flags the state.
    * ``mistake``: where importance flags the state (Torrey & Taylor 2013's *mistake
      correcting*): the teacher checks the student's action, and its answer is stored as a
      label only where it disagrees (TLAC.collect).

    ``threshold`` None: :data:`DEFAULT_THRESHOLDS`.

    >>> ask_gate("early", np.zeros((3, 2))).tolist()
    [True, True, True]
    >>> ask_gate("importance", np.array([[0.4, 0.0], [1.5, 0.0]]), 1.0).tolist()
    [False, True]
    >>> ask_gate("learned", np.array([[0.4, 0.0], [1.5, 0.0]])).tolist(), ask_gate(
    ...     "learned", np.array([[0.4, 0.0], [1.5, 0.0]]), 1.0).tolist()
    ([True, True], [False, True])
    """
    n = logits.shape[0]
    if rule in ("always", "early") or (rule == "learned" and threshold is None):
        return np.ones(n, dtype=bool)
    if threshold is None:
        threshold = DEFAULT_THRESHOLDS[rule]
    if rule in ("importance", "mistake", "learned"):
        return logit_spread(logits) >= threshold
    if rule == "uncertainty":
        return normalized_entropy(logits) >= threshold
    raise ValueError(f"unknown asking rule {rule!r}; expected one of {', '.join(ASK_RULES)}")


SCARCE_RATE = 0.01
"""Answers per step (the budget's even pace over the run, per unit of mean cost) below which
answers are scarce: there the learned rule asks only where importance flags the state
(:func:`learned_threshold`)."""


def learned_threshold(rate: float) -> float | None:
    """The importance gate of ``ask learned`` with no ``ask_threshold`` given and discrete
    actions (:attr:`AdviceLedger.gate_when_scarce`), decided at the first rollout from the even
    asking ``rate`` of the budget (answers per step): importance's 1.0
    (:data:`DEFAULT_THRESHOLDS`) where answers are scarce (``rate`` below :data:`SCARCE_RATE`);
    None (every state) otherwise.

    With 1e2 answers over 1e5 steps the untrained high level's few asks fall in states that do
    not matter and cannot yet tell it which teacher helps; gated, they go where the student's
    own logits say the choice matters (MountainCar, 5 seeds: -114.0 +- 0.9 gated, -132.8 in
    every state). With more, the gate gained nothing measured (MountainCar 1e3 and 1e4, DoorKey
    1 optimal + 2 random at 1e4: docs/advice.md), so every state stays open there.

    >>> learned_threshold(100 / 100_000), learned_threshold(1e4 / 1e5), learned_threshold(0.01)
    (1.0, None, None)
    """
    return DEFAULT_THRESHOLDS["learned"] if rate < SCARCE_RATE else None


def starting_price(n_teachers: int, pace: float, cost: float) -> float:
    """The price of an answer, per unit of cost, at which a high level with no preference yet
    (every logit equal) asks at the even ``pace`` (cost units per step) of the budget: it
    chooses any of the ``n_teachers`` with probability ``K e^(-price c) / (K e^(-price c) + 1)``
    (:func:`priced_logits`), set equal to the asking rate ``r = pace / cost``:
    ``price = log(K (1 - r) / r) / cost``; 0 where the budget covers asking as often as the
    untrained high level does (``r >= K / (K + 1)``).

    Without it the untrained high level asks in most states (two teachers and the agent: 2 of
    3) and a budget of 1e3 answers is spent in the first 1,500 steps, before the price could
    learn anything from the spending (issue 66: the budget is not spent in the first episodes).

    >>> round(starting_price(2, 0.01, 1.0), 4)   # 1e3 answers over 1e5 steps: log(198)
    5.2883
    >>> starting_price(2, 0.9, 1.0)
    0.0
    >>> starting_price(2, 0.0, 1.0)   # a budget of 0: no teacher can be asked, at any price
    0.0
    """
    if cost <= 0 or pace <= 0:  # free answers, or nothing left to spend: nothing to pace
        return 0.0
    rate = pace / cost
    if rate >= n_teachers / (n_teachers + 1):
        return 0.0
    return max(math.log(n_teachers * (1.0 - rate) / rate), 0.0) / cost


def paced_price(
    price: float,
    spent: float,
    steps: int,
    remaining: float,
    steps_left: int,
    step: float = PACING_STEP,
    horizon: int = PACING_HORIZON,
) -> float:
    """The price of an answer after a rollout of ``steps`` steps that spent ``spent``: a dual
    variable (the Lagrange multiplier of the budget constraint, moved by dual ascent) that rises
    when the spending ran ahead of the even pace of the budget ``remaining`` at the rollout's
    start over the ``steps_left`` then, and falls when it lagged behind:

        pace = remaining / steps_left;  planned = pace * steps
        price' = max(0, price + step * (spent - planned) / (pace * horizon))

    The move is linear in the overspending, so that its expectation is 0 exactly at the even
    pace (a 16-step rollout spends 0 or at least one answer, never the pace's 0.16: a clipped
    or logarithmic move would settle elsewhere). Nothing left to pace (``remaining`` or
    ``steps_left`` 0): the price is kept.

    Hand-checked: price 5, 30 spent in 1,000 steps, 1,000 left over 100,000 steps: pace 0.01,
    planned 10, 5 + 0.5 * 20 / 20.48 = 5.48828125; 0 spent: 5 - 0.5 * 10 / 20.48.

    >>> paced_price(5.0, 30.0, 1000, 1000.0, 100_000)
    5.48828125
    >>> paced_price(5.0, 0.0, 1000, 1000.0, 100_000)
    4.755859375
    >>> paced_price(0.1, 0.0, 1000, 1000.0, 100_000)   # never below 0
    0.0
    """
    if remaining <= 0 or steps_left <= 0 or steps <= 0:
        return price
    pace = remaining / steps_left
    planned = pace * steps
    return max(0.0, price + step * (spent - planned) / (pace * horizon))


def priced_logits(high_logits: Any, shift: Any) -> Any:
    """The high level's logits ``(n, K + 1)`` with each teacher's price charged: teacher ``k``'s
    logit minus ``shift[k]`` (``price * cost_k``; ``shift`` ``(K,)`` or ``(n, K)``); the agent's
    (the last column) is free. The high level that maximises its advantage minus the price of
    its answers, with an entropy bonus of temperature ``tau``, is ``softmax((Q_e - price c_e) /
    tau)``: a logit shift by the price (the Lagrangian of the budget constraint). NumPy arrays
    and torch tensors alike.

    >>> priced_logits(np.zeros((1, 3)), np.array([1.0, 2.5])).tolist()
    [[-1.0, -2.5, 0.0]]
    """
    k = shift.shape[-1]
    out = high_logits.clone() if hasattr(high_logits, "clone") else high_logits.copy()
    out[:, :k] = out[:, :k] - shift
    return out


def grant_in_order(
    wanted: np.ndarray,
    costs: np.ndarray,
    remaining: float,
    paid: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """Which of the ``wanted`` answers ``(n, K)`` (rows: states in rollout order; columns:
    teachers) are asked, and the budget left after them. Answers are granted row by row,
    teacher by teacher, each while its cost fits in what is left; one that does not fit is
    skipped, and a cheaper one after it may still be granted. So the total cost never exceeds
    ``remaining``. ``paid`` ``(n, K)``: answers already asked (a teacher that acted in that state:
    its label comes with the same answer), granted again at no cost.

    >>> wanted = np.array([[True, True], [True, True]])
    >>> granted, left = grant_in_order(wanted, np.array([2.0, 1.0]), 3.0)
    >>> granted.tolist(), left
    ([[True, True], [False, False]], 0.0)
    >>> paid = np.array([[True, False], [False, False]])
    >>> grant_in_order(wanted, np.array([2.0, 1.0]), 3.0, paid)[0].tolist()
    [[True, True], [True, False]]
    """
    wanted = np.asarray(wanted, dtype=bool)
    free = np.zeros_like(wanted) if paid is None else np.asarray(paid, dtype=bool) & wanted
    charged = wanted & ~free
    bill = np.broadcast_to(costs, wanted.shape)[charged]
    if math.fsum(bill.tolist()) <= remaining:  # everything fits: no loop
        return wanted.copy(), max(remaining - math.fsum(bill.tolist()), 0.0)
    granted = free.copy()
    for i, k in zip(*np.nonzero(charged), strict=True):
        cost = float(costs[k])
        if cost <= remaining:
            granted[i, k] = True
            remaining -= cost  # >= 0: IEEE subtraction of a smaller number
    return granted, remaining


def acting_teachers(choices: np.ndarray, n_teachers: int) -> np.ndarray:
    """``(n, K)`` bool: the teacher that acts in each row (``choices`` ``(n,)``; the agent,
    ``K``, is no teacher).

    >>> acting_teachers(np.array([1, 2, 0]), 2).astype(int).tolist()
    [[0, 1], [0, 0], [1, 0]]
    """
    acting = np.flatnonzero(choices < n_teachers)
    rows = np.zeros((len(choices), n_teachers), dtype=bool)
    rows[acting, choices[acting]] = True
    return rows


def corrected_rows(
    choices: np.ndarray, own: np.ndarray, executed: np.ndarray, n_teachers: int
) -> np.ndarray:
    """``(n,)`` bool, mistake correcting (Torrey & Taylor 2013): the rows where a teacher was
    asked to check the student's action (the high level chose it, ``choices < K``) and
    disagreed: the action it gave (``executed``) is not the one the student meant (``own``, its
    sample). Only there is its answer stored as a label; where it agrees, the action is the
    student's own.

    >>> choices = np.array([0, 1, 2, 0])            # two teachers; 2 is the agent
    >>> own, executed = np.array([1, 0, 1, 0]), np.array([0, 0, 1, 0])
    >>> corrected_rows(choices, own, executed, 2).tolist()
    [True, False, False, False]
    """
    differs = np.asarray(own) != np.asarray(executed)
    if differs.ndim > 1:  # Box actions: any coordinate
        differs = differs.reshape(len(differs), -1).any(axis=1)
    return (np.asarray(choices) < n_teachers) & differs


def per_teacher(
    values: dict[str, float], names: list[str], setting: str, default: float
) -> np.ndarray:
    """``(K,)``: a per-teacher setting (``teacher_cost``, ``availability``) given by name, in
    the order of ``names``; ``default`` where a teacher is not named. A name shared by several
    teachers (``random`` for ``random_1`` and ``random_2``, as tlac names duplicates) sets them
    all; a teacher's own name wins over its group's, in whatever order they are given. A name
    that is no teacher's raises one ConfigError listing the teachers.

    >>> per_teacher({"random": 2.0}, ["optimal", "random_1", "random_2"], "teacher_cost", 1.0)
    array([1., 2., 2.])
    >>> per_teacher({"random_1": 5.0, "random": 2.0}, ["random_1", "random_2"], "cost", 1.0)
    array([5., 2.])
    """
    return np.array([float(v) for v in per_teacher_values(values, names, setting, default)])


def per_teacher_values(
    values: dict[str, Any], names: list[str], setting: str, default: Any
) -> list[Any]:
    """:func:`per_teacher` for values of any kind (an availability may be a schedule or a
    function), as a list in the order of ``names``.

    >>> per_teacher_values({"pd": {"linear": [1, 0]}}, ["pd", "coin"], "availability", 1.0)
    [{'linear': [1, 0]}, 1.0]
    """
    from tlac.errors import ConfigError

    out = [default] * len(names)
    # groups first, so that a teacher's own name (applied after them) wins
    for key, value in sorted(values.items(), key=lambda item: item[0] in names):
        hits = [i for i, n in enumerate(names) if n == key]
        if not hits:
            hits = [
                i
                for i, n in enumerate(names)
                if n.rsplit("_", 1)[0] == key and n.rsplit("_", 1)[-1].isdigit()
            ]
        if not hits:
            teachers = ", ".join(names) or "none"
            raise ConfigError(
                f"TL-AC setting {setting} names teacher {key!r}, not one of this run's teachers "
                f"({teachers})"
            )
        for i in hits:
            out[i] = value
    return out


def mask_logits(high_logits: np.ndarray, can_answer: np.ndarray) -> np.ndarray:
    """The high level's logits ``(n, K + 1)`` with every teacher that cannot answer in a row
    (``can_answer`` ``(n, K)`` False) set to :data:`MASKED_LOGIT`; the agent (the last column)
    is always there. Works on NumPy arrays and torch tensors alike.

    >>> mask_logits(np.zeros((1, 3)), np.array([[True, False]])).tolist()
    [[0.0, -1000000000.0, 0.0]]
    """
    if isinstance(high_logits, np.ndarray):
        keep = np.concatenate([can_answer, np.ones((len(can_answer), 1), bool)], axis=1)
        return np.where(keep, high_logits, MASKED_LOGIT).astype(high_logits.dtype)
    import torch

    keep = torch.cat([can_answer, torch.ones(len(can_answer), 1, dtype=torch.bool)], dim=1)
    return torch.where(keep, high_logits, torch.full_like(high_logits, MASKED_LOGIT))


def away_to_agent(high_logits: Any, away: Any) -> Any:
    """The high level's logits ``(n, K + 1)`` under ask learned, where choosing a teacher is
    asking it: a choice of a teacher that is away (``away`` ``(n, K)`` True: absent from the
    episode) gets no answer, and the student acts. The agent's logit (the last column) becomes
    ``log(e^agent + sum_away e^logit_k)`` and the away teachers' are masked, so each teacher
    present keeps the probability it has when every teacher is there, and an absent one's goes
    to the agent, not (renormalised) to the teachers present: with the optimal teacher away,
    the high level does not ask a random one in its place. In torch the away teachers' logits
    enter the agent's without gradient: as under a mask, the update learns nothing about a
    teacher from the rows it was away (a failed episode it was absent from does not lower its
    choice). Rows with no teacher away are returned as they are. NumPy arrays and torch
    tensors alike.

    >>> out = away_to_agent(np.zeros((2, 3)), np.array([[True, False], [False, False]]))
    >>> np.exp(out[0]).round(6).tolist(), out[1].tolist()   # 1 : 2 = the teacher's 1/3, 2/3
    ([0.0, 1.0, 2.0], [0.0, 0.0, 0.0])
    """
    if isinstance(high_logits, np.ndarray):
        away = np.asarray(away, dtype=bool)
        if not away.any():
            return high_logits
        teachers = np.where(away, high_logits[:, :-1], -np.inf)
        merged = np.logaddexp(high_logits[:, -1], np.logaddexp.reduce(teachers, axis=1))
        out = np.where(away, MASKED_LOGIT, high_logits[:, :-1])
        agent = np.where(away.any(axis=1), merged, high_logits[:, -1])
        return np.concatenate([out, agent[:, None]], axis=1).astype(high_logits.dtype)
    import torch

    away_logits = high_logits[:, :-1].detach()  # no gradient to a teacher from rows it was away
    teachers = torch.where(away, away_logits, torch.full_like(away_logits, -math.inf))
    merged = torch.logsumexp(torch.cat([high_logits[:, -1:], teachers], dim=1), dim=1)
    agent = torch.where(away.any(dim=1), merged, high_logits[:, -1])
    masked = torch.where(away, torch.full_like(teachers, MASKED_LOGIT), high_logits[:, :-1])
    return torch.cat([masked, agent[:, None]], dim=1)


class OutsidePresence:
    """Which teachers the world outside the run says are there now (:meth:`AdviceLedger.
    outside_presence`): a person whose browser tab is closed, or who let a question time out
    (tlac.human), a recorded teacher in a state it never answered. A small holder, so that a
    checkpoint (which keeps the ledger's arrays) does not keep it: it is set again each step.

    >>> OutsidePresence(np.array([[True, False]])).mask.tolist()
    [[True, False]]
    """

    def __init__(self, mask: np.ndarray):
        self.mask = np.asarray(mask, dtype=bool)


class AdviceLedger:
    """The advice a run may still ask and the answers it has asked: the budget left, each
    teacher's presence in every environment's current episode, and per teacher the answers
    asked (``answers``), those used to act (``acted``) and those stored as labels (``labels``;
    an answer both acted on and stored counts once in ``answers``).

    ``costs``: per teacher; ``budget``: cost units, None for no limit. ``availability``: per
    teacher, a number, or a schedule (``{linear: [start, end]}``, ``{steps: [[step, chance],
    ...]}``) or a function of the environment step (tlac.presets.make_availability): the
    chance it is present in an episode, taken at the step at which the episode starts
    (:meth:`draw_presence`). ``names``: the teachers' names, for messages.
    """

    def __init__(
        self,
        costs: np.ndarray,
        availability: Sequence[Any] | np.ndarray,
        budget: float | None,
        n_envs: int,
        seed: int,
        rule: str = "always",
        threshold: float | None = None,
        names: Sequence[str] | None = None,
        discrete: bool = True,
    ):
        from tlac.presets import make_availability

        self.costs = np.asarray(costs, dtype=np.float64)
        given = availability.tolist() if isinstance(availability, np.ndarray) else availability
        # tuples: rebuilt from the settings, not kept in a training state (attributes_state)
        self.availability_given = tuple(given)
        self.names = (
            tuple(names)
            if names is not None
            else tuple(f"teacher {k}" for k in range(len(self.costs)))
        )
        self.schedules = tuple(
            None if isinstance(v, int | float | np.number) else make_availability(v)
            for v in self.availability_given
        )
        # each teacher's chance now: a schedule's at step 0 until draw_presence moves it
        self.availability = np.array(
            [float(v) if f is None else 0.0 for v, f in zip(given, self.schedules, strict=True)],
            dtype=np.float64,
        )
        self.set_availability(0, 1.0)
        self.budget = math.inf if budget is None else float(budget)
        self.remaining = self.budget
        self.rule, self.threshold = rule, threshold
        # ask learned with no threshold given: the gate is decided from the budget's pace at
        # the first rollout (learned_threshold; a float threshold is kept in a checkpoint)
        self.gate_when_scarce = rule == "learned" and threshold is None and discrete
        n_teachers = len(self.costs)
        # until an environment's first episode draws it, only an always-present teacher is
        self.present = np.tile(self.availability >= 1, (n_envs, 1))
        self.answers = np.zeros(n_teachers, dtype=np.int64)
        self.acted = np.zeros(n_teachers, dtype=np.int64)
        self.labels = np.zeros(n_teachers, dtype=np.int64)
        self.spent = 0.0
        self.rng = np.random.default_rng([seed, 0xAD71CE])  # its own stream: acting is untouched
        # ask learned: the price of an answer per unit of cost, charged in the high level's
        # logits (priced_logits); nan until the first rollout sets it (starting_price)
        self.price = math.nan
        # teachers the outside world says are absent now (outside_presence); None: none is
        self.outside: OutsidePresence | None = None

    def outside_presence(self, present: np.ndarray | None) -> None:
        """Say which teachers are there now, beyond the drawn availability: ``present``
        ``(K,)`` or ``(E, K)`` bool (False: absent, it can neither be chosen nor lead now), or
        None (every teacher is). Set before each step by the run (tlac.human: a person with no
        tab open, or away after a question timed out, is absent, so the high level cannot
        choose it).

        >>> ledger = AdviceLedger(np.ones(2), np.ones(2), None, 1, 0)
        >>> ledger.outside_presence(np.array([True, False]))
        >>> ledger.can_lead().tolist()
        [[True, False]]
        """
        if present is None:
            self.outside = None
            return
        self.outside = OutsidePresence(np.broadcast_to(present, self.present.shape))

    @property
    def paced(self) -> bool:
        """The price of answers is paced (ask learned, a budget)."""
        return self.rule == "learned" and math.isfinite(self.budget)

    def shift(self) -> np.ndarray:
        """``(K,)``: what each teacher's answer costs in the high level's logits now."""
        price = self.price if self.paced and math.isfinite(self.price) else 0.0
        return price * self.costs

    def start_pacing(self, steps_left: int) -> None:
        """Before a rollout (ask learned, a budget): the first sets the price at which the
        untrained high level asks at the even pace (:func:`starting_price`), and, with no
        threshold given, the importance gate where answers are scarce
        (:func:`learned_threshold`)."""
        if self.paced and math.isnan(self.price) and steps_left > 0:
            cost = float(self.costs.mean()) if len(self.costs) else 0.0
            pace = self.remaining / steps_left
            self.price = starting_price(len(self.costs), pace, cost)
            if self.gate_when_scarce:
                rate = pace / cost if cost > 0 else math.inf  # free answers are never scarce
                self.threshold = learned_threshold(rate)

    def repace(self, spent: float, steps: int, remaining: float, steps_left: int) -> None:
        """After a rollout of ``steps`` that spent ``spent``, from ``remaining`` over
        ``steps_left`` at its start: the price moves toward the even pace (:func:`paced_price`)."""
        if self.paced and math.isfinite(self.price):
            self.price = paced_price(self.price, spent, steps, remaining, steps_left)

    def set_availability(self, step: int, progress_remaining: float) -> None:
        """Each scheduled teacher's chance (``availability``) at environment step ``step``, in
        a ``learn`` call with ``progress_remaining`` (1 -> 0); a constant one keeps its own. A
        function's value that is no number in [0, 1] is one ConfigError naming the teacher."""
        from tlac.errors import ConfigError

        for k, schedule in enumerate(self.schedules):
            if schedule is None:
                continue
            chance = schedule(step, progress_remaining)
            ok = isinstance(chance, int | float | np.number) and not isinstance(
                chance, bool | np.bool_
            )
            if not ok or not 0.0 <= float(chance) <= 1.0:  # NaN fails too
                raise ConfigError(
                    f"TL-AC setting availability[{self.names[k]!r}] must give a number in "
                    f"[0, 1], got {chance!r} at step {step}"
                )
            self.availability[k] = float(chance)

    def draw_presence(
        self, episode_starts: np.ndarray, step: int | None = None, progress_remaining: float = 1.0
    ) -> None:
        """Draw which teachers are present in the episodes that start now, each with its
        availability; no draw while every teacher's chance is 1 (a constant 1 never draws), and
        then every teacher is present in them (one whose chance came back to 1 returns).
        A scheduled teacher's chance is taken at ``step``, the environment step now, and
        ``progress_remaining`` (:meth:`set_availability`; ``step`` None: as last set), at every
        step: one whose chance is 0 has left, and is absent at once, in the episodes under way
        too (a chance above 0 is drawn for only as episodes start)."""
        starting = np.flatnonzero(episode_starts)
        if step is not None and any(f is not None for f in self.schedules):
            self.set_availability(step, progress_remaining)
            self.present[:, self.availability == 0] = False
        if len(starting) and (self.availability < 1).any():
            draws = self.rng.random((len(starting), len(self.availability)))
            self.present[starting] = draws < self.availability
        elif len(starting):
            # every chance is 1: no draw (the stream holds), but a teacher whose chance came
            # back to 1 after a 0 is present again in the episodes that start now
            self.present[starting] = True

    def affordable(self) -> np.ndarray:
        """``(K,)``: the teachers whose next answer fits in the budget left."""
        return self.costs <= self.remaining

    @property
    def exhausted(self) -> bool:
        """No teacher's answer fits in the budget left: no teacher is asked again."""
        return not bool(self.affordable().any())

    def can_lead(self) -> np.ndarray:
        """``(E, K)``: the teachers that can answer in each environment now, whatever the
        asking rule says (present, affordable, and not absent by the outside world's say:
        :meth:`outside_presence`): not :meth:`away`, and affordable."""
        return ~self.away() & self.affordable()

    def away(self) -> np.ndarray:
        """``(E, K)``: the teachers absent now in each environment (not drawn present in the
        episode, or absent by the outside world's say), affordable or not."""
        away = ~self.present
        if self.outside is not None:
            away = away | ~self.outside.mask
        return away

    def can_answer(self, gate: np.ndarray) -> np.ndarray:
        """``(E, K)``: the teachers the high level may choose in each environment: present,
        affordable, and the student asks there (``gate`` ``(E,)``, :func:`ask_gate`)."""
        return self.can_lead() & np.asarray(gate, dtype=bool)[:, None]

    def charge(
        self, wanted: np.ndarray, paid: np.ndarray | None = None, acting: bool = False
    ) -> np.ndarray:
        """Ask the ``wanted`` answers ``(n, K)`` that fit (:func:`grant_in_order`), count them
        and spend their cost; ``paid``: answers already counted (granted at no cost, counted
        as labels only). ``acting``: the answers are used to act (else stored as labels)."""
        granted, self.remaining = grant_in_order(wanted, self.costs, self.remaining, paid)
        new = granted if paid is None else granted & ~np.asarray(paid, dtype=bool)
        new_counts = new.sum(axis=0)
        self.answers += new_counts
        self.spent += float(new_counts @ self.costs)
        (self.acted if acting else self.labels)[:] += granted.sum(axis=0)
        return granted

    def count_unlimited(self, choices: np.ndarray, labelled: bool) -> None:
        """Count a rollout's answers where advice is not limited (nothing is refused): the
        teachers that acted (``choices`` ``(n,)``, the agent is ``K``) and, where the rollout
        was ``labelled``, every teacher in every row (an acted answer labels its row too)."""
        k = len(self.costs)
        acted = np.bincount(choices[choices < k], minlength=k).astype(np.int64)
        self.acted += acted
        new = np.full(k, len(choices), dtype=np.int64) if labelled else acted
        if labelled:
            self.labels += len(choices)
        self.answers += new
        self.spent += float(new @ self.costs)

    def metrics(self, names: list[str]) -> dict[str, float]:
        """The logged counts: ``advice/answers_<teacher>``, ``advice/spent`` and, with a budget,
        ``advice/remaining``."""
        out = {f"advice/answers_{n}": float(a) for n, a in zip(names, self.answers, strict=True)}
        out["advice/spent"] = self.spent
        if math.isfinite(self.budget):
            out["advice/remaining"] = self.remaining
        if self.paced and math.isfinite(self.price):
            out["advice/price"] = self.price
        return out

    def summary(self, names: list[str]) -> dict[str, object]:
        """For result.json: the budget, what was spent, and per teacher its answers, those
        used to act and those stored as labels; the availability as given (a number, a
        schedule's form, ``"callable"`` for a function)."""
        from tlac.presets import availability_form

        return {
            "budget": None if not math.isfinite(self.budget) else self.budget,
            "spent": self.spent,
            "ask": self.rule,
            **({"price": self.price} if self.paced and math.isfinite(self.price) else {}),
            "teachers": {
                n: {
                    "cost": float(c),
                    "availability": availability_form(p),
                    "answers": int(a),
                    "acted": int(x),
                    "labels": int(lab),
                }
                for n, c, p, a, x, lab in zip(
                    names,
                    self.costs,
                    self.availability_given,
                    self.answers,
                    self.acted,
                    self.labels,
                    strict=True,
                )
            },
        }

    def progress(self, names: list[str]) -> str:
        """The progress bar's text: the answers per teacher and the budget spent.

        >>> ledger = AdviceLedger(np.ones(2), np.ones(2), 10.0, 1, 0)
        >>> _ = ledger.charge(np.array([[True, False]]))
        >>> ledger.progress(["a", "b"])
        'answers a 1 b 0, spent 1/10'
        """
        counts = " ".join(f"{n} {a}" for n, a in zip(names, self.answers, strict=True))
        limit = f"/{self.budget:g}" if math.isfinite(self.budget) else ""
        return f"answers {counts}, spent {self.spent:g}{limit}"
