"""The graduate variant (the default) and the pinned paper variant of TL-AC (issue 8)."""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections import deque

import gymnasium as gym
import numpy as np
import pytest
import torch

from tlac import TLAC
from tlac.algorithms.encoding import OneHotEncoder, make_encoder
from tlac.domains import get_domain
from tlac.errors import ConfigError, TeacherError
from tlac.evaluation import evaluate_student
from tlac.presets import DEFAULT_VARIANT, VARIANTS, load_preset
from tlac.run import RunSpec, train_run
from tlac.teachers.base import advice_actions, as_teacher, self_agreement_information
from tlac.teachers.wrappers import (
    GaussianNoiseTeacher,
    MixedRandomTeacher,
    PartialTeacher,
    RandomTeacher,
)
from tlac.two_level import VARIANT_DEFAULTS, TLACConfig, fast, losses
from tlac.two_level.graduation import (
    AdviceBuffer,
    SoloEpisodes,
    competence,
    entropy_coefs,
    solo_probability,
    worth_deploying,
)
from tlac.two_level.labels import advice_on


def _replay_plan(model: TLAC) -> fast.ReplayPlan:
    """The replayed rows of one minibatch, as the update plans them."""
    batch = model.config.imitation_batch_size
    return fast.replay_plan(model.nets, model.advice_buffer, batch, 1, model._replay_generator)


def _entropy_coefs(model: TLAC) -> torch.Tensor:
    """The entropy coefficients of the model's next gradient step."""
    return entropy_coefs(model._ent_coefs, model.solo, model._handover)


# sha256 (first 16 hex digits) of episodes.csv of the paper variant: DoorKey, seed 3, 6000 steps.
# Only a commit that changes the paper variant on purpose (and says why) may change them.
# The paper variant's low-level KL for the target-KL stop is taken over all rows since issue 9
# (what an implementation on SB3's PPO computes; docs/reproduction.md). The rule it used before,
# agent rows only, is pinned with its digests from before the graduate variant existed: the
# commit that flipped the default changed nothing else.
# Each entry holds one digest per machine type the project has run on (docs/architecture.md,
# "Golden hashes across machines"): a change of behaviour gives bytes that match none. The third
# is an AMD EPYC with AVX-512 (2026-11-25), where the off-policy digests match one of the first two.
PAPER_GOLDEN = {
    (("optimal", "random", "random"), "all"): (
        "0a35bfcdd9dfe4cf",
        "3c8aad06a06823d2",
        "fac82244b95e8d86",
    ),
    (("noisy", "noisy", "noisy"), "all"): (
        "b43ddf3bf06686ca",
        "93fffca39772ad92",
        "7e95da3bd4bb6aef",
    ),
    (("optimal", "random", "random"), "agent"): (
        "6b019105ffece0b1",
        "005a74e0edcb41fd",
        "3af305e7f7241cdf",
    ),
    (("noisy", "noisy", "noisy"), "agent"): (
        "120f9356582ed944",
        "e0650656500ef312",
        "b47df1d2f8b21593",
    ),
}


# The paper variant's update rule since 2026-11-26, per_level (each level's own gradient clip
# and target-KL stop, docs/reproduction.md "One update per level"): taken on an Intel Xeon
# (2026-11-26), where the joint digests above match one of theirs, and on an AMD EPYC with
# AVX-512 (2026-11-27: 4d4feb9, a commit of the Intel digests, gives it the same bytes as
# today's main), and on an AMD EPYC without AVX-512 (2026-11-28: main at 20ba871, unchanged,
# every other test passing); another machine type may need its own digest added. The digests
# above are of update_rule joint, the rule before, which these tests keep pinned.
PER_LEVEL_GOLDEN = {
    ("optimal", "random", "random"): ("d69392e1d3b1620e", "1ad06d8dbf7f7b00", "e9f8ac0cb3c9fb3d"),
    ("noisy", "noisy", "noisy"): ("2b4cd406d3fd7405", "b6a5fed7b485d266", "c1ec94458853a469"),
}


def _paper_run_digest(tmp_path, teachers, overrides) -> str:
    spec = RunSpec(
        env="doorkey",
        teachers=list(teachers),
        steps=6000,
        seed=3,
        eval_episodes=0,
        overrides={"variant": "paper", **overrides},
    )
    train_run(spec, tmp_path)
    return hashlib.sha256((tmp_path / "episodes.csv").read_bytes()).hexdigest()[:16]


def _push_pendulum(obs: np.ndarray) -> np.ndarray:
    """A weak Pendulum controller: torque against the angular speed."""
    return np.array([np.clip(-0.5 * obs[2], -2.0, 2.0)], dtype=np.float32)


@pytest.mark.parametrize(("teachers", "kl_rows"), list(PAPER_GOLDEN))
def test_paper_variant_joint_rule_is_pinned(tmp_path, teachers, kl_rows):
    overrides = {"update_rule": "joint", "kl_rows": kl_rows}
    assert _paper_run_digest(tmp_path, teachers, overrides) in PAPER_GOLDEN[(teachers, kl_rows)]


@pytest.mark.parametrize("teachers", list(PER_LEVEL_GOLDEN))
def test_paper_variant_is_pinned(tmp_path, teachers):
    assert _paper_run_digest(tmp_path, teachers, {}) in PER_LEVEL_GOLDEN[teachers]


def test_variant_defaults_and_explicit_settings():
    paper = TLACConfig(variant="paper")
    assert (paper.distill_coef, paper.solo_budget, paper.low_level_data) == (0.0, 0.0, "all")
    assert (paper.kl_rows, paper.obs_encoding) == ("all", "raw")
    grad = TLACConfig()
    assert grad.variant == "graduate"
    for key, value in VARIANT_DEFAULTS["graduate"].items():
        assert getattr(grad, key) == value
    # an explicit setting wins over the variant's default
    assert TLACConfig(variant="paper", solo_budget=0.2).solo_budget == 0.2
    with pytest.raises(ConfigError, match="variant"):
        TLACConfig.from_settings({"variant": "greedy"})
    with pytest.raises(ConfigError, match="kl_rows"):
        TLACConfig.from_settings({"kl_rows": "some"})
    with pytest.raises(ConfigError, match="solo_budget"):
        TLACConfig.from_settings({"solo_budget": -0.1})


def test_python_api_uses_the_domain_preset():
    for name in ("doorkey", "hopper"):
        preset = load_preset(get_domain(name).presets["tlac"], "tlac")
        model = TLAC(name, teachers=[], seed=0)
        for key in ("n_envs", "n_steps", "batch_size", "n_epochs", "gamma", "use_sde"):
            if key in preset:
                assert getattr(model.config, key) == preset[key], (name, key)
        assert model.n_envs == preset.get("n_envs", 1)
    # an explicit setting still wins
    assert TLAC("hopper", teachers=[], n_steps=32, batch_size=32).config.n_steps == 32


def test_a_preset_value_given_per_variant_follows_the_run_variant():
    preset = {"n_steps": 16, "max_grad_norm": {"graduate": 100.0, "paper": 0.5}}
    assert TLACConfig.from_settings(preset).max_grad_norm == 100.0
    assert TLACConfig.from_settings({**preset, "variant": "paper"}).max_grad_norm == 0.5
    # a schedule ({linear: ...}) and the advice mapping are not values per variant
    cfg = TLACConfig.from_settings({"learning_rate": {"linear": [1e-3, 0.0]}})
    assert cfg.learning_rate == {"linear": [1e-3, 0.0]}
    with pytest.raises(ConfigError, match=r"max_grad_norm.*'paper'"):
        TLACConfig.from_settings({"variant": "paper", "max_grad_norm": {"graduate": 1.0}})
    with pytest.raises(ConfigError, match="unknown variant 'papr'"):
        TLACConfig.from_settings({**preset, "variant": "papr"})
    # the presets' list of variants (a lower layer) is TL-AC's own
    assert tuple(VARIANT_DEFAULTS) == VARIANTS and TLACConfig().variant == DEFAULT_VARIANT


def test_a_users_environment_gets_the_default_preset():
    default = load_preset("default", "tlac")
    # docs/graduation.md, "Users' own environments": SB3 PPO's rollouts, the student's own
    # policy gradient everywhere, the imitation weaned by competence, a fifth of episodes solo,
    # raw observations normalised, 30% of the assisted episodes led by one teacher
    expected = dict(
        n_steps=2048,
        batch_size=64,
        n_epochs=10,
        learning_rate=3e-4,
        optimizer="adam",
        gae_lambda=0.95,
        target_kl=None,
        ent_coef_high=0.01,
        ent_cap_high=0.0,
        low_level_data="agent",
        wean_imitation=True,
        solo_budget=0.2,
        normalize_obs="auto",
        teacher_episodes=0.3,
    )
    assert default == expected
    model = TLAC(gym.make("CartPole-v1"), teachers=[lambda obs: 0], seed=0)
    assert model.config == TLACConfig(**expected)
    assert model.config.variant == "graduate"
    # the default preset is the graduate variant's: the paper variant on a user's environment
    # is Algorithm 1 as written (no solo or teacher-led episodes, no weaning, Table 5's rollouts)
    paper_on_users = TLAC(gym.make("CartPole-v1"), teachers=[lambda obs: 0], variant="paper")
    assert paper_on_users.config == TLACConfig(variant="paper")
    # the former opt-in preset is the default now: its name is unknown
    with pytest.raises(ConfigError, match=r"unknown preset 'past-teachers'"):
        TLAC(gym.make("CartPole-v1"), teachers=[lambda obs: 0], preset="past-teachers")
    # a named domain's preset leaves the high-level bonus to the graduate variant: capped
    doorkey = TLAC("doorkey", teachers=["optimal"]).config
    assert (doorkey.ent_coef_high, doorkey.ent_cap_high, doorkey.ent_coef) == (0.03, 0.5, 0.0)
    paper = TLAC("doorkey", teachers=["optimal"], variant="paper").config
    assert (paper.ent_coef_high, paper.ent_cap_high) == (None, 0.0)
    assert TLAC(gym.make("CartPole-v1"), teachers=[], ent_coef_high=0.0).config.ent_coef_high == 0
    hopper = TLAC(gym.make("Pendulum-v1"), teachers=[], preset="hopper", batch_size=8)
    assert hopper.config.n_epochs == load_preset("hopper", "tlac")["n_epochs"]


