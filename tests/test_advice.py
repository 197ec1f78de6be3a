"""Advice that costs (issue 66): the asking rules' decisions, the budget never exceeded, absent
teachers never chosen nor asked, the answers counted, and bad input said in one line."""

from __future__ import annotations

import csv
import hashlib
import json
import math

import gymnasium as gym
import numpy as np
import pytest
import stable_baselines3  # noqa: F401  (imported while collecting: the first test is not its import)
import torch

from tlac import TLAC
from tlac.algorithms.advice import (
    PACING_HORIZON,
    AdviceLedger,
    ask_gate,
    away_to_agent,
    corrected_rows,
    grant_in_order,
    logit_spread,
    mask_logits,
    normalized_entropy,
    paced_price,
    per_teacher,
    priced_logits,
    starting_price,
)
from tlac.cli import main
from tlac.errors import ConfigError
from tlac.recording import Recorder
from tlac.teachers import RandomTeacher, TeacherSpec
from tlac.two_level import losses

torch.set_num_threads(1)

SMALL = {"n_steps": 32, "batch_size": 32, "n_epochs": 2}  # many short, cheap updates


class Spy:
    """A CartPole teacher that pushes where the pole leans and counts the states it is asked
    about (``predict`` is its only method: its labels are asked through it too)."""

    def __init__(self, name: str):
        self.name, self.rows = name, 0

    def predict(self, obs: np.ndarray) -> np.ndarray:
        self.rows += len(obs)
        return (obs[:, 2] + 0.5 * obs[:, 3] > 0).astype(np.int64)


# --------------------------------------------------------------------------- the asking rules
def test_rules_decide_by_hand():
    logits = np.array(
        [
            [0.0, 0.0, 0.0],  # no preference: spread 0, entropy 1
            [2.0, 0.0, 0.0],  # spread 2; p = (0.787, 0.107, 0.107), entropy 0.606 of log 3
            [0.5, 0.0, 0.0],  # spread 0.5; entropy 0.983
            [9.0, 0.0, 0.0],  # spread 9; entropy 0.0023
        ]
    )
    assert logit_spread(logits).tolist() == [0.0, 2.0, 0.5, 9.0]
    p = np.exp([2.0, 0, 0]) / np.exp([2.0, 0, 0]).sum()
    by_hand = -(p * np.log(p)).sum() / math.log(3)
    assert normalized_entropy(logits)[1] == pytest.approx(by_hand) == pytest.approx(0.6061, 1e-3)
    assert ask_gate("always", logits).tolist() == [True] * 4
    assert ask_gate("early", logits).tolist() == [True] * 4
    assert ask_gate("importance", logits, 1.0).tolist() == [False, True, False, True]
    assert ask_gate("importance", logits, 2.0).tolist() == [False, True, False, True]  # >=
    assert ask_gate("importance", logits, 2.5).tolist() == [False, False, False, True]
    assert ask_gate("uncertainty", logits, 0.5).tolist() == [True, True, True, False]
    assert ask_gate("uncertainty", logits, 0.7).tolist() == [True, False, True, False]
    assert ask_gate("importance", logits).tolist() == ask_gate("importance", logits, 1.0).tolist()
    assert ask_gate("uncertainty", logits).tolist() == ask_gate("uncertainty", logits, 0.5).tolist()


def test_learned_and_mistake_gates_by_hand():
    logits = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.5, 0.0, 0.0], [9.0, 0.0, 0.0]])
    # learned: the student may ask everywhere (the high level's choice is the ask)
    assert ask_gate("learned", logits).tolist() == [True] * 4
    # with a threshold, learned asks only where importance flags the state (spread >= it)
    assert ask_gate("learned", logits, 1.0).tolist() == [False, True, False, True]
    assert ask_gate("learned", logits, 2.5).tolist() == [False, False, False, True]
    # mistake correcting checks in the states importance flags (spread >= 1 by default)
    assert ask_gate("mistake", logits).tolist() == [False, True, False, True]
    assert ask_gate("mistake", logits, 2.5).tolist() == [False, False, False, True]


def test_starting_price_by_hand():
    # two teachers, 1e3 answers over 1e5 steps (pace 0.01 a step, cost 1): log(2 * 0.99 / 0.01)
    price = starting_price(2, 0.01, 1.0)
    assert price == pytest.approx(math.log(198.0)) == pytest.approx(5.28827, abs=1e-5)
    # at that price a high level with equal logits asks (chooses either teacher) 1% of the time
    p = np.exp(priced_logits(np.zeros((1, 3)), price * np.ones(2)))[0]
    assert p[:2].sum() / p.sum() == pytest.approx(0.01)
    # a teacher of cost 2 at pace 0.01 (0.005 answers a step): log(2 * 0.995 / 0.005) / 2
    assert starting_price(2, 0.01, 2.0) == pytest.approx(math.log(398.0) / 2)
    assert starting_price(2, 0.7, 1.0) == 0.0  # affords the untrained 2 in 3
    assert starting_price(3, 0.5, 0.0) == 0.0  # free answers: nothing to pace


