"""Availability as a function of the step (issue 66, point 1): a teacher's chance to be present
given as a schedule (``{linear: [start, end]}`` over the run's progress, ``{steps: [[step,
chance], ...]}`` by environment step) or, from Python, a function of the step. Hand-checked
chances, a teacher that leaves is never chosen nor asked after it left, the budget is never
exceeded, a constant 1 changes nothing, and bad input is one line naming the teacher."""

from __future__ import annotations

import hashlib
import json
import warnings

import gymnasium as gym
import numpy as np
import pytest
import stable_baselines3  # noqa: F401  (imported while collecting: the first test is not its import)
import torch
from test_advice import ask_and_charge

from tlac import TLAC
from tlac.algorithms.advice import AdviceLedger
from tlac.cli import main
from tlac.errors import ConfigError
from tlac.presets import availability_form, availability_problem, make_availability
from tlac.teachers import TeacherSpec
from tlac.two_level.config import AdviceSettings
from tlac.two_level.graduation import SoloEpisodes

torch.set_num_threads(1)

SMALL = {"n_steps": 32, "batch_size": 32, "n_epochs": 2}
LEAVES = 1024  # a multiple of a rollout's 32 steps: the rollout before it is the last it is in


class Spy:
    """A CartPole teacher (push where the pole leans) that records the environment step at
    which it is asked (``model``: set once the model exists)."""

    def __init__(self, name: str):
        self.name, self.rows, self.model = name, 0, None

    def predict(self, obs: np.ndarray) -> np.ndarray:
        self.rows += len(obs)
        return (obs[:, 2] + 0.5 * obs[:, 3] > 0).astype(np.int64)


def _digest(model: TLAC) -> str:
    digest = hashlib.sha256()
    for key, tensor in sorted(model.nets.net.state_dict().items()):
        digest.update(key.encode() + tensor.numpy().tobytes())
    return digest.hexdigest()[:16]


def _cartpole(teachers, **settings):
    return TLAC(gym.make("CartPole-v1"), teachers=teachers, **{"seed": 0, **SMALL, **settings})


# --------------------------------------------------------------------------- the chances
def test_chances_by_hand():
    steps = make_availability({"steps": [[0, 1.0], [20_000, 0.5], [50_000, 0.0]]})
    # piecewise constant in the environment step: the last pair at or before the step
    assert [steps(s, 1.0) for s in (0, 19_999, 20_000, 49_999, 50_000, 10**7)] == [
        1.0,
        1.0,
        0.5,
        0.5,
        0.0,
        0.0,
    ]
    # linear over the learn call's progress remaining (1 -> 0), as learning_rate's:
    # 1.0 + (0.2 - 1.0) * (1 - p): p 1 -> 1.0, p 0.5 -> 0.6, p 0 -> 0.2, whatever the step
    linear = make_availability({"linear": [1.0, 0.2]})
    assert linear(0, 1.0) == 1.0
    assert linear(5, 0.5) == pytest.approx(0.6)
    assert linear(5, 0.0) == pytest.approx(0.2)
    assert make_availability(lambda step: 1.0 if step < 100 else 0.25)(99, 0.0) == 1.0
    assert make_availability(lambda step: 1.0 if step < 100 else 0.25)(100, 1.0) == 0.25
    assert make_availability(0.3)(10**6, 0.0) == 0.3


def test_the_ledger_takes_the_chance_at_the_step():
    ledger = AdviceLedger(
        np.ones(3),
        [{"steps": [[0, 1.0], [100, 0.25]]}, {"linear": [1.0, 0.0]}, lambda s: 0.5],
        None,
        n_envs=1,
        seed=0,
    )
    assert ledger.availability.tolist() == [1.0, 1.0, 0.5]  # at step 0, progress 1
    ledger.draw_presence(np.array([True]), step=150, progress_remaining=0.25)
    assert ledger.availability.tolist() == [0.25, 0.25, 0.5]