def test_imitation_loss_hand_checked():
    nll = torch.tensor([[0.5, 2.0, 1.0], [3.0, 0.0, 4.0]])  # 2 teachers x 3 states
    trust = torch.tensor([[1.0, 0.0], [0.5, 0.5], [0.25, 0.75]])
    # state 0: 0.5 ; state 1: 0.5*2 + 0.5*0 = 1 ; state 2: 0.25*1 + 0.75*4 = 3.25
    assert float(losses.imitation_loss(nll, trust)) == pytest.approx((0.5 + 1.0 + 3.25) / 3)


def test_scaled_squared_error_hand_checked():
    mean = torch.tensor([[0.5, -1.0]])
    targets = torch.tensor([[[1.5, 1.0]]])
    # ((0.5 - 1.5) / 2)^2 = 0.25 ; ((-1 - 1) / 1)^2 = 4 ; 0.5 * mean = 0.5 * 2.125
    got = losses.scaled_squared_error(mean, targets, torch.tensor([2.0, 1.0]))
    assert got.tolist() == [[pytest.approx(1.0625)]]


def test_box_imitation_is_a_gaussian_of_a_tenth_of_the_half_width():
    """Pendulum's box is [-2, 2] (half-width 2): a teacher 0.2 away from the low level's mean
    costs 0.5 * (0.2 / (0.1 * 2))^2 = 0.5 nats."""
    from tlac.two_level.networks import IMITATION_STD

    env = gym.make("Pendulum-v1")
    model = TLAC(env, teachers=[lambda obs: np.array([0.0], np.float32)], seed=0)
    assert IMITATION_STD == 0.1
    mean = torch.tensor([[0.5], [-1.0]])
    advice = torch.tensor([[[0.7], [-1.0]]])  # 1 teacher x 2 states x 1 dim
    nll = model.nets.advice_nll(mean, torch.zeros(2, 64), advice)
    assert nll.tolist() == [[pytest.approx(0.5), pytest.approx(0.0)]]


def test_a_box_teacher_pushing_at_a_bound_is_copied_by_any_mean_beyond_it():
    """Pendulum's box [-2, 2]: a teacher's 1.95 is within 5% of the half-width (0.1) of the bound,
    so any mean above 1.95 executes what it means (the environment clips to 2) and costs nothing,
    a mean of 1.75 costs 0.5 * (0.2 / 0.2)^2 = 0.5 nats; -1.95 the same below; an inner 1.85 is
    copied as before, so 2.05 costs 0.5 * (0.2 / 0.2)^2 = 0.5. An unbounded box has no bound."""
    model = TLAC(gym.make("Pendulum-v1"), teachers=[lambda obs: np.array([0.0], np.float32)])
    low, high = model.nets.saturated
    assert low.tolist() == [pytest.approx(-1.9)] and high.tolist() == [pytest.approx(1.9)]
    mean = torch.tensor([[2.6], [1.75], [-3.0], [2.05]])
    advice = torch.tensor([[[1.95], [1.95], [-1.95], [1.85]]])
    nll = model.nets.advice_nll(mean, torch.zeros(4, 64), advice)
    assert nll.tolist() == [[0.0, pytest.approx(0.5), 0.0, pytest.approx(0.5)]]
    unbounded = gym.spaces.Box(-np.inf, np.inf, (1,), np.float32)
    env = gym.wrappers.TransformAction(gym.make("Pendulum-v1"), lambda a: a, unbounded)
    low, high = TLAC(env, teachers=[lambda obs: np.zeros(1, np.float32)]).nets.saturated
    assert low.tolist() == [-np.inf] and high.tolist() == [np.inf]


def test_solo_probability_keeps_the_expected_cost_within_budget():
    for c in np.linspace(0.0, 0.999, 50):
        p = solo_probability(float(c), 0.05)
        assert 0.05 <= p <= 1.0
        assert p * (1.0 - c) <= 0.05 + 1e-12
    assert solo_probability(0.5, 0.0) == 0.0
    assert competence(solo=0.2, assisted=0.2, floor=0.2) == 0.0  # no evidence yet
    assert competence(solo=-3.0, assisted=1.0, floor=0.0) == 0.0


def test_solo_episodes_follow_competence():
    solo = SoloEpisodes(n_envs=4, budget=0.05, seed=0, window=10, min_episodes=3)
    assert solo.probability == 0.05  # nothing measured yet
    solo.active[:] = [True, True, True, False]
    for i in range(3):
        solo.end(i, 0.0)  # three failed solo episodes set the floor at 0
    for _ in range(3):
        solo.end(3, 1.0)  # three assisted episodes show what the teachers reach
    assert solo.floor == 0.0 and solo.best_assisted == 1.0 and solo.competence == 0.0
    # assisted episodes getting worse must not read as a competent student
    for _ in range(10):
        solo.end(3, 0.0)
    assert solo.best_assisted == 1.0 and solo.competence == 0.0
    solo.active[:] = True
    for _ in range(30):
        solo.end(0, 0.99)
    assert solo.competence == pytest.approx(0.99)
    assert solo.probability == 1.0
    flags = solo.start(np.array([True, False, True, False]))
    assert flags[0] and flags[2]


def test_solo_window_decides_which_student_is_deployed():
    """A full window of solo returns within one standard error of the best window's mean
    deploys the student that played it; a clearly worse window does not, and never lowers
    the best."""
    assert worth_deploying(deque([2.0, 4.0]), best=-np.inf) == (True, 3.0)  # the first window
    assert worth_deploying(deque([1.0, 3.0]), best=3.0) == (False, 3.0)  # 2 < 3 - 1/sqrt(2)
    assert worth_deploying(deque([2.0, 4.0, 2.0, 4.0]), best=3.4) == (True, 3.4)  # 3 >= 3.4 - 0.5
    solo = SoloEpisodes(n_envs=1, budget=1.0, seed=0, window=3, min_episodes=1)
    solo.active[:] = True
    deploys = [solo.end(0, r) for r in (0.0, 2.0, 4.0, 1.0, 0.0, 0.0)]
    # full at the 3rd (mean 2), best 7/3 at the 4th, 5/3 (se 0.98) still close, 1/3 not
    assert deploys == [False, False, True, True, True, False]
    assert solo.best_solo == pytest.approx(7 / 3)
    solo.active[:] = False
    assert solo.end(0, 5.0) is False  # assisted episodes never deploy


def _same_student(a, b) -> bool:
    """Whether two student snapshots hold the same weights."""
    pairs = zip(a.layers, b.layers, strict=True)
    return all(np.array_equal(x, y) for pa, pb in pairs for x, y in zip(pa, pb, strict=True))


def _solo_cartpole(n_steps: int) -> TLAC:
    """TL-AC on CartPole with one upright teacher and every episode the student's alone."""
    return TLAC(
        gym.make("CartPole-v1"),
        teachers=[lambda obs: int(obs[2] > 0)],
        seed=0,
        solo_budget=1.0,
        n_steps=n_steps,
        batch_size=min(n_steps, 64),
    )


def test_a_renewal_deploys_the_student_that_played_the_episodes(tmp_path):
    """The kept student renewed is the one that collected the last rollout (whose episodes
    said it was worth it), not the live weights its update left; a checkpoint keeps it."""

    def upright(obs):
        return int(obs[2] > 0)

    m = TLAC(
        gym.make("CartPole-v1"),
        teachers=[upright],
        seed=0,
        solo_budget=1.0,
        n_steps=16,
        batch_size=16,
    )
    m.learn(2000, progress_bar=False)
    collector = m.collector  # taken before the last update, which moved the live weights on
    assert not _same_student(collector, m.nets.snapshot_student(m.num_timesteps))
    m.solo.solo_returns.extend([1000.0] * 20)  # a new best window, whatever ends next
    m.learn(16, reset_num_timesteps=False)
    assert m.deployed is m.collector and not _same_student(m.deployed, m.nets.snapshot_student(0))
    path = m.save(tmp_path / "c.pt", training_state=True)
    loaded = TLAC.load(path, env=gym.make("CartPole-v1"), teachers=[upright], resume=True)
    assert _same_student(loaded.collector, m.collector)
    assert loaded.collector.num_timesteps == m.collector.num_timesteps == 2016
    loaded.set_parameters(TLAC.load(path).get_parameters())  # weights from outside
    assert loaded.collector is None  # the next renewal before an update takes the live ones