def test_paced_price_by_hand():
    # pace 1000 / 100000 = 0.01; 1000 steps plan 10 answers
    # overspent by 20: + 0.5 * 20 / (0.01 * 2048) = 0.48828125
    assert PACING_HORIZON == 2048
    assert paced_price(5.0, 30.0, 1000, 1000.0, 100_000) == 5.48828125
    assert paced_price(5.0, 10.0, 1000, 1000.0, 100_000) == 5.0  # on the pace: kept
    assert paced_price(5.0, 0.0, 1000, 1000.0, 100_000) == 4.755859375  # behind: falls
    assert paced_price(0.2, 0.0, 1000, 1000.0, 100_000) == 0.0  # never below 0
    assert paced_price(3.0, 5.0, 16, 0.0, 500) == 3.0  # nothing left: kept
    # a 16-step rollout spends 0 or 1 answers: at the pace (16 answers over 16,000 steps: one
    # in 62.5 rollouts) the moves cancel in expectation, so the price settles where the
    # spending keeps the pace
    chance = 16 * 16.0 / 16_000
    up = paced_price(1.0, 1.0, 16, 16.0, 16_000) - 1.0
    down = 1.0 - paced_price(1.0, 0.0, 16, 16.0, 16_000)
    assert chance * up == pytest.approx((1 - chance) * down)


def test_priced_logits_charge_teachers_not_the_agent():
    logits = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]])
    shifted = priced_logits(logits, np.array([0.5, 2.0]))
    assert shifted.tolist() == [[0.5, 0.0, 3.0], [-0.5, -2.0, 0.0]]
    assert logits.tolist() == [[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]]  # a copy
    as_torch = priced_logits(torch.tensor(logits), torch.tensor([[0.5, 2.0], [0.5, 2.0]]))
    assert as_torch.tolist() == shifted.tolist()


def test_corrected_rows_by_hand():
    # teachers 0 and 1, the agent 2: a row is corrected where a teacher acted and its action
    # differs from the one the student sampled
    choices = np.array([0, 1, 2, 0, 1])
    own = np.array([1, 0, 1, 0, 1])
    executed = np.array([0, 0, 1, 0, 0])
    assert corrected_rows(choices, own, executed, 2).tolist() == [True, False, False, False, True]


def test_grant_in_order_by_hand():
    wanted = np.array([[True, True, False], [True, True, True]])
    costs = np.array([1.0, 3.0, 0.5])
    # row 0: teacher 0 (1, left 3), teacher 1 (3, left 0); row 1: none fits but the free one
    granted, left = grant_in_order(wanted, costs, 4.0)
    assert granted.tolist() == [[True, True, False], [False, False, False]] and left == 0.0
    # with 4.5: row 1's teacher 2 (0.5) still fits after teacher 0 and 1 are skipped
    granted, left = grant_in_order(wanted, costs, 4.5)
    assert granted.tolist() == [[True, True, False], [False, False, True]] and left == 0.0
    # an answer already paid (a teacher that acted) labels at no cost: 4 - 1 - 1 - 0.5
    paid = np.array([[False, True, False], [False, False, False]])
    granted, left = grant_in_order(wanted, costs, 4.0, paid)
    assert granted.tolist() == [[True, True, False], [True, False, True]] and left == 1.5
    free = grant_in_order(wanted, np.zeros(3), 0.0)[0]  # free teachers: asked on no budget
    assert free.tolist() == wanted.tolist()


def test_the_budget_is_never_exceeded_random_cases():
    """Property test over random costs (some free), wants, paid answers and budgets."""
    rng = np.random.default_rng(66)
    for _ in range(300):
        n, k = rng.integers(1, 40), rng.integers(1, 5)
        costs = rng.choice([0.0, 0.1, 0.3, 1.0, 2.5, 7.0], size=k)
        wanted = rng.random((n, k)) < rng.random()
        paid = wanted & (rng.random((n, k)) < 0.2)
        budget = float(rng.choice([0.0, 0.7, 3.0, 10.0, 1e9]))
        granted, left = grant_in_order(wanted, costs, budget, paid)
        bill = math.fsum(np.broadcast_to(costs, (n, k))[granted & ~paid].tolist())
        assert bill <= budget + 1e-9 and left >= 0.0
        assert left == pytest.approx(budget - bill, abs=1e-9)
        assert not (granted & ~wanted).any() and not (paid & ~granted).any()
        refused = wanted & ~granted
        assert (np.broadcast_to(costs, (n, k))[refused] > left).all()  # none was left unasked


def ask_and_charge(ledger: AdviceLedger, rng: np.random.Generator, envs: int, k: int) -> np.ndarray:
    """One collection step of random asks and high-level choices among the teachers that can
    answer: the acting answers, then the labels, paid as TL-AC pays them. Checks that only
    present, asked teachers label; returns the answers counted per teacher."""
    can = ledger.can_answer(rng.random(envs) < 0.8)
    choices = np.array([rng.choice(np.flatnonzero(np.append(c, True))) for c in can])
    wanted = np.zeros((envs, k), dtype=bool)
    acting = np.flatnonzero(choices < k)
    wanted[acting, choices[acting]] = True
    acted = ledger.charge(wanted, acting=True)
    labels = ledger.charge(can | acted, paid=acted)
    assert not (labels & ~(can | acted)).any()  # only present, asked teachers label
    return (acted | labels).sum(0)