def test_presence_follows_the_chance_of_the_episode_start():
    """Drawn per episode start with the chance then; a chance of 0 is absent at once."""
    ledger = AdviceLedger(
        np.ones(2), [{"steps": [[0, 0.25], [1000, 0.0]]}, 1.0], None, n_envs=1, seed=0
    )
    present = []
    for step in range(1000):
        ledger.draw_presence(np.array([True]), step)
        present.append(ledger.present[0].copy())
    present = np.array(present)
    assert present[:, 0].mean() == pytest.approx(0.25, abs=0.04) and present[:, 1].all()
    ledger.present[0, 0] = True  # present in an episode under way...
    ledger.draw_presence(np.array([False]), 1000)  # ... it has left at step 1000
    assert not ledger.present[0, 0] and ledger.present[0, 1]


def test_a_chance_of_one_draws_nothing():
    """A schedule at 1 (or a constant 1) draws nothing from the ledger's stream."""
    ledger = AdviceLedger(
        np.ones(2), [{"steps": [[0, 1.0], [50, 0.5]]}, 1.0], None, n_envs=2, seed=0
    )
    before = ledger.rng.bit_generator.state
    for step in range(50):
        ledger.draw_presence(np.array([True, step % 2 == 0]), step)
    assert ledger.rng.bit_generator.state == before and ledger.present.all()
    ledger.draw_presence(np.array([True, False]), 50)
    assert ledger.rng.bit_generator.state != before


def test_a_teacher_whose_chance_comes_back_to_one_returns():
    """A chance 0 -> 1: absent while 0, present again in the episodes that start after it is
    back at 1 (with no draw: every chance is 1 then), not in one under way."""
    ledger = AdviceLedger(
        np.ones(2), [{"steps": [[0, 1.0], [100, 0.0], [200, 1.0]]}, 1.0], None, n_envs=2, seed=0
    )
    ledger.draw_presence(np.array([True, True]), 150)  # a chance of 0 draws
    assert not ledger.present[:, 0].any()
    before = ledger.rng.bit_generator.state
    ledger.draw_presence(np.array([False, False]), 200)  # back at 1, no episode starts
    assert not ledger.present[:, 0].any()
    ledger.draw_presence(np.array([True, False]), 201)  # env 0 starts an episode
    assert ledger.present[:, 0].tolist() == [True, False] and ledger.present[:, 1].all()
    ledger.draw_presence(np.array([False, True]), 202)
    assert ledger.present.all() and ledger.rng.bit_generator.state == before


def test_the_budget_is_never_exceeded_with_schedules():
    """The property of test_advice's random cases, over chances that change with the step:
    presence follows the chance now (0: never), what is spent never exceeds the budget and is
    the answers' cost, every answer counted once."""
    rng = np.random.default_rng(11)
    forms = [
        0.3,
        1.0,
        {"steps": [[0, 1.0], [10, 0.0]]},
        {"steps": [[0, 0.0], [8, 0.6]]},
        {"linear": [1.0, 0.0]},
        lambda step: 0.9 if step % 7 else 0.0,
    ]
    for case in range(100):
        k, envs = int(rng.integers(1, 4)), int(rng.integers(1, 4))
        costs = rng.choice([0.0, 0.5, 1.0, 3.0], size=k)
        chances = [forms[i] for i in rng.integers(0, len(forms), size=k)]
        budget = float(rng.choice([0.0, 5.0, 40.0]))
        ledger = AdviceLedger(costs, chances, budget, envs, seed=case)
        expected = np.zeros(k, dtype=np.int64)
        for step in range(20):
            ledger.draw_presence(rng.random(envs) < 0.3, step, 1.0 - step / 20)
            assert not ledger.present[:, ledger.availability == 0].any()
            expected += ask_and_charge(ledger, rng, envs, k)
        assert ledger.spent <= budget + 1e-9
        assert ledger.spent == pytest.approx(float(ledger.answers @ costs))
        assert ledger.answers.tolist() == expected.tolist()