def test_the_weights_a_model_starts_from_are_never_the_kept_student():
    """Windows played before the first update never renew the kept student; after it, while the
    starting weights were the collecting ones, a renewal takes the live weights (a one-rollout
    run deploys what its update made); from then on, the student one update behind them."""

    m = _solo_cartpole(n_steps=512)
    asked_untrained = []

    def untrained_windows_only() -> bool:  # an untrained student's lucky windows
        asked_untrained.append(m._n_updates == 0)
        return m._n_updates == 0

    m.solo.latest_is_worth_deploying = untrained_windows_only
    m.learn(512, progress_bar=False)
    assert sum(asked_untrained) >= 2 and asked_untrained[-1] is False  # during and at the end
    assert m.deployed is None and m.collector is None  # predict: the live, updated weights
    m.solo.latest_is_worth_deploying = lambda: True  # from now on every window qualifies
    m._deploy_if_worth(True)
    after_one = m.nets.snapshot_student(512)
    assert _same_student(m.deployed, after_one)
    m.learn(512, reset_num_timesteps=False, progress_bar=False)
    assert m.deployed is m.collector and _same_student(m.collector, after_one)
    assert not _same_student(m.deployed, m.nets.snapshot_student(1024))


def _box_model(**settings):
    env = gym.make("Pendulum-v1")

    def swing(obs):
        return np.clip(np.array([-2.0 * obs[2]], dtype=np.float32), -2.0, 2.0)

    return TLAC(env, teachers=[swing], seed=0, n_steps=8, batch_size=8, **settings)


def test_the_kept_student_is_what_predict_deploys_and_save_keeps(tmp_path):
    """The kept student: a snapshot acts exactly as the live student did when it was taken,
    and goes on acting so after the live weights move on; save/load keeps it. With no solo
    episodes (the paper variant) predict uses the live weights."""
    model = _box_model(normalize_obs=True, obs_encoding="raw")
    model.learn(64, progress_bar=False)
    obs = np.stack([model.observation_space.sample() for _ in range(20)])
    before = model.predict(obs, deterministic=True)[0]
    model.deployed = model.nets.snapshot_student(model.num_timesteps)
    assert np.array_equal(model.predict(obs, deterministic=True)[0], before)
    model.learn(64, progress_bar=False)  # the live weights and the normaliser move on
    live = model.nets.act(obs)[1]
    assert not np.allclose(live, before)
    assert np.array_equal(model.predict(obs, deterministic=True)[0], before)
    path = model.save(tmp_path / "m.pt")
    loaded = TLAC.load(path)
    assert loaded.deployed.num_timesteps == model.deployed.num_timesteps == 64
    assert np.array_equal(loaded.predict(obs, deterministic=True)[0], before)
    # solo episodes deploy a student by themselves
    m = _solo_cartpole(n_steps=16)  # every episode solo: the window of 20 fills in 2000 steps
    m.learn(2000, progress_bar=False)
    assert len(m.solo.solo_returns) == m.solo.solo_returns.maxlen
    assert m.deployed is not None
    # the end of learn deploys the student that collected the last rollout if the latest
    # window qualifies, else keeps the one it had (16-step rollouts: each learn(16) is one)
    m.solo.solo_returns.extend([0.0] * 20)
    m.solo.best_solo, kept = 100.0, m.deployed
    m.learn(16, reset_num_timesteps=False)
    assert m.deployed is kept  # far below the best window
    m.solo.solo_returns.extend([1000.0] * 20)  # a new best window, whatever ends next
    m.learn(16, reset_num_timesteps=False)
    assert m.deployed.num_timesteps == m.num_timesteps == 2032
    paper = TLAC("doorkey", teachers=["random"], seed=0, variant="paper")
    paper.learn(64, progress_bar=False)
    assert paper.solo is None and paper.deployed is None


def test_low_level_learns_from_the_agents_rows_whatever_the_kl_rule():
    """``low_level_data: agent`` means the agent's rows (solo episodes included) train the low
    level's policy gradient; the KL rule only chooses the rows of the stop. Before 2026-11-23
    the loss rows WERE the KL rows, so the graduate variant's ``kl_rows: high`` zeroed them
    (its student learnt by imitation alone)."""
    from tlac.two_level.rows import row_weights

    data = {
        "log_prob_low": torch.zeros(4),
        "log_prob_high": torch.zeros(4),
        "choices": torch.tensor([0, 2, 1, 2]),  # 2 teachers: choice 2 is the agent
        "solo": torch.tensor([0.0, 0.0, 0.0, 1.0]),
    }
    for kl_rows in ("high", "agent", "all"):
        cfg = TLACConfig.from_settings({"kl_rows": kl_rows, "low_level_data": "agent"})
        rows = row_weights(cfg, data, 2, True, True, has_advice=True)
        assert rows.loss[0].tolist() == [0.0, 1.0, 0.0, 1.0]
        assert rows.loss[1].tolist() == [1.0, 1.0, 1.0, 0.0]  # the high level chose nothing solo
    rows = row_weights(cfg, data, 2, True, True, has_advice=True)
    assert rows.kl[0].tolist() == [1.0, 1.0, 1.0, 1.0]  # kl_rows all
    cfg = TLACConfig.from_settings({})  # silent, with no silent state: imitation alone
    rows = row_weights(cfg, data, 2, True, True, has_advice=True)
    assert rows.loss[0].tolist() == [0.0] * 4
    # no advice yet (the first update) or no teachers at all: the agent's rows, as PPO
    rows = row_weights(cfg, data, 2, True, True, has_advice=False)
    assert rows.loss[0].tolist() == [0.0, 1.0, 0.0, 1.0]


def test_silent_rows_carry_the_agents_policy_gradient():
    """``low_level_data: silent`` (the graduate default): the agent's rows in the states where
    every teacher's advice is uniform; teacher rows stay out. Before any advice, the agent's
    rows (PPO); with no silent state (Box actions, point-mass teachers), none at all."""
    from tlac.two_level.rows import row_weights

    data = {
        "log_prob_low": torch.zeros(4),
        "log_prob_high": torch.zeros(4),
        "choices": torch.tensor([0, 2, 1, 2]),  # 2 teachers: choice 2 is the agent
        "solo": torch.tensor([0.0, 0.0, 0.0, 1.0]),
    }
    cfg = TLACConfig.from_settings({})
    assert cfg.low_level_data == "silent" and cfg.kl_rows == "high"
    silent = torch.tensor([1.0, 0.0, 1.0, 1.0])
    rows = row_weights(cfg, data, 2, True, True, has_advice=True, silent=silent)
    assert rows.loss[0].tolist() == [0.0, 0.0, 0.0, 1.0]  # the agent's silent rows
    assert row_weights(cfg, data, 2, True, True, True).loss[0].tolist() == [0.0] * 4
    assert row_weights(cfg, data, 2, True, True, False).loss[0].tolist() == [0.0, 1.0, 0.0, 1.0]


def test_silent_states_are_where_no_teacher_speaks():
    """A good and a noisy DoorKey teacher are never uniform, so no state the student met is
    silent; with a random teacher alone every state is, and the student's own rows carry a
    policy gradient there (the test can fail: silent_states reads the stored advice)."""
    for teachers, expected in ((["good", "noisy"], [0.0]), (["random"], [1.0])):
        model = TLAC("doorkey", teachers=teachers, seed=1)
        model.learn(320)
        buf = model.advice_buffer
        advice = buf.advice[: len(buf)].transpose(0, 1)  # (teachers, states, actions)
        assert losses.silent_states(advice).unique().tolist() == expected


def test_teacher_led_episodes_are_played_by_one_teacher_chosen_by_ucb1():
    """``teacher_episodes``: a share of the non-solo episodes is played from start to end by
    one teacher, chosen by UCB1 over the returns of its earlier led episodes; they count as
    assisted episodes for competence."""
    solo = SoloEpisodes(4, budget=0.0, seed=0, n_teachers=2, teacher_share=1.0)
    solo.start(np.ones(4, dtype=bool))
    assert not solo.active.any() and sorted(set(solo.leader.tolist())) <= [0, 1]
    for i in range(4):  # teacher 1's episodes return 10, teacher 0's 0
        solo.end(i, 10.0 * solo.leader[i])
    assert solo.led_counts.sum() == 4 and list(solo.assisted_returns) == [
        10.0 * k for k in solo.leader
    ]
    assert solo.led_counts.min() > 0  # (seed 0: both tried) UCB1 now prefers teacher 1
    solo.start(np.ones(4, dtype=bool))
    assert (solo.leader == 1).all()
    # without a share, no led episode and no extra draw from the generator
    plain, led = SoloEpisodes(2, 0.5, seed=3), SoloEpisodes(2, 0.5, seed=3, n_teachers=2)
    assert (plain.start(np.ones(2, bool)) == led.start(np.ones(2, bool))).all()
    assert (led.leader == -1).all()


def test_teacher_led_rows_carry_the_leader_as_the_high_level_choice():
    model = TLAC(
        gym.make("CartPole-v1"),
        teachers=[lambda obs: 0, lambda obs: 1],
        seed=0,
        n_steps=256,
        batch_size=64,
        teacher_episodes=1.0,
        solo_budget=1e-9,  # (solo episodes on, almost never drawn)
    )
    model.solo.solo_episodes, model.solo.led_counts[:] = 5, 3  # (past the audition)
    ro = model.collect()
    choices, actions = ro.choices.reshape(-1), ro.actions.reshape(-1)
    assert set(np.unique(choices).tolist()) <= {0, 1}  # never the agent, never mixed per step
    assert (actions == choices).all()  # teacher k pushes k
    starts = np.flatnonzero(np.r_[True, ro.dones.reshape(-1)[:-1]])
    for a, b in zip(starts, [*starts[1:], len(choices)], strict=True):
        assert len(set(choices[a:b].tolist())) == 1  # one teacher per episode
    with pytest.raises(ConfigError, match="teacher_episodes needs solo episodes"):
        TLAC(gym.make("CartPole-v1"), teachers=[lambda obs: 0], teacher_episodes=0.5, solo_budget=0)