def test_ledger_counts_add_up_random_cases():
    """Over random costs, availabilities and budgets: presence follows availability (0 never,
    1 always), what is spent never exceeds the budget and is the answers' cost, and every
    answer is counted once however it was used."""
    rng = np.random.default_rng(7)
    for case in range(100):
        k, envs = int(rng.integers(1, 4)), int(rng.integers(1, 4))
        costs = rng.choice([0.0, 0.5, 1.0, 3.0], size=k)
        availability = rng.choice([0.0, 0.3, 1.0], size=k)
        budget = float(rng.choice([0.0, 5.0, 40.0]))
        ledger = AdviceLedger(costs, availability, budget, envs, seed=case)
        expected_answers = np.zeros(k, dtype=np.int64)
        for _step in range(20):
            ledger.draw_presence(rng.random(envs) < 0.3)
            assert not ledger.present[:, availability == 0].any()
            assert ledger.present[:, availability == 1].all()
            expected_answers += ask_and_charge(ledger, rng, envs, k)
        assert ledger.spent <= budget + 1e-9
        assert ledger.spent == pytest.approx(float(ledger.answers @ costs))
        assert ledger.answers.tolist() == expected_answers.tolist()
        assert (ledger.answers <= ledger.acted + ledger.labels).all()


def test_masked_logits_leave_the_agent_and_zero_the_absent():
    logits = np.array([[1.0, 2.0, 3.0]], dtype=np.float32)
    masked = mask_logits(logits, np.array([[False, True]]))
    probs = np.exp(masked - masked.max()) / np.exp(masked - masked.max()).sum()
    assert masked.dtype == np.float32 and probs[0, 0] == 0.0 and probs[0, 1:].sum() == 1.0
    same = mask_logits(torch.tensor(logits), torch.tensor([[True, True]]))
    assert torch.equal(same, torch.tensor(logits))


def test_an_away_teachers_probability_goes_to_the_agent_by_hand():
    # teachers 0 and 1 at e^0 and e^ln2, the agent at e^0: with teacher 0 away, teacher 1 keeps
    # its 2/4 and the agent gets its own 1/4 plus teacher 0's 1/4 (masking alone: 2/3, 1/3)
    logits = np.array([[0.0, math.log(2.0), 0.0], [0.0, math.log(2.0), 0.0]], np.float32)
    away = np.array([[True, False], [False, False]])
    out = away_to_agent(logits, away)
    probs = np.exp(out) / np.exp(out).sum(axis=1, keepdims=True)
    assert np.allclose(probs, [[0.0, 0.5, 0.5], [0.25, 0.5, 0.25]], atol=1e-6)
    assert out.dtype == np.float32 and np.array_equal(out[1], logits[1])  # none away: as it was
    assert away_to_agent(logits, np.zeros((2, 2), bool)) is logits
    # the torch form gives the same, and a finite gradient
    t = torch.tensor(logits, requires_grad=True)
    tout = away_to_agent(t, torch.tensor(away))
    assert np.allclose(tout.detach().numpy(), out) and torch.equal(tout[1], t[1])
    # the update learns nothing about a teacher from the rows it was away (as a mask's)
    torch.log_softmax(tout, -1)[0, 2].backward()
    assert torch.isfinite(t.grad).all() and t.grad[0, 0] == 0
    assert t.grad[0, 2] > 0 and t.grad[0, 1] < 0


def test_per_teacher_names():
    names = ["optimal", "random_1", "random_2"]
    assert per_teacher({}, names, "availability", 1.0).tolist() == [1.0, 1.0, 1.0]
    assert per_teacher({"random_2": 0.5}, names, "availability", 1.0).tolist() == [1, 1, 0.5]
    with pytest.raises(ConfigError, match="names teacher 'oracle', not one of this run's"):
        per_teacher({"oracle": 2.0}, names, "teacher_cost", 1.0)
    # a teacher's own name wins over its group's, whichever comes first
    for given in ({"random_1": 5.0, "random": 2.0}, {"random": 2.0, "random_1": 5.0}):
        assert per_teacher(given, names, "teacher_cost", 1.0).tolist() == [1.0, 5.0, 2.0]


# --------------------------------------------------------------------------- in training
def _cartpole(teachers, **settings):
    return TLAC(gym.make("CartPole-v1"), teachers=teachers, **{"seed": 0, **SMALL, **settings})


def test_an_absent_teacher_is_never_asked_nor_chosen():
    gone, here = Spy("gone"), Spy("here")
    model = _cartpole([gone, here], availability={"gone": 1e-12})
    model.learn(320)
    assert gone.rows == 0 and model.advice.answers[0] == 0
    assert here.rows > 0 and model.advice.answers[1] > 0
    # the high level could not choose it in any row it trained on
    ro = model.collect()
    assert not (ro.choices == 0).any() and not ro.high_mask[..., 0].any()
    assert not model.advice_buffer.labelled[: len(model.advice_buffer), 0].any()