# --------------------------------------------------------------------------- in training
@pytest.mark.parametrize(
    "leaves",
    [{"steps": [[0, 1.0], [LEAVES, 0.0]]}, lambda step: 1.0 if step < LEAVES else 0.0],
    ids=["steps", "function"],
)
def test_a_teacher_that_leaves_is_never_chosen_nor_asked_after(leaves):
    pd, here = Spy("pd"), Spy("here")
    model = _cartpole([TeacherSpec(pd, name="pd", availability=leaves), here])
    assert model.limited_advice
    seen: list[tuple[int, int, int]] = []
    model.learn(3000, callback=lambda m: seen.append((m.num_timesteps, pd.rows, here.rows)))
    before = [rows for step, rows, _ in seen if step <= LEAVES]
    after = [rows for step, rows, _ in seen if step >= LEAVES]
    assert before[-1] > 0  # asked while there
    assert set(after) == {before[-1]}  # not once after it left (labels included)
    assert seen[-1][2] > next(h for s, _, h in seen if s == LEAVES)  # the other one still is
    ro = model.collect()
    assert not (ro.choices == 0).any() and not ro.high_mask[..., 0].any()
    assert not ro.askable[..., 0].any()
    summary = model.advice.summary(model.teacher_names)["teachers"]["pd"]
    expected = availability_form(leaves)
    assert summary["availability"] == expected and summary["answers"] == model.advice.answers[0]


@pytest.mark.parametrize("seed", [0, 1])
def test_the_budget_is_never_exceeded_in_training_with_a_schedule(seed):
    a, b = Spy("a"), Spy("b")
    chances = {"a": {"linear": [1.0, 0.2]}, "b": {"steps": [[0, 0.5], [320, 1.0]]}}
    model = _cartpole(
        [a, b], advice_budget=60.0, teacher_cost={"a": 2.0}, availability=chances, seed=seed
    )
    model.learn(960)
    ledger = model.advice
    assert ledger.spent <= 60.0
    assert ledger.spent == pytest.approx(ledger.answers @ np.array([2.0, 1.0]))
    assert (a.rows, b.rows) == tuple(ledger.acted + ledger.labels)


def test_a_constant_availability_of_one_changes_nothing():
    digests = []
    for settings in ({}, {"availability": {"pd": 1.0}}):
        model = _cartpole([Spy("pd"), Spy("other")], **settings)
        assert not model.limited_advice
        digests.append(_digest(model.learn(256)))
    assert digests[0] == digests[1]


def test_a_schedule_counts_as_limiting_and_the_audition_skips_a_gone_teacher():
    assert AdviceSettings(availability={"pd": {"steps": [[0, 1.0]]}}).limits
    assert AdviceSettings(availability={"pd": lambda step: 1.0}).limits
    assert not AdviceSettings(availability={"pd": 1.0}).limits
    solo = SoloEpisodes(1, budget=0.05, seed=0, min_episodes=1, n_teachers=2, teacher_share=0.2)
    solo.solo_episodes, solo.floor = 1, 0.0
    solo.led_counts[:] = [3, 0]
    assert solo.auditioning  # waits for the second teacher's three led episodes...
    solo.gone[:] = [False, True]
    assert not solo.auditioning  # ... unless it has left: it is not waited for


def test_a_helpful_teacher_the_budget_no_longer_pays_is_still_judged():
    """no_teacher_helps: a teacher absent now is not judged, but one whose answers the budget
    no longer pays for is: its labels paid for stay copied when it helped."""
    solo = SoloEpisodes(1, budget=0.05, seed=0, min_episodes=1, n_teachers=2, teacher_share=0.2)
    solo.solo_episodes, solo.floor, solo.untrained = 1, 0.0, 0.0
    solo.led_counts[:] = [3, 3]
    solo.led_sums[:] = [30.0, 0.0]  # teacher 0: 9, 10, 11 (helps); teacher 1: three 0s
    solo.led_squares[:] = [302.0, 0.0]
    assert not solo.no_teacher_helps
    solo.gone[:] = [True, False]  # unaffordable: not awaited, still judged
    assert not solo.no_teacher_helps
    solo.absent[:] = [True, False]  # absent: only teacher 1 is judged, and it does not help
    assert solo.no_teacher_helps


# --------------------------------------------------------------------------- saving
def test_a_schedule_survives_save_and_an_interrupted_run_resumes_exactly(tmp_path):
    settings = {
        "seed": 3,
        "n_steps": 8,
        "batch_size": 8,
        "advice_budget": 100,
        "availability": {"optimal": {"steps": [[0, 1.0], [48, 0.5], [120, 0.0]]}},
        "ask": "always",  # learned paces over its learn call (test_advice's resume tests)
    }
    whole = TLAC("doorkey", teachers=["optimal", "random"], **settings).learn(160)
    half = TLAC("doorkey", teachers=["optimal", "random"], **settings).learn(80)
    half.save(tmp_path / "half.pt", training_state=True)
    resumed = TLAC.load(
        tmp_path / "half.pt", env="doorkey", teachers=["optimal", "random"], resume=True
    )
    assert resumed.config.advice.availability == settings["availability"]
    resumed.learn(80, reset_num_timesteps=False)
    assert _digest(resumed) == _digest(whole)
    assert resumed.advice.answers.tolist() == whole.advice.answers.tolist()