def test_wean_imitation_scales_the_imitation_weight_by_one_minus_competence():
    model = TLAC("doorkey", teachers=["optimal"], seed=0, wean_imitation=True)
    model.learn(32, progress_bar=False)
    model.solo.solo_returns.extend([0.75] * 5)  # solo mean 0.75 ...
    model.solo.floor, model.solo.best_assisted = 0.0, 1.0  # ... of the teachers' 1.0
    assert model.update(model.collect(), 1.0)["train/distill_coef"] == pytest.approx(0.25)
    # once the teacher has led an episode alone (return 0.8), the weight is 1 - weaning
    model.solo.led_sums[:], model.solo.led_counts[:] = 0.8, 1
    rollout = model.collect()
    weaning = model.solo.weaning
    assert weaning != model.solo.competence
    logged = model.update(rollout, 1.0)
    assert logged["train/distill_coef"] == pytest.approx(1.0 - weaning)
    assert logged["train/weaning"] == weaning  # logged beside train/competence


def test_the_copy_is_weaned_against_the_best_teacher_alone():
    """The imitation fades as the student alone matches the best teacher ALONE (the mean of
    its led episodes), not a per-step mix of teachers and student that can beat both: solo 5
    over a floor of 0, teachers led alone at 4 (teacher 0) and 2 (teacher 1), a mix at 10 ->
    weaning min(1, 5 / 4) = 1 where competence is 5 / 10. Before every teacher has led
    MIN_LED_EPISODES (3) episodes: 1, nothing copied (the audition)."""
    solo = SoloEpisodes(1, budget=0.2, seed=0, min_episodes=1, n_teachers=2, teacher_share=0.3)
    solo.active[:] = True
    solo.end(0, 0.0)  # the floor
    solo.active[:] = False
    solo.end(0, 10.0)  # a mixed assisted episode
    assert solo.competence == 0.0 and solo.weaning == 1.0 and solo.auditioning
    solo.active[:] = True
    solo.end(0, 10.0)  # solo mean 5
    assert solo.competence == 0.5 and solo.weaning == 1.0
    solo.active[:] = False
    for teacher, episode_return in [(0, 3.0), (0, 5.0), (1, 2.0), (0, 4.0), (1, 2.0), (1, 2.0)]:
        solo.leader[0] = teacher
        solo.end(0, episode_return)
    assert not solo.auditioning and solo.competence == 0.5 and solo.weaning == 1.0
    solo.solo_returns.extend([1.0] * 18)  # solo mean 28 / 20 = 1.4: 1.4 / 4 of the best teacher
    assert solo.weaning == pytest.approx(0.35)


def test_the_first_episodes_measure_the_student_and_each_teacher_before_any_copy():
    """Issue 63's audition: the student alone for ``min_episodes`` episodes (its floor), then
    each teacher leads until it has led MIN_LED_EPISODES (3), the least-led first; nothing is
    copied meanwhile (weaning 1). Then the draws of solo_budget and teacher_share."""
    solo = SoloEpisodes(1, budget=0.2, seed=0, min_episodes=2, n_teachers=2, teacher_share=0.3)
    kinds = []
    while solo.auditioning:
        assert solo.weaning == 1.0
        solo.start(np.ones(1, dtype=bool))
        kinds.append("solo" if solo.active[0] else f"teacher {solo.leader[0]}")
        solo.end(0, 1.0 if solo.active[0] else 5.0 + solo.leader[0])
    assert kinds[:2] == ["solo", "solo"] and len(kinds) == 8
    assert sorted(kinds[2:4]) == sorted(kinds[4:6]) == ["teacher 0", "teacher 1"]
    assert kinds[2:].count("teacher 0") == kinds[2:].count("teacher 1") == 3
    # teachers at 5 and 6 over the floor 1: competence 0, a full copy, solo budget 0.2
    assert solo.weaning == 0.0 and solo.probability == pytest.approx(0.2)
    # without teacher-led episodes there is no audition (the paper's DoorKey presets)
    assert not SoloEpisodes(1, 0.2, seed=0, n_teachers=2).auditioning


def test_teachers_that_show_nothing_above_the_floor_are_not_copied():
    """Issue 63: every teacher led MIN_LED_EPISODES (3) episodes at the untrained student's
    floor (-500, a sparse goal never reached): nothing to copy (weaning 1) and nine episodes in
    ten the student's own (the tenth led by a teacher, so the evidence keeps coming), where before the led episodes at the floor read as "no
    evidence" (weaning 0: a full copy). Teacher 0 then leads -300, -300 and -200: its mean
    must beat the floor by two standard errors (-450 - 2 x 43.3 and -420 - 2 x 43.8: not yet;
    -383.3 - 2 x 49.5 = -482.4 > -500: help), and the weaning is competence against it."""
    solo = SoloEpisodes(1, budget=0.2, seed=0, min_episodes=1, n_teachers=2, teacher_share=0.3)
    solo.active[:] = True
    solo.end(0, -500.0)  # the floor
    solo.active[:] = False

    def lead(teacher: int, episode_return: float) -> None:
        solo.leader[0] = teacher
        solo.end(0, episode_return)

    for _ in range(3):
        lead(0, -500.0)
    for _ in range(2):
        lead(1, -500.0)
    assert not solo.no_teacher_helps and solo.auditioning  # teacher 1 has led 2 episodes only
    assert solo.weaning == 1.0 and solo.probability == 0.0  # the audition: teacher 1 leads next
    solo.start(np.ones(1, dtype=bool))
    assert not solo.active[0] and solo.leader[0] == 1
    lead(1, -500.0)
    assert solo.no_teacher_helps
    assert solo.weaning == 1.0 and solo.probability == pytest.approx(0.9)
    kinds = []  # 400 episode starts: solo, or led (never the high level's mix)
    for _ in range(400):
        solo.start(np.ones(1, dtype=bool))
        kinds.append("solo" if solo.active[0] else "led" if solo.leader[0] >= 0 else "mix")
    assert "mix" not in kinds and 20 <= kinds.count("led") <= 60  # ~10%: 40
    solo.active[:] = False
    solo.solo_returns.append(-100.0)  # solo mean -300, above every led mean (-500): no rechecks
    assert solo.probability == 1.0
    solo.solo_returns.pop()
    lead(0, -300.0)
    assert solo.no_teacher_helps
    lead(0, -300.0)
    assert solo.no_teacher_helps
    lead(0, -200.0)
    assert not solo.no_teacher_helps
    assert solo.weaning == 0.0 and solo.probability == pytest.approx(0.2)  # solo still -500


def test_help_is_judged_against_the_untrained_student_not_its_worst_window():
    """Issue 63 (Pendulum, an adversarial teacher beside a random one, seed 3): the student's
    own solo returns fell from -1390 to -1667 before any copy, the lowest window so far, and
    the adversarial teacher's led episodes (-1505) then beat it: judged to help, it was copied
    and the student stayed near -1600 (PPO alone -1016). Hand-checked, windows of one episode:
    the untrained student's first solo return -500, then -800 (the floor); a teacher whose
    three led episodes score -600, -610, -590 (se 5.8) shows help against -800 but not against
    -500, so no teacher helps; eighteen more at -400, -410, -390 show it."""
    solo = SoloEpisodes(
        1, budget=0.2, seed=0, window=1, min_episodes=1, n_teachers=1, teacher_share=0.3
    )
    solo.active[:] = True
    solo.end(0, -500.0)
    solo.end(0, -800.0)
    assert solo.floor == -800.0 and solo.untrained == -500.0
    solo.active[:] = False
    solo.leader[0] = 0
    for episode_return in (-600.0, -610.0, -590.0):
        solo.end(0, episode_return)
    assert solo.no_teacher_helps and solo.weaning == 1.0
    for episode_return in (-400.0, -410.0, -390.0) * 6:
        solo.end(0, episode_return)
    assert not solo.no_teacher_helps  # 21 led episodes, mean -428.6, se 15.4: -459.3 > -500


def test_a_teacher_with_nothing_to_copy_does_not_count_as_help():
    """Issue 63 (Pendulum): a random teacher's led episodes beat the untrained student's floor,
    but nothing of it can be copied. Hand-checked: floor -500; teacher 0's led episodes -300,
    -300, -200 show help (-383.3 - 2 x 49.5 > -500), teacher 1's three at -500 do not. Until
    teacher 0's advice is asked, it is a helper to measure; asked on 4 rows with information
    0, 0, 0.02, 0 (mean 0.005 <= SAYS_NOTHING 0.01) it says nothing, and no teacher helps;
    with information 0.8 in every row it helps, and the weaning is competence against it."""
    solo = SoloEpisodes(1, budget=0.2, seed=0, min_episodes=1, n_teachers=2, teacher_share=0.3)
    solo.active[:] = True
    solo.end(0, -500.0)
    solo.active[:] = False
    for teacher, episode_return in [(0, -300.0), (0, -300.0), (0, -200.0)] + [(1, -500.0)] * 3:
        solo.leader[0] = teacher
        solo.end(0, episode_return)
    assert solo.unmeasured_helpers.tolist() == [True, False]
    assert not solo.no_teacher_helps and solo.weaning == 0.0
    solo.record_information(np.array([[0.0, 0.0, 0.02, 0.0], [1.0, 1.0, 1.0, 1.0]]))
    assert solo.says_nothing.tolist() == [True, False]
    assert not solo.unmeasured_helpers.any()
    assert solo.no_teacher_helps and solo.weaning == 1.0
    # 4 more rows at 0.8 on teacher 0 only (asked on its rows): mean (0.02 + 3.2) / 8 = 0.4025
    asked = np.array([[1, 1, 1, 1], [0, 0, 0, 0]])
    solo.record_information(np.array([[0.8] * 4, [0.0] * 4]), asked)
    assert solo.information_sums.tolist() == pytest.approx([3.22, 4.0])
    assert solo.information_rows.tolist() == [8.0, 4.0]
    assert not solo.no_teacher_helps and solo.weaning == 0.0