@pytest.mark.parametrize("selector", ["random", "ucb1"])
def test_a_selector_that_reads_no_logits_never_gets_an_absent_teacher(selector):
    gone, here = Spy("gone"), Spy("here")
    model = _cartpole([gone, here], availability={"gone": 1e-12}, selector=selector)
    model.learn(128)
    assert gone.rows == 0 and model.advice.answers[0] == 0
    assert not (model.collect().choices == 0).any()
    if selector == "ucb1":  # its arm is never credited with the agent's episodes
        assert model.selector.counts[0] == 0 and model.selector.counts[1:].sum() > 0


def test_ucb1_picks_a_teacher_whose_ask_gate_is_shut_at_the_episode_start():
    # the gate never opens (threshold out of reach): the agent acts every row, but the
    # episodes still go to UCB1's untried teacher arms first (the gate is per state)
    teachers = [Spy("a"), Spy("b")]
    model = _cartpole(
        teachers, selector="ucb1", ask="importance", ask_threshold=1e9, teacher_episodes=0
    )
    model.learn(320)
    assert model.selector.counts[:2].min() >= 1
    assert teachers[0].rows == teachers[1].rows == 0


def test_a_teacher_the_budget_cannot_pay_does_not_hold_the_audition_open():
    """The graduate variant's audition waits for each teacher's led episodes; one whose answers
    no longer fit in the budget can never lead, so it is not waited for: the audition ends and
    the labels paid for are copied (weaning below 1), instead of nothing ever being copied."""
    costly, cheap = Spy("costly"), Spy("cheap")
    model = _cartpole(
        [costly, cheap], teacher_cost={"costly": 1000.0}, advice_budget=100, ask="early"
    )
    assert model.config.teacher_episodes > 0
    model.learn(1500)
    assert costly.rows == 0 and model.advice.exhausted
    assert model.solo.gone.all() and not model.solo.auditioning
    assert model.solo.weaning < 1.0


def test_a_teacher_half_present_acts_and_labels_only_where_present():
    teacher = Spy("pd")
    model = _cartpole([teacher], availability={"pd": 0.5})
    model.learn(640)
    ro = model.collect()
    chose = ro.choices == 0
    assert chose.any() and ro.askable[..., 0][chose].all()  # chosen only where present
    ledger = model.advice
    # asking means calling: the teacher saw exactly the states it was counted for (an answer
    # both acted on and stored as a label is one answer, asked for its action and its label)
    assert teacher.rows == ledger.acted[0] + ledger.labels[0]
    assert 0 < ledger.answers[0] <= ledger.acted[0] + ledger.labels[0]


def test_learned_asking_never_asks_in_place_of_a_teacher_away():
    """Under ask learned, choosing a teacher is asking it: where it is away, the agent acts
    with the probability the high level gave that teacher, and no other teacher gets it."""
    model = _cartpole(
        [Spy("a"), Spy("b")], availability={"a": 0.5}, ask="learned", teacher_episodes=0
    )
    model.learn(320)
    rows = []  # (obs, away, shift, choice, stored probability): rollouts until a is away
    for _ in range(40):
        ro = model.collect()
        assert (ro.high_away[..., 0] == ~ro.askable[..., 0]).all()
        assert not ro.high_away[..., 1].any()
        seen = ro.obs if model.nets.normalizer is None else ro.net_obs  # what the nets read
        rows.append(
            (seen, ro.high_away[..., 0], ro.high_shift, ro.choices, np.exp(ro.log_prob_high))
        )
        if sum(r[1].sum() for r in rows) >= 64 and sum((~r[1]).sum() for r in rows) >= 64:
            break
    obs, away, shift, choices, stored = (
        np.concatenate([r[i].reshape(-1, *r[i].shape[2:]) for r in rows]) for i in range(5)
    )
    high = model.nets.heads(torch.from_numpy(obs))[0].detach().numpy()
    priced = priced_logits(high, shift)
    probs = np.exp(priced) / np.exp(priced).sum(axis=1, keepdims=True)
    # where a is away, the agent's row has its own probability and a's, b's is b's own; where
    # both are there, each has its own
    assert away.any() and not (choices[away] == 0).any()
    agent = away & (choices == 2)
    assert agent.any() and np.allclose(stored[agent], (probs[:, 0] + probs[:, 2])[agent], atol=1e-5)
    b = away & (choices == 1)
    assert np.allclose(stored[b], probs[b, 1], atol=1e-5)
    here = ~away
    assert np.allclose(stored[here], probs[here, choices[here]], atol=1e-5)