def test_a_function_is_saved_as_its_value_then(tmp_path):
    def leaves(step):
        return 1.0 if step < 64 else 0.0

    model = _cartpole([TeacherSpec(Spy("pd"), name="pd", availability=leaves)]).learn(96)
    model.save(tmp_path / "m.pt", training_state=True)
    with pytest.warns(UserWarning, match=r"availability given as a function .*'pd' 0"):
        loaded = TLAC.load(tmp_path / "m.pt")
    assert loaded.config.advice.availability == {"pd": {"steps": [[0, 0.0]]}}
    assert loaded.config.advice.limits
    env = gym.make("CartPole-v1")
    with pytest.raises(ConfigError, match=r"custom_objects=\{'availability': \{'pd': f\}\}"):
        TLAC.load(tmp_path / "m.pt", env=env, teachers=[Spy("pd")], resume=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again = TLAC.load(
            tmp_path / "m.pt",
            env=env,
            teachers=[Spy("pd")],
            resume=True,
            custom_objects={"availability": {"pd": leaves}},
        )
    assert again.config.advice.availability["pd"] is leaves


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("chance", "message"),
    [
        ({"linear": [1.0, 1.5]}, r"availability\['pd'\] must be \{linear: \[start, end\]\} with"),
        ({"linear": [1.0]}, r"availability\['pd'\] must be \{linear"),
        ({"steps": [[10, 1.0]]}, r"availability\['pd'\] must be \{steps: .* starting at step 0"),
        ({"steps": [[0, 1.0], [0, 0.5]]}, "steps increasing"),
        ({"steps": [[0, -0.1]]}, "chances in"),
        ({"often": 1}, r"availability\['pd'\] must be a number in \(0, 1\], \{linear"),
        ("half", r"availability\['pd'\] must be a number in \(0, 1\]"),
        (0.0, r"availability\['pd'\] must be in \(0, 1\], got 0.0"),
    ],
)
def test_bad_availabilities_say_which_teacher_and_what(chance, message):
    with pytest.raises(ConfigError, match=message) as caught:
        _cartpole([Spy("pd")], availability={"pd": chance})
    assert len(str(caught.value).splitlines()) == 1
    if not isinstance(chance, float):
        assert availability_problem(chance) is not None
    with pytest.raises(ConfigError, match="TeacherSpec availability must be"):
        TeacherSpec(Spy("pd"), availability=chance)


def test_a_function_that_gives_no_chance_says_which_teacher_and_when():
    with pytest.raises(ConfigError, match=r"availability\['pd'\] must give a number in \[0, 1\]"):
        _cartpole([TeacherSpec(Spy("pd"), name="pd", availability=lambda step: "yes")])
    model = _cartpole(
        [TeacherSpec(Spy("pd"), name="pd", availability=lambda step: 1.0 if step < 64 else 2.0)]
    )
    with pytest.raises(ConfigError, match=r"availability\['pd'\] .*got 2.0 at step 64$"):
        model.learn(256)


# --------------------------------------------------------------------------- the command line
def test_cli_takes_a_linear_flag_and_a_step_schedule_by_set(tmp_path):
    out = tmp_path / "linear"
    base = ["train", "--env", "doorkey", "--steps", "64", "--no-progress"]
    assert main([*base, "--out", str(out), "--availability", "optimal=linear:1.0:0.2"]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["advice"]["teachers"]["optimal"]["availability"] == {"linear": [1.0, 0.2]}
    out = tmp_path / "steps"
    chance = "availability={optimal: {steps: [[0, 1.0], [32, 0.0]]}}"
    assert main([*base, "--out", str(out), "--set", chance]) == 0
    result = json.loads((out / "result.json").read_text())
    teacher = result["advice"]["teachers"]["optimal"]
    assert teacher["availability"] == {"steps": [[0, 1.0], [32, 0.0]]}