def test_a_helper_with_nothing_to_say_is_measured_before_the_copy_opens():
    """Issue 63 (Pendulum, adversarial + random, seed 5): a random teacher's led returns beat
    the untrained student's, so it counted as help until its advice was measured, and the
    update that measured it had already set the copy's weight: one whole update copied the
    adversarial teacher beside it (the student's mean action at 1.5 of 2 after it, -1421 alone
    at the end where PPO alone reaches -986). Hand-checked: untrained student -1400 (5 solo
    episodes); teacher 0 (always full throttle one way) leads -1500 three times, the random
    teacher -1000, -1050, -1100 (-1050 - 2 x 28.9 > -1400: help, but unmeasured). Weighted
    before the measurement, the copy is whole (competence 0 against -1050); measured first, the
    random teacher says nothing, no teacher helps and the update copies nothing."""
    box = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)
    one_way = as_teacher(lambda obs: np.float32([2.0]), box)
    model = TLAC(
        gym.make("Pendulum-v1"),
        teachers=[one_way, RandomTeacher(box, seed=1)],
        seed=0,
        n_steps=64,
        batch_size=32,
    )
    solo = model.solo
    solo.active[:] = True
    for _ in range(5):
        solo.end(0, -1400.0)
    solo.active[:] = False
    for teacher, episode_return in [(0, -1500.0)] * 3 + [(1, -1000.0), (1, -1050.0), (1, -1100.0)]:
        solo.leader[0] = teacher
        solo.end(0, episode_return)
    assert not solo.auditioning and solo.unmeasured_helpers.tolist() == [False, True]
    assert solo.weaning == 0.0  # the random teacher's returns alone would open a whole copy
    out = model.update(model.collect(), 1.0)
    assert solo.says_nothing.tolist() == [False, True] and solo.no_teacher_helps
    assert "train/imitation_loss" not in out and len(model.advice_buffer) == 0


def test_a_teacher_whose_episodes_show_harm_is_not_copied_beside_one_whose_show_help():
    """Issue 63: a copy opened by one teacher's help copied every teacher by the high level's
    trust, near uniform at first; beside the near-optimal SAC actor its mirror image (led
    -1525 against the untrained student's -1100) took half of it (Pendulum, 5 seeds: -243.0,
    beside a random teacher -151.9). Hand-checked: untrained student -500; teacher 0 leads
    -300, -300, -200 (help), teacher 1 -600 three times (-600 + 0 < -500: harm), teacher 2
    -500, -400, -600 (mean -500, se 47.1 x 2: neither). Only teacher 1 is left out, and taken
    back once its led episodes no longer show harm (eighteen more at -100: mean -171.4). An
    untrained level measured on five spread episodes needs a larger gap. Then, in an update:
    teachers that say +1 and -1 everywhere, equally trusted; the copy moves the student's mean
    action toward +1, where without the gate the two pulls cancel."""
    solo = SoloEpisodes(1, budget=0.2, seed=0, min_episodes=1, n_teachers=3, teacher_share=0.3)
    assert solo.shown_harm.tolist() == [False, False, False]  # nothing judged yet
    solo.active[:] = True
    solo.end(0, -500.0)
    solo.active[:] = False
    led = [(0, -300.0), (0, -300.0), (0, -200.0), (1, -600.0), (1, -600.0), (1, -600.0)]
    for teacher, episode_return in [*led, (2, -500.0), (2, -400.0), (2, -600.0)]:
        solo.leader[0] = teacher
        solo.end(0, episode_return)
    assert solo.shown_harm.tolist() == [False, True, False]
    solo.outside[1] = True  # a person is never judged
    assert solo.shown_harm.tolist() == [False, False, False]
    solo.outside[1] = False
    solo.leader[0] = 1
    for _ in range(18):
        solo.end(0, -100.0)
    assert solo.shown_harm.tolist() == [False, False, False]
    # the untrained level's own error counts: four episodes at -500 and one at -429 (mean
    # -485.8, se 12.7) are no evidence that a teacher at -500 (0 + 14.2 < 2 x 12.7) harms
    sparse = SoloEpisodes(1, budget=0.2, seed=0, min_episodes=5, n_teachers=1, teacher_share=0.3)
    sparse.active[:] = True
    for episode_return in [-500.0] * 4 + [-429.0]:
        sparse.end(0, episode_return)
    sparse.active[:] = False
    sparse.leader[0] = 0
    for _ in range(3):
        sparse.end(0, -500.0)
    assert round(sparse.untrained_se, 1) == 12.7
    assert sparse.shown_harm.tolist() == [False]
    sparse.untrained_se = 0.0  # the one-sample test would call it harm
    assert sparse.shown_harm.tolist() == [True]

    def mean_action_after_one_update(gate: bool) -> float:
        box = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)
        plus = as_teacher(lambda obs: np.float32([1.0]), box)
        minus = as_teacher(lambda obs: np.float32([-1.0]), box)
        model = TLAC(
            gym.make("Pendulum-v1"),
            teachers=[plus, minus],
            seed=0,
            n_steps=64,
            batch_size=32,
            learning_rate=3e-3,
        )
        solo = model.solo
        solo.active[:] = True
        for _ in range(5):
            solo.end(0, -1400.0)
        solo.active[:] = False
        second = -1500.0 if gate else -1400.0  # the minus teacher's led episodes: harm or not
        for teacher, episode_return in [(0, -1000.0)] * 3 + [(1, second)] * 3:
            solo.leader[0] = teacher
            solo.end(0, episode_return)
        assert solo.shown_harm.tolist() == [False, gate]
        ro = model.collect()
        model.update(ro, 1.0)
        with torch.no_grad():
            return float(model.nets.heads(model.nets.update_rows(ro.flat()["obs"]))[1].mean())

    assert mean_action_after_one_update(gate=True) > 0.3
    assert abs(mean_action_after_one_update(gate=False)) < 0.1


def test_a_checkpoint_saved_before_the_harm_gate_resumes_without_it():
    """A training state without ``untrained_se`` (saved before the harm gate) resumes with the
    gate off (an infinite error), not with the test against the untrained mean alone."""
    from tlac.two_level.persistence import get_training_state, set_training_state

    model = TLAC(gym.make("CartPole-v1"), teachers=[lambda obs: 0], seed=0, n_steps=64)
    state = get_training_state(model)
    set_training_state(model, state)
    assert model.solo.untrained_se == 0.0
    del state["solo"]["untrained_se"]
    set_training_state(model, state)
    assert model.solo.untrained_se == float("inf")
    model.solo.untrained, model.solo.led_counts[:] = -500.0, 3
    model.solo.led_sums[:], model.solo.led_squares[:] = -3000.0, 3_000_000.0  # three at -1000
    assert model.solo.shown_harm.tolist() == [False]


def test_advice_buffer_wraps_and_samples_aligned_rows():
    buf = AdviceBuffer(capacity=5, obs_dim=1, advice_shape=(2,), advice_dtype=torch.int64)
    for start in range(0, 12, 4):
        obs = torch.arange(start, start + 4, dtype=torch.float32)[:, None]
        advice = torch.stack([obs[:, 0].long(), 100 + obs[:, 0].long()])  # (teachers, n)
        buf.add(obs, advice)
    assert len(buf) == 5
    assert sorted(buf.obs[:, 0].tolist()) == [7.0, 8.0, 9.0, 10.0, 11.0]
    obs, advice = buf.sample(50, torch.Generator().manual_seed(0))
    assert advice.shape == (2, 50)
    assert (advice[0] == obs[:, 0].long()).all() and (advice[1] == 100 + obs[:, 0].long()).all()


def test_one_hot_encoder_numpy_equals_torch_and_hand_made():
    space = gym.spaces.Box(low=np.array([0, 1]), high=np.array([2, 3]), dtype=np.uint8)
    enc = make_encoder("onehot", space)
    assert isinstance(enc, OneHotEncoder) and enc.out_dim == 6
    x = np.array([[0, 1], [2, 3], [1, 2]], dtype=np.float32)
    expected = np.array(
        [[1, 0, 0, 1, 0, 0], [0, 0, 1, 0, 0, 1], [0, 1, 0, 0, 1, 0]], dtype=np.float32
    )
    np.testing.assert_array_equal(enc.numpy(x), expected)
    np.testing.assert_array_equal(enc.torch(torch.from_numpy(x)).numpy(), expected)
    assert make_encoder("auto", gym.spaces.Box(-1.0, 1.0, (2,))) is None
    with pytest.raises(ConfigError, match="onehot"):
        make_encoder("onehot", gym.spaces.Box(-1.0, 1.0, (2,)))