def test_presence_is_drawn_per_episode_with_its_chance():
    ledger = AdviceLedger(np.ones(3), np.array([0.0, 0.25, 1.0]), None, n_envs=2, seed=0)
    present = []
    for _ in range(2000):
        ledger.draw_presence(np.array([True, False]))  # env 0's episodes start, env 1's go on
        present.append(ledger.present.copy())
    present = np.array(present)
    assert present[:, 0].mean(0).tolist()[0] == 0.0 and present[:, 0, 2].all()
    assert present[:, 0, 1].mean() == pytest.approx(0.25, abs=0.03)
    assert (present[:, 1] == [False, False, True]).all()  # not drawn yet: only the sure one


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_budget_is_never_exceeded_in_training(seed):
    rng = np.random.default_rng(seed)
    costs = {"a": float(rng.choice([0.5, 1.0, 3.0])), "b": float(rng.choice([1.0, 2.0]))}
    chances = {"a": float(rng.choice([0.3, 1.0])), "b": float(rng.choice([0.5, 1.0]))}
    budget = float(rng.choice([50.0, 400.0]))
    a, b = Spy("a"), Spy("b")
    model = _cartpole(  # every state asked (a budget's default rule paces its answers)
        [a, b],
        advice_budget=budget,
        teacher_cost=costs,
        availability=chances,
        seed=seed,
        ask="always",
    )
    model.learn(960)
    ledger = model.advice
    assert ledger.spent <= budget
    assert ledger.spent == pytest.approx(ledger.answers @ np.array([costs["a"], costs["b"]]))
    assert ledger.exhausted  # 960 steps ask more than either budget
    assert (a.rows, b.rows) == tuple(ledger.acted + ledger.labels)
    # spent: every episode from now on is the student's, and nobody is asked again
    before = (a.rows, b.rows)
    ro = model.collect()
    assert (ro.choices == 2).all() and (a.rows, b.rows) == before


def test_a_teacher_spec_sets_cost_and_availability():
    pd, other = Spy("pd"), Spy("other")
    model = _cartpole(
        [TeacherSpec(pd, name="pd", cost=2.0, availability=0.5), other], advice_budget=10
    )
    assert model.config.advice.teacher_cost == {"pd": 2.0}
    assert model.config.advice.availability == {"pd": 0.5}
    assert model.advice.costs.tolist() == [2.0, 1.0]
    with pytest.raises(ConfigError, match="give it once"):
        _cartpole([TeacherSpec(pd, name="pd", cost=2.0)], teacher_cost={"pd": 3.0})


def test_answers_are_logged_and_reported(tmp_path):
    recorder = Recorder(tmp_path, ["pd", "agent"], log_interval=64)
    model = _cartpole([Spy("pd")], advice_budget=100, recorder=recorder)
    model.learn(256)
    recorder.close(model.num_timesteps)
    progress = (tmp_path / "progress.csv").read_text()
    assert "advice/answers_pd" in progress and "advice/spent" in progress
    assert "advice/remaining" in progress
    assert model.advice.progress(["pd"]).startswith("answers pd ")
    summary = model.advice.summary(["pd"])
    assert summary["budget"] == 100 and summary["teachers"]["pd"]["answers"] > 0


def test_learned_asking_paces_the_budget():
    """ask learned: the price starts where the untrained high level asks at the even pace, so
    the budget is not spent in the first rollouts; the update's high level sees the priced
    logits it acted with (ratio 1 before any step); labels come only from the teachers that
    acted; the budget is never exceeded."""
    run = _cartpole([Spy("pd"), Spy("coin")], advice_budget=40, ask="learned")
    assert run.solo.teacher_share == 0.0  # no teacher-led episodes: they would ignore the price
    run._schedule = (0, 32_000)  # as learn(32_000) sets it: a pace of 1 answer in 800 steps
    ro = run.collect()
    price = starting_price(2, 40 / 32_000, 1.0)  # log(2 * 0.99875 / 0.00125) = 7.3765
    assert price == pytest.approx(7.3765, abs=1e-4)
    assert ro.high_shift[0, 0].tolist() == pytest.approx([price, price])
    assert run.advice.spent <= 2  # at price 0 the untrained high level would ask 2 in 3 of 32
    assert run.advice.price == pytest.approx(paced_price(price, run.advice.spent, 32, 40.0, 32_000))
    data = ro.flat()  # the update's high-level log-probabilities are those it acted with
    high_logits = run.nets.heads(run.nets.update_rows(data["obs"]))[0]
    high_logits = mask_logits(priced_logits(high_logits, data["high_shift"]), data["high_mask"])
    lp = torch.log_softmax(high_logits, -1).gather(1, data["choices"].view(-1, 1)).squeeze(1)
    assert torch.allclose(lp, data["log_prob_high"], atol=1e-5)

    pd, coin = Spy("pd"), Spy("coin")
    model = _cartpole([pd, coin], advice_budget=40, ask="learned")
    model.learn(3200)
    ledger = model.advice
    assert 0 < ledger.spent <= 40
    assert ledger.labels.tolist() == ledger.acted.tolist() == ledger.answers.tolist()
    assert (pd.rows, coin.rows) == tuple(ledger.acted + ledger.labels)
    buffer = model.advice_buffer  # only the asked states, each labelled by the one that acted
    assert len(buffer) == min(int(ledger.answers.sum()), buffer.capacity)
    assert (buffer.labelled[: len(buffer)].sum(1) == 1).all()
    assert ledger.summary(model.teacher_names)["price"] == ledger.price >= 0