def _teacher_likelihood(model_settings: dict, steps: int = 8000) -> float:
    """Mean probability the student gives the optimal teacher's actions on 300 of that
    teacher's own DoorKey states, after ``steps`` steps with that teacher alone."""
    from tlac.domains import make_teachers

    domain = get_domain("doorkey")
    env = domain.make_env()
    teacher = make_teachers(domain, ["optimal"], env, 0)[0]
    obs = []
    o, _ = env.reset(seed=123)
    for _ in range(300):
        obs.append(o)
        o, _, term, trunc, _ = env.step(int(teacher.predict(o[None])[0]))
        if term or trunc:
            o, _ = env.reset()
    obs = np.stack(obs)
    advice = teacher.predict(obs)
    model = TLAC("doorkey", teachers=["optimal"], seed=0, **model_settings)
    model.learn(steps, progress_bar=False)
    low_logits = model.nets.act(obs)[1]
    log_p = low_logits - np.log(np.exp(low_logits).sum(-1, keepdims=True))
    return float(np.exp(log_p[np.arange(len(obs)), advice]).mean())


@pytest.mark.slow  # a learning test (about 35 s)
def test_graduate_imitation_moves_the_student_towards_its_teacher():
    """8000 steps with one deterministic teacher: the student's likelihood of the teacher's
    actions on the teacher's own states is far higher with the imitation term than without it
    (the same graduate variant with distill_coef 0 learns only from the advantage). Under
    Table 5's gradient clip, which holds the advantage's steps as short as the imitation's:
    with DoorKey's loose clip (100) the advantage alone also reaches 0.55 by 8000 steps (0.63
    with the imitation). The default's student alone: test_doorkey_student_alone_succeeds."""
    likelihood = {
        coef: _teacher_likelihood({"distill_coef": coef, "max_grad_norm": 0.5})
        for coef in (1.0, 0.0)
    }
    assert likelihood[1.0] > 0.35
    assert likelihood[1.0] > likelihood[0.0] + 0.2


@pytest.mark.slow
def test_doorkey_student_alone_succeeds():
    """The default TL-AC, 1 optimal + 2 random teachers, 1e5 steps (the demo): the student
    ALONE (greedy, no teacher) solves DoorKey. The paper variant's student scores 0.000 here
    at every evaluation (docs/graduation.md)."""
    model = TLAC("doorkey", teachers=["optimal", "random", "random"], seed=0)
    model.learn(100_000, progress_bar=False)
    returns = evaluate_student(model, get_domain("doorkey"), 50, seed=10_000)
    assert returns.mean() >= 0.85, returns


@pytest.mark.slow
def test_a_useless_teacher_leaves_the_student_at_ppo_alones_level_on_a_sparse_task():
    """Issue 63: Acrobot-v1 (-1 a step until the tip swings above the line) with a teacher that
    never applies torque (it never swings up: -500) beside a random one. SB3 PPO alone reaches
    -80 to -85 in 1e5 steps; the default's student copied the deterministic teacher and stayed
    at -500 (-415 at best, seed 0) until its led episodes at the floor were read as nothing to
    copy. 30 greedy episodes, the student alone."""
    env = gym.make("Acrobot-v1")
    space = env.action_space
    space.seed(0)
    model = TLAC(env, teachers=[lambda obs: 1, lambda obs: space.sample()], seed=0)
    model.learn(100_000, progress_bar=False)
    returns = []
    for episode in range(30):
        obs, _ = env.reset(seed=10_000 + episode)
        done, total = False, 0.0
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, _ = env.step(int(action))
            total += float(reward)
            done = terminated or truncated
        returns.append(total)
    assert np.mean(returns) >= -120.0, returns


def test_capped_high_level_entropy_hand_checked():
    """The graduate variant's high-level bonus counts each state's entropy up to the cap:
    a uniform state over 4 choices (ln 4 = 1.386 nats) counts 0.5, a certain one ~0."""
    model = TLAC("doorkey", teachers=["optimal", "random", "random"], seed=0)
    high = torch.tensor([[0.0, 0.0, 0.0, 0.0], [50.0, 0.0, 0.0, 0.0]])
    low, latent = torch.zeros(2, 6), torch.zeros(2, 64)
    capped = model.nets.mean_entropies(high, low, latent, cap_high=0.5)
    uncapped = model.nets.mean_entropies(high, low, latent)
    assert abs(float(capped[1]) - 0.25) < 1e-6  # (0.5 + 0) / 2
    assert abs(float(uncapped[1]) - math.log(4) / 2) < 1e-6
    assert abs(float(capped[0]) - math.log(6)) < 1e-6  # the low level is never capped
    # the cap stops the bonus's gradient in states already above it
    logits = high.clone().requires_grad_(True)
    model.nets.mean_entropies(logits, low, latent, cap_high=0.5)[1].backward()
    assert float(logits.grad[0].abs().sum()) == 0.0


def test_distribution_labels_hand_checked():
    """The imitation term is the cross-entropy from each teacher's distribution to pi_low; a
    point mass gives exactly -log pi_low(a|s) of its action."""
    env = gym.make("CartPole-v1")
    model = TLAC(env, teachers=[lambda obs: 0], seed=0)
    logits = torch.log(torch.tensor([[0.25, 0.75]]))  # pi_low = (1/4, 3/4)
    dists = torch.tensor([[[0.5, 0.5]], [[0.0, 1.0]]])  # 2 teachers x 1 state x 2 actions
    nll = model.nets.advice_nll(logits, torch.zeros(1, 64), dists)
    assert nll.tolist() == [
        [pytest.approx(-(0.5 * math.log(0.25) + 0.5 * math.log(0.75)))],
        [pytest.approx(-math.log(0.75))],
    ]
    assert model.advice_buffer.advice.shape[1:] == (1, 2)
    assert model.advice_buffer.advice.dtype == torch.float32


def test_teachers_tell_the_distribution_they_sample_from():
    from tlac.teachers.base import NamedTeacher, advice_probabilities
    from tlac.teachers.wrappers import MixedRandomTeacher, PartialTeacher, RandomTeacher

    space = gym.spaces.Discrete(4)
    obs = np.zeros((40_000, 2))
    good = MixedRandomTeacher(lambda o: 1, 0.8, space, seed=3)
    told = advice_probabilities(good, obs[:1], space)[0]
    assert told.tolist() == pytest.approx([0.05, 0.85, 0.05, 0.05])
    seen = np.bincount(good.predict(obs), minlength=4) / len(obs)
    assert np.abs(seen - told).max() < 0.01
    left = PartialTeacher(lambda o: 3, lambda b: (b[:, 0] > 0).astype(int), [0], space, seed=0)
    rows = np.array([[-1.0, 0.0], [1.0, 0.0]])
    assert advice_probabilities(left, rows, space).tolist() == [[0, 0, 0, 1], [0.25] * 4]
    renamed = NamedTeacher(RandomTeacher(space, seed=0), "random_1")
    assert advice_probabilities(renamed, rows, space).tolist() == [[0.25] * 4] * 2

    class Broken:
        name = "broken"

        def predict(self, obs):
            return np.zeros(len(obs), dtype=np.int64)

        def action_probabilities(self, obs):
            return np.ones((len(obs), 3))

    with pytest.raises(TeacherError, match="'broken': action_probabilities gave an array"):
        advice_probabilities(Broken(), rows, space)


def test_informative_trust_hand_checked():
    """A teacher's trust is weighted by 1 - H / log A of its advice in that state, then the
    state's total trust is restored. Four actions: (0.5, 0.5, 0, 0) has H = ln 2, half of
    ln 4 (information 0.5); a point mass 1; the uniform distribution 0."""
    half = torch.tensor([0.5, 0.5, 0.0, 0.0])
    point, uniform = torch.tensor([1.0, 0.0, 0.0, 0.0]), torch.full((4,), 0.25)
    dists = torch.stack([torch.stack([half]), torch.stack([point]), torch.stack([uniform])])
    trust = torch.tensor([[0.5, 0.25, 0.25]])  # (B=1, K=3)
    # info = 0.5, 1, 0 -> weighted 0.25, 0.25, 0 -> rescaled to total 1: 0.5, 0.5, 0
    got = losses.informative_trust(trust, dists)
    assert got.tolist() == [[pytest.approx(0.5), pytest.approx(0.5), pytest.approx(0.0)]]
    share = losses.informative_trust(trust * 0.5, dists)  # the agent's share is kept out
    assert share.sum().item() == pytest.approx(0.5)


def test_advice_labels_remove_the_uniform_floor_hand_checked():
    """The label copied from a teacher is its advice minus its uniform floor, renormalised.
    DoorKey's noisy teacher (6 actions, its base with probability 0.2): 0.2 + 0.8 / 6 = 1/3 on
    the base's action and 0.8 / 6 = 2/15 on each other; the floor 2/15 leaves 0.2 on the base,
    renormalised to a point mass. A good teacher (0.8) gives the same label. (0.5, 0.3, 0.1,
    0.1) has floor 0.1 and share 1 - 4 * 0.1 = 0.6: (0.4, 0.2, 0, 0) / 0.6. A point mass is
    returned bit for bit, and the uniform distribution is left as it is."""
    base = torch.zeros(6)
    base[3] = 1.0
    noisy = 0.2 * base + 0.8 / 6
    good = 0.8 * base + 0.2 / 6
    mixed = torch.tensor([0.5, 0.3, 0.1, 0.1])
    for advice, label in ((noisy, base), (good, base)):
        got = losses.advice_labels(advice[None, None])[0, 0]
        assert got.tolist() == pytest.approx(label.tolist(), abs=1e-6)
    got = losses.advice_labels(mixed[None, None])[0, 0]
    assert got.tolist() == pytest.approx([2 / 3, 1 / 3, 0.0, 0.0], abs=1e-6)
    point, uniform = torch.tensor([0.0, 1.0, 0.0]), torch.full((3,), 1 / 3)
    both = losses.advice_labels(torch.stack([point[None], uniform[None]]))
    assert torch.equal(both[0, 0], point) and torch.equal(both[1, 0], uniform)