def test_learned_asking_gates_by_importance_where_answers_are_scarce():
    """ask learned with no ask_threshold: where the budget's even pace is under 1 answer per
    100 steps (and actions are discrete), the high level may choose a teacher only where the
    student's logits spread by at least 1 nat (importance's threshold); with more, everywhere.
    The untrained student (logits near 0) flags no state, so a scarce budget asks nobody yet."""
    scarce = _cartpole([Spy("pd"), Spy("coin")], advice_budget=40)
    assert scarce.config.advice.ask == "learned" and scarce.advice.threshold is None
    scarce._schedule = (0, 32_000)  # 40 answers over 32,000 steps: 0.00125 a step, scarce
    ro = scarce.collect()
    assert scarce.advice.threshold == 1.0
    logits = scarce.nets.act_on_input(scarce.nets.normalized(ro.obs.reshape(-1, 4)))[1]
    assert logit_spread(np.asarray(logits)).max() < 1.0  # (the untrained student's)
    assert not ro.high_mask.any() and (ro.choices == 2).all() and scarce.advice.spent == 0

    plenty = _cartpole([Spy("pd"), Spy("coin")], advice_budget=40)
    plenty._schedule = (0, 320)  # 0.125 answers a step: every state may ask
    ro = plenty.collect()
    assert plenty.advice.threshold is None and ro.high_mask.all()

    everywhere = _cartpole([Spy("pd"), Spy("coin")], advice_budget=40, ask_threshold=0.0)
    everywhere._schedule = (0, 32_000)  # scarce, but the threshold given is kept
    assert everywhere.collect().high_mask.all() and everywhere.advice.threshold == 0.0

    box = TLAC(gym.make("Pendulum-v1"), teachers=[lambda o: np.zeros(1)], advice_budget=10)
    assert box.config.advice.ask == "learned" and not box.advice.gate_when_scarce


def test_the_unlikelihood_of_an_ask_that_said_nothing_by_hand():
    """ask learned: -log(1 - p) of the teacher chosen where its answer said nothing; its
    gradient lowers that choice in that row and leaves every other row as it was."""
    logits = torch.zeros(2, 3, requires_grad=True)  # 2 teachers and the agent, p = 1/3 each
    choices, wasted = torch.tensor([1, 0]), torch.tensor([1.0, 0.0])
    loss = losses.wasted_ask_loss(logits, choices, wasted)
    assert float(loss.detach()) == pytest.approx(-math.log(2 / 3) / 2)  # over the 2 rows
    loss.backward()
    # d/dz_j of -log(1 - p_1) = p_1 (1[j = 1] - p_j) / (1 - p_1): 1/3 for j = 1, -1/6 for the
    # others, halved by the mean over rows; a gradient step lowers teacher 1 in row 0 only
    assert logits.grad[0].tolist() == pytest.approx([-1 / 12, 1 / 6, -1 / 12])
    assert logits.grad[1].abs().max() == 0
    info = torch.tensor([[0.0, 1.0], [0.0, 0.0]])  # teacher 0 says nothing in row 0
    labelled = torch.tensor([[True, False], [True, False]])
    assert losses.wasted_asks(torch.tensor([0, 0]), info, labelled).tolist() == [1.0, 0.0]
    assert losses.wasted_asks(torch.tensor([2, 2]), info, labelled).tolist() == [0.0, 0.0]


def _logged(folder, key):
    """The values logged under ``key`` in a run's progress.csv (timestep, key, value rows)."""
    with open(folder / "progress.csv", newline="") as f:
        return [float(row["value"]) for row in csv.DictReader(f) if row["key"] == key]


@pytest.mark.parametrize("second", ["random", "spy"])
def test_asks_that_said_nothing_are_counted_under_learned_asking(tmp_path, second):
    """A teacher whose advice is uniform (RandomTeacher) paid for under ask learned is an ask
    that said nothing (train/wasted_asks, logged at every update); a deterministic one never
    is."""
    space = gym.make("CartPole-v1").action_space
    other = RandomTeacher(space, seed=0, name="coin") if second == "random" else Spy("coin")
    recorder = Recorder(tmp_path, ["pd", "coin", "agent"], log_interval=64)
    model = _cartpole([Spy("pd"), other], advice_budget=300, ask="learned", recorder=recorder)
    model.learn(1024)
    recorder.close(model.num_timesteps)
    wasted = _logged(tmp_path, "train/wasted_asks")
    assert len(wasted) == len(_logged(tmp_path, "train/n_updates")) > 0  # zeros included
    assert (sum(wasted) > 0) is (second == "random")


def test_the_paper_variant_measures_no_ask(tmp_path):
    """The paper variant keeps no advice buffer: its answers are acted on, never measured, so
    no ask is judged (and nothing is logged as if it were)."""
    recorder = Recorder(tmp_path, ["pd", "coin", "agent"], log_interval=64)
    space = gym.make("CartPole-v1").action_space
    coin = RandomTeacher(space, seed=0, name="coin")
    model = _cartpole(
        [Spy("pd"), coin], variant="paper", advice_budget=300, ask="learned", recorder=recorder
    )
    assert model.advice_buffer is None
    model.learn(512)
    recorder.close(model.num_timesteps)
    assert model.advice.spent > 0 and not _logged(tmp_path, "train/wasted_asks")


def test_box_asks_are_not_judged_by_what_they_said(tmp_path):
    """Box actions: a teacher's information comes from the few rows a budget pays for, where a
    noisy teacher reads as a random one: no ask is marked as saying nothing."""
    rng = np.random.default_rng(0)
    noisy = TeacherSpec(lambda o: np.clip(rng.normal(0.0, 0.05, 1), -2, 2), name="noisy")
    recorder = Recorder(tmp_path, ["noisy", "agent"], log_interval=64)
    model = TLAC(
        gym.make("Pendulum-v1"),
        teachers=[noisy],
        advice_budget=50,
        ask="learned",
        recorder=recorder,
        **{"seed": 0, **SMALL},
    )
    model.learn(512)
    recorder.close(model.num_timesteps)
    assert model.advice.spent > 0 and not _logged(tmp_path, "train/wasted_asks")


def test_mistake_correcting_labels_only_disagreements():
    """ask mistake: where importance flags the state, the chosen teacher checks the student's
    sampled action; its answer is stored as a label only where it disagrees."""
    teacher = Spy("pd")
    model = _cartpole([teacher], ask="mistake", ask_threshold=0.0, teacher_episodes=0)
    model.learn(320)  # (ask_threshold 0: every state flagged)
    ro = model.collect()
    acted = ro.choices == 0
    assert acted.any() and ro.corrected is not None
    assert not ro.corrected[~acted].any()  # only where the teacher was asked
    # by hand: the teacher's action against what the student would have done there
    obs = ro.obs.reshape(-1, ro.obs.shape[-1])
    pd_actions = (obs[:, 2] + 0.5 * obs[:, 3] > 0).astype(np.int64).reshape(ro.choices.shape)
    assert (ro.actions[acted] == pd_actions[acted]).all()
    before = len(model.advice_buffer)
    labels_before = int(model.advice.labels[0])
    model.update(ro, 1.0)
    added = int(ro.corrected.sum())
    assert int(model.advice.labels[0]) - labels_before == added
    assert len(model.advice_buffer) == min(before + added, model.advice_buffer.capacity)
    # the answers: every check is one (acted), the corrections among them are labels too
    assert model.advice.answers[0] == model.advice.acted[0]
    with pytest.raises(ConfigError, match="needs discrete actions"):
        TLAC(gym.make("Pendulum-v1"), teachers=[lambda o: np.zeros(1)], ask="mistake")


def _digest(model: TLAC) -> str:
    digest = hashlib.sha256()
    for key, tensor in sorted(model.nets.net.state_dict().items()):
        digest.update(key.encode() + tensor.numpy().tobytes())
    return digest.hexdigest()[:16]


def test_a_budget_never_reached_changes_nothing():
    """The limited path (masks, gates, labels by teacher) with a budget it never reaches and
    ask early trains the same weights as the run without limits, to the byte (DoorKey: labels
    from the first update)."""
    digests = []
    for settings in ({}, {"advice_budget": 1e12, "ask": "early"}):
        model = TLAC(
            "doorkey", teachers=["optimal", "random"], seed=1, n_steps=8, batch_size=8, **settings
        )
        assert model.limited_advice == bool(settings)
        model.learn(160)
        digests.append(_digest(model))
    assert digests[0] == digests[1]


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"teacher_cost": {"a": -1.0}}, r"teacher_cost\['a'\] must be >= 0, got -1.0"),
        ({"availability": {"a": 1.5}}, r"availability\['a'\] must be in \(0, 1\], got 1.5"),
        ({"availability": {"a": 0.0}}, r"availability\['a'\] must be in \(0, 1\], got 0.0"),
        ({"advice_budget": -1}, "advice_budget must be >= 0"),
        ({"ask": "sometimes"}, "unknown ask 'sometimes'"),
        ({"teacher_cost": {"z": 2.0}}, "names teacher 'z', not one of this run's teachers"),
        ({"ask": "learned", "selector": "ucb1"}, "selector 'ucb1' reads no logits"),
        ({"ask_threshold": 1.0}, "ask 'always' asks in every state"),
        ({"ask": "early", "ask_threshold": 1.0}, "ask 'early' asks in every state"),
    ],
)
def test_bad_advice_settings_say_what(settings, message):
    with pytest.raises(ConfigError, match=message):
        _cartpole([Spy("a")], **settings)


def test_bad_teacher_spec_and_rules_for_box_actions():
    with pytest.raises(ConfigError, match="availability must be a number in"):
        TeacherSpec(lambda obs: 0, availability=2.0)
    with pytest.raises(ConfigError, match="needs discrete actions"):
        TLAC(gym.make("Pendulum-v1"), teachers=[lambda o: np.zeros(1)], ask="importance")
    with pytest.raises(ConfigError, match="ask_threshold under ask 'learned'"):
        TLAC(
            gym.make("Pendulum-v1"),
            teachers=[lambda o: np.zeros(1)],
            ask="learned",
            ask_threshold=1.0,
            advice_budget=10,
        )