def test_the_student_copies_a_noisy_teachers_base_action():
    """On one DoorKey state trusted to a noisy teacher alone, the imitation term is the whole
    -log pi_low of its base's action (the label's uniform floor is removed), not the
    cross-entropy from its flat distribution."""
    model = TLAC("doorkey", teachers=["noisy"], seed=0)
    n_actions = model.nets.net.out_dims[1]
    noisy = torch.full((n_actions,), 0.8 / n_actions)
    noisy[2] += 0.2
    assert n_actions == 6
    buffer = model.advice_buffer
    buffer.add(torch.zeros(1, buffer.obs.shape[1]), noisy[None, None])
    labels = _replay_plan(model).advice[:, :1]  # what the update copies from that state
    low = torch.log(torch.tensor([[0.1, 0.1, 0.3, 0.2, 0.2, 0.1]]))
    term = float(model.nets.imitation_term(torch.zeros(1, 2), low, torch.zeros(1, 64), labels))
    assert term == pytest.approx(-math.log(0.3), abs=1e-5)


def test_weaned_imitation_hands_over_with_an_entropy_bonus():
    """presets/default.yaml (wean_imitation) on a discrete user environment: the low level's
    entropy coefficient is the setting's (0) plus 0.05 x competence, the high level's stays
    0.01. Competence (solo - floor) / (assisted - floor): -300 between -500 and -100 is 0.5.
    DoorKey's preset (no weaning) and a Box action space (imitated under a fixed variance) get
    no bonus."""
    model = TLAC(gym.make("Acrobot-v1"), teachers=[lambda obs: 2], seed=0)
    solo = model.solo
    solo.floor, solo.best_assisted = -500.0, -100.0
    solo.solo_episodes = 20  # past the audition: the teacher led 3 episodes at -100
    solo.led_sums[:], solo.led_squares[:], solo.led_counts[:] = -300.0, 30_000.0, 3
    solo.solo_returns.extend([-300.0] * 20)
    assert solo.competence == pytest.approx(0.5)
    assert _entropy_coefs(model).tolist() == pytest.approx([0.025, 0.01])
    solo.solo_returns.extend([-100.0] * 20)
    assert _entropy_coefs(model).tolist() == pytest.approx([0.05, 0.01])
    doorkey = TLAC("doorkey", teachers=["optimal"], seed=0)
    doorkey.solo.solo_returns.extend([1.0] * 20)
    assert _entropy_coefs(doorkey).tolist() == pytest.approx([0.0, 0.03])
    pendulum = TLAC(gym.make("Pendulum-v1"), teachers=[lambda obs: np.zeros(1, np.float32)])
    assert not pendulum._handover


def test_box_imitation_weighs_the_teachers_actions_by_the_high_levels_trust():
    """On a Box space the advice is the teachers' actions, not distributions: the imitation
    term is their scaled squared errors weighted by the softmax of the teachers' logits (the
    agent's logit left out); without information (all 1) nothing is re-weighted."""
    high = torch.tensor([[0.3, -0.2, 0.1]])  # 2 teachers + agent
    mean, latent = torch.tensor([[0.5, 0.0, -0.5]]), torch.zeros(1, 64)
    advice = torch.tensor([[[0.7, 0.2, 0.1]], [[-0.9, 0.5, 0.0]]])  # 2 teachers x 1 state x 3
    teachers = [lambda obs: np.zeros(3, np.float32)] * 2
    model = TLAC(gym.make("Hopper-v5"), teachers=teachers, seed=0)
    got = float(model.nets.imitation_term(high, mean, latent, advice))
    trust = torch.softmax(torch.tensor([0.3, -0.2]), 0)
    errors = losses.scaled_squared_error(mean, advice, model.nets.imitation_scale)[:, 0]
    assert got == pytest.approx(float((trust * errors).sum()))


def test_box_advice_is_the_base_action_and_a_random_teacher_is_not_copied():
    """Box advice, wired from the teachers to the imitation term: a good teacher (its base with
    probability 0.8) gives its base's action with information 0.8, a random one information 0,
    so on a state trusted to both equally the term is the base action's whole scaled error."""
    box = gym.spaces.Box(-1.0, 1.0, (3,))
    base = np.array([0.6, -0.2, 0.4], np.float32)
    good = MixedRandomTeacher(lambda obs: base, 0.8, box, seed=0, name="good")
    model = TLAC(gym.make("Hopper-v5"), teachers=[good, RandomTeacher(box, seed=1)], seed=0)
    obs = torch.zeros(1, model.nets.obs_dim)
    model.advice_buffer.add(obs, advice_on(model.nets, model.teachers, obs))
    plan = _replay_plan(model)  # every drawn row is the one stored state
    assert plan.advice[0, 0].tolist() == pytest.approx(base.tolist())
    assert plan.information[:, 0].tolist() == pytest.approx([0.8, 0.0])
    mean, latent = torch.tensor([[0.0, 0.0, 0.0]]), torch.zeros(1, 64)
    high = torch.tensor([[0.0, 0.0, -30.0]])  # the two teachers equal; the agent ~0
    labels, information = plan.advice[:, :1], plan.information[:, :1]
    got = float(model.nets.imitation_term(high, mean, latent, labels, information))
    # 0.5 * mean_d (base_d / (0.1 * 1))^2 with trust 1 on the good teacher
    assert got == pytest.approx(0.5 * float(np.mean((base / 0.1) ** 2)), rel=1e-5)


def test_box_teachers_say_what_they_mean():
    """Hand-checked advice_actions of tlac's Box teachers: random says nothing; good / noisy
    give their base with information 0.8 / 0.2; Gaussian noise its base; partial its base
    inside its region and nothing outside; a plain function its action with information 1.
    None of them draws from its generator."""
    box = gym.spaces.Box(
        np.array([-2, 0], np.float32), np.array([2, 4], np.float32)
    )  # centre (0, 2)
    base = lambda obs: np.array([1.5, 0.5], np.float32)  # noqa: E731
    obs = np.array([[-1.0], [1.0]])
    partial = PartialTeacher(base, lambda b: (b[:, 0] > 0).astype(int), [0], box, seed=0)
    beyond = lambda obs: np.array([2.5, 0.5], np.float32)  # noqa: E731 - outside the box
    cases = {
        "random": (RandomTeacher(box, seed=0), [[0, 2], [0, 2]], [0.0, 0.0]),
        "noisy": (MixedRandomTeacher(base, 0.2, box, seed=0), [[1.5, 0.5]] * 2, [0.2, 0.2]),
        "gauss": (
            GaussianNoiseTeacher(beyond, 0.3, box, 0, rescale=False),
            [[2.0, 0.5]] * 2,  # clipped to the box, as its predict clips
            [1, 1],
        ),
        "partial": (partial, [[1.5, 0.5], [0, 2]], [1.0, 0.0]),
        "function": (as_teacher(base, box), [[1.5, 0.5]] * 2, [1.0, 1.0]),
    }
    for name, (teacher, actions, information) in cases.items():
        state = getattr(getattr(teacher, "rng", None), "bit_generator", None)
        before = None if state is None else state.state
        got_actions, got_information = advice_actions(teacher, obs, box)
        np.testing.assert_allclose(got_actions, actions, err_msg=name)
        assert got_information.tolist() == pytest.approx(information), name
        assert before is None or teacher.rng.bit_generator.state == before, name
    reweighted = losses.reweighted_trust(
        torch.tensor([[0.3, 0.3, 0.2]]), torch.tensor([[0.5], [0.0], [1.0]])
    )
    # weighted 0.15, 0, 0.2 (sum 0.35), rescaled to keep the total trust 0.8
    np.testing.assert_allclose(reweighted[0], [0.15 * 0.8 / 0.35, 0.0, 0.2 * 0.8 / 0.35], rtol=1e-6)


def test_a_box_function_that_disagrees_with_itself_means_less():
    """A Box teacher that does not say what it means is asked twice. Hand-checked: equal answers
    mean information 1; the differing rows share 1 - mean gap / (width^2 / 6), if that is above
    0 by 2 standard errors of a random teacher's mean gap (sd sqrt(7 width^4 / 180)). A user's
    uniformly random function then means nothing, one that adds noise its mean answer with the
    information of that noise, a deterministic one exactly what it says."""
    box = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)
    first = np.array([[1.0]] + [[0.0], [0.5]] * 10)
    second = np.array([[1.0]] + [[1.0], [-0.5]] * 10)
    # 20 rows differ by 1: 1 - 1 / (16 / 6) = 0.625, above 2 * 3.155 / 2.667 / sqrt(20) = 0.529
    got = self_agreement_information(first, second, box)
    np.testing.assert_allclose(got, [1.0] + [0.625] * 20)
    # 2 rows: the margin is 2 * 3.155 / 2.667 / sqrt(2) = 1.67, which no agreement reaches
    np.testing.assert_allclose(self_agreement_information(first[:3], second[:3], box), [1, 0, 0])
    unbounded = gym.spaces.Box(-np.inf, np.inf, (1,), np.float32)
    np.testing.assert_allclose(self_agreement_information(first, second, unbounded), [1] * 21)

    obs = np.zeros((2048, 3))
    box.seed(0)
    random_function = as_teacher(lambda o: box.sample(), box)
    # a rollout's worth of rows, 50 times: without the margin half of them read as meant (up
    # to 0.08, which the imitation scales up to the whole trust of a state); with it ~2.3%
    meant = [advice_actions(random_function, obs, box)[1].max() for _ in range(50)]
    assert np.mean(np.array(meant) > 0) <= 0.1 and max(meant) < 0.1
    rng = np.random.default_rng(0)
    noisy = as_teacher(lambda o: np.float32([np.clip(0.5 + rng.normal(0.0, 0.5), -2, 2)]), box)
    actions, information = advice_actions(noisy, obs, box)
    # E gap = 2 * 0.5^2 = 0.5 against 2 * 16 / 12: information 1 - 0.1875
    assert information.mean() == pytest.approx(0.8125, abs=0.02)
    assert float(actions.mean()) == pytest.approx(0.5, abs=0.02)
    fixed = as_teacher(lambda o: np.float32([0.3]), box)
    actions, information = advice_actions(fixed, obs[:2], box)
    assert actions.tolist() == [[np.float32(0.3)]] * 2 and information.tolist() == [1.0, 1.0]


def test_a_random_teachers_trust_moves_to_the_teacher_that_knows():
    """The imitation term on one DoorKey state where the high level trusts an optimal-like
    teacher (a point mass) and a random one (uniform) equally: the random teacher's trust moves
    to the point mass, so the term is the point's whole -log pi."""
    model = TLAC("doorkey", teachers=["optimal", "random"], seed=0)
    n_actions = model.nets.net.out_dims[1]
    point = torch.zeros(n_actions)
    point[2] = 1.0
    advice = torch.stack([point[None], torch.full((1, n_actions), 1.0 / n_actions)])
    high = torch.tensor([[0.0, 0.0, -30.0]])  # optimal, random equal; the agent ~0
    low = torch.zeros(1, n_actions)  # pi_low uniform: -log pi(a) = log n for every action
    latent = torch.zeros(1, 64)
    term = float(model.nets.imitation_term(high, low, latent, advice))
    assert term == pytest.approx(math.log(n_actions))  # trust 1 on the point mass


def test_former_settings_are_unknown():
    """Settings measured worse or no better were removed with their code; a result that used
    them is reproduced at the commit its NOTES.md names (results/README.md)."""
    # 41: the advice settings are one field, advice (grouped in AdviceSettings)
    assert len(dataclasses.fields(TLACConfig)) <= 41
    with pytest.raises(ConfigError, match="unknown TL-AC setting 'advice_labels'"):
        TLAC("doorkey", teachers=["random"], advice_labels="sampled")
    with pytest.raises(ConfigError, match="unknown TL-AC setting 'keep_best_student'"):
        TLACConfig.from_settings({"keep_best_student": False})
    with pytest.raises(ConfigError, match="unknown low_level_data 'none'; expected one of"):
        TLAC("doorkey", teachers=["random"], low_level_data="none")


def test_box_solo_episodes_are_greedy_and_leave_the_policy_gradient():
    """Box actions with a low level trained by imitation (`low_level_data: silent`): a solo
    episode acts with pi_low's mean (the student a user deploys), and its rows are no samples
    of pi_low, so the low level's policy gradient leaves them out. With `agent` (the default
    preset of a user's environment) solo episodes stay sampled."""
    settings = {"solo_budget": 1.0, "normalize_obs": False, "teacher_episodes": 0.0}
    model = TLAC(
        gym.make("Pendulum-v1"),
        teachers=[_push_pendulum],
        low_level_data="silent",
        seed=0,
        **settings,
    )
    from tlac.two_level.rows import row_weights

    assert model.greedy_solo
    ro = model.collect()
    solo = ro.solo.reshape(-1) > 0
    assert solo.any()
    means = model.nets.act(ro.obs.reshape(len(solo), -1))[1]
    np.testing.assert_allclose(ro.actions.reshape(len(solo), -1)[solo], means[solo], atol=1e-5)
    data = {
        "log_prob_low": torch.zeros(4),
        "log_prob_high": torch.zeros(4),
        "choices": torch.tensor([1, 1, 0, 1]),  # the agent (1) acts in rows 0, 1 and 3
        "solo": torch.tensor([1.0, 0.0, 0.0, 0.0]),
    }
    cfg = model.config
    greedy = row_weights(cfg, data, 1, True, True, True, torch.ones(4), greedy_solo=True)
    sampled = row_weights(cfg, data, 1, True, True, True, torch.ones(4), greedy_solo=False)
    assert greedy.loss[0].tolist() == [0.0, 1.0, 0.0, 1.0]
    assert sampled.loss[0].tolist() == [1.0, 1.0, 0.0, 1.0]
    sampling = TLAC(gym.make("Pendulum-v1"), teachers=[_push_pendulum], seed=0, **settings)
    assert sampling.config.low_level_data == "agent" and not sampling.greedy_solo


def test_greedy_solo_rows_leave_the_kl_estimate_and_apply_with_silent_only():
    """The agent's-rows KL estimate (the first update's fallback) leaves greedy solo rows out,
    and greedy solo episodes apply only where the low level learns by imitation (`silent`):
    with `all` or `agent` its policy gradient needs sampled solo rows."""
    from tlac.two_level.rows import row_weights

    for data_rule, greedy in (("silent", True), ("all", False), ("agent", False)):
        model = TLAC(
            gym.make("Pendulum-v1"),
            teachers=[_push_pendulum],
            low_level_data=data_rule,
            solo_budget=0.5,
        )
        assert model.greedy_solo is greedy, data_rule
    data = {
        "log_prob_low": torch.zeros(3),
        "log_prob_high": torch.zeros(3),
        "choices": torch.tensor([1, 1, 0]),
        "solo": torch.tensor([1.0, 0.0, 0.0]),
    }
    cfg = TLACConfig.from_settings({"low_level_data": "silent", "kl_rows": "agent"})
    rows = row_weights(cfg, data, 1, True, True, True, torch.ones(3), greedy_solo=True)
    assert rows.kl[0].tolist() == [0.0, 1.0, 0.0]


def test_a_box_checkpoint_without_the_information_column_is_refused(tmp_path):
    """A Box run's advice buffer stores each teacher's information in a last column since
    2026-11-27; resuming a checkpoint whose rows have another shape is a ConfigError, not a
    silent misreading (with one action dimension the action would read as information)."""
    model = TLAC(
        gym.make("Pendulum-v1"), teachers=[_push_pendulum], n_steps=64, batch_size=64, seed=0
    )
    model.learn(128, progress_bar=False)
    path = tmp_path / "run.pt"
    model.save(path, training_state=True)
    state = torch.load(path, weights_only=True)
    advice = state["training"]["advice"]
    advice["advice"] = advice["advice"][..., :-1]  # as a Box run saved before the column
    torch.save(state, path)
    with pytest.raises(ConfigError, match="advice buffer holds rows of shape"):
        TLAC.load(path, env=gym.make("Pendulum-v1"), teachers=[_push_pendulum], resume=True)


@pytest.mark.parametrize("case", ["doorkey", "Pendulum-v1"])
def test_the_update_is_the_same_with_replayed_rows_planned_or_made_per_minibatch(monkeypatch, case):
    """An update holds its replayed rows (and narrows the first layer to the columns they and
    the rollout activate) when they are small, else makes them per minibatch on the whole
    layer: the same training, weights and optimiser statistics, up to rounding on DoorKey
    (where the narrowing happens) and bit for bit on Pendulum (normalised raw inputs, every
    column active)."""

    def trained(max_values: int) -> tuple[TLAC, int]:
        monkeypatch.setattr(fast, "MAX_PLANNED_REPLAY_VALUES", max_values)
        if case == "doorkey":
            model = TLAC("doorkey", teachers=["optimal", "random", "random"], seed=4)
        else:
            env = gym.make(case)
            env.action_space.seed(5)
            teachers = [_push_pendulum, lambda obs: env.action_space.sample()]
            model = TLAC(env, teachers=teachers, seed=4, n_steps=128, batch_size=32)
        narrowed = []
        original = fast.narrowed_columns
        monkeypatch.setattr(
            fast, "narrowed_columns", lambda *a: narrowed.append(original(*a)) or narrowed[-1]
        )
        model.learn(96 if case == "doorkey" else 384)
        return model, sum(c is not None for c in narrowed)

    planned, narrowed_updates = trained(fast.MAX_PLANNED_REPLAY_VALUES)
    per_minibatch, none = trained(0)
    assert narrowed_updates == (6 if case == "doorkey" else 0) and none == 0
    tolerance = 1e-6 if case == "doorkey" else 0.0
    for a, b in zip(planned.nets.params, per_minibatch.nets.params, strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=tolerance)
        state_a, state_b = planned.optimizer.state[a], per_minibatch.optimizer.state[b]
        assert state_a.keys() == state_b.keys() and float(state_a["step"]) > 0
        for key, value in state_a.items():  # RMSprop's or Adam's statistics and step count
            torch.testing.assert_close(value, state_b[key], rtol=0, atol=tolerance)