def test_cli_advice_flags_add_to_set_teacher_by_teacher(tmp_path):
    """--availability / --teacher-cost on top of --set's mapping: merged per teacher."""
    out = tmp_path / "r"
    argv = ["train", "--env", "doorkey", "--teachers", "optimal,random", "--steps", "64"]
    argv += ["--set", "availability={optimal: 0.5}", "--availability", "random=0.25"]
    argv += ["--set", "teacher_cost={optimal: 2}", "--teacher-cost", "random=3"]
    assert main([*argv, "--out", str(out), "--no-progress"]) == 0
    teachers = json.loads((out / "result.json").read_text())["advice"]["teachers"]
    assert teachers["optimal"]["availability"] == 0.5 and teachers["random"]["availability"] == 0.25
    assert teachers["optimal"]["cost"] == 2.0 and teachers["random"]["cost"] == 3.0


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--teacher-cost", "oracle=2"], "names teacher 'oracle'"),
        (["--teacher-cost", "random=-1"], "must be >= 0"),
        (["--availability", "optimal=1.5"], "must be in (0, 1]"),
        (["--teacher-cost", "random"], "--teacher-cost expects NAME=NUMBER"),
        # availability schedules (docs/advice.md)
        (["--availability", "optimal=linear:1.0"], "NAME=NUMBER or NAME=linear:START:END"),
        (["--availability", "optimal=linear:1:2"], "{linear: [start, end]} with start and end"),
        (["--set", "availability={optimal: {steps: [[5, 1.0]]}}"], "starting at step 0"),
        (["--availability", "oracle=linear:1:0"], "names teacher 'oracle'"),
    ],
)
def test_cli_bad_advice_flags_exit_2_with_one_line(tmp_path, capsys, flags, message):
    argv = ["train", "--env", "doorkey", "--steps", "64", "--out", str(tmp_path / "r"), *flags]
    assert main([*argv, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err


def test_an_interrupted_run_resumes_its_budget_exactly(tmp_path):
    """The ledger (budget left, presence, its random stream, the counts) and the labels the
    buffer holds travel in a training-state checkpoint: interrupted and resumed equals
    uninterrupted."""
    settings = {
        "seed": 3,
        "n_steps": 8,
        "batch_size": 8,
        "advice_budget": 100,
        "availability": {"optimal": 0.5},
        "ask": "always",  # learned paces over its learn call: the test below
    }
    whole = TLAC("doorkey", teachers=["optimal", "random"], **settings).learn(160)
    half = TLAC("doorkey", teachers=["optimal", "random"], **settings).learn(80)
    half.save(tmp_path / "half.pt", training_state=True)
    resumed = TLAC.load(
        tmp_path / "half.pt", env="doorkey", teachers=["optimal", "random"], resume=True
    )
    resumed.learn(80, reset_num_timesteps=False)
    assert _digest(resumed) == _digest(whole)
    assert resumed.advice.answers.tolist() == whole.advice.answers.tolist()
    assert resumed.advice.spent == whole.advice.spent <= 100


@pytest.mark.parametrize("budget, gate", [(30, None), (1, 1.0)])
def test_a_learned_asking_interrupted_mid_run_resumes_its_price_exactly(tmp_path, budget, gate):
    """A budget's default rule (learned) paces its price over the learn call: a run stopped
    half-way through that call (as a killed ``tlac train`` resumes from its checkpoint) and
    resumed equals the run left alone, price, answers and gate included (1 answer over 160
    steps is scarce: the importance gate, decided at the first rollout, is kept)."""
    settings = {"seed": 3, "n_steps": 8, "batch_size": 8, "advice_budget": budget}
    teachers = ["optimal", "random"]
    whole = TLAC("doorkey", teachers=teachers, **settings)
    assert whole.config.advice.ask == "learned"
    whole.learn(160)

    def stop_half_way(model):
        if model.num_timesteps < 80:
            return True
        model.save(tmp_path / "half.pt", training_state=True)
        return False

    TLAC("doorkey", teachers=teachers, **settings).learn(160, callback=stop_half_way)
    resumed = TLAC.load(tmp_path / "half.pt", env="doorkey", teachers=teachers, resume=True)
    resumed.learn(80, reset_num_timesteps=False)
    assert resumed.num_timesteps == whole.num_timesteps == 160
    assert _digest(resumed) == _digest(whole)
    assert resumed.advice.price == whole.advice.price
    assert resumed.advice.answers.tolist() == whole.advice.answers.tolist()
    assert resumed.advice.threshold == whole.advice.threshold == gate
    assert whole.advice.spent <= budget and (gate is not None or whole.advice.spent > 0)


def test_a_budget_of_nothing_asks_nobody_under_the_default_rule():
    """advice_budget 0 with the rule a budget gets by default (learned): the student acts
    alone from the first step, and the price has nothing to pace (no division by zero)."""
    pd = Spy("pd")
    model = _cartpole([pd], advice_budget=0).learn(256)
    assert model.config.advice.ask == "learned"
    assert model.advice.spent == 0 and pd.rows == 0
