"""The baselines: SB3 A2C/PPO adapters, DQN-TLQL and AC-Teach.

Tiers: hand-checked math (AC-Teach's switching rule, the alpha-divergence loss, TD targets),
smoke runs on CartPole (Discrete) and Pendulum (Box) with simple function teachers, the run
folder through ``train_run`` on DoorKey, and one learning check per multi-teacher baseline on
DoorKey (an optimal teacher against random advice), marked ``slow``.
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike
from stable_baselines3.common.vec_env import DummyVecEnv

from tlac.algorithms import get_algorithm
from tlac.algorithms.common import linear_epsilon, real_next_obs, td_targets
from tlac.baselines.ac_teach import (
    ACTeach,
    BayesianCritic,
    alpha_divergence_loss,
    commitment_decision,
    commitment_threshold,
    dropout_mask,
    dropout_weight_decay,
    switch_probability,
)
from tlac.baselines.dqn_tlql import DQNTLQL
from tlac.baselines.sb3_baselines import A2CBaseline, PPOBaseline, sb3_kwargs
from tlac.errors import ConfigError, TeacherError
from tlac.presets import load_preset
from tlac.recording import EpisodeRecorder, Recorder
from tlac.teachers.base import as_teacher

torch.set_num_threads(1)


def phi(x: float) -> float:
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


# --------------------------------------------------------------------------- fixtures
def cartpole(n: int = 1, seed: int = 0) -> EpisodeRecorder:
    venv = DummyVecEnv([lambda: gym.make("CartPole-v1") for _ in range(n)])
    venv.seed(seed)
    return EpisodeRecorder(venv)


def pendulum(n: int = 1, seed: int = 0) -> EpisodeRecorder:
    venv = DummyVecEnv([lambda: gym.make("Pendulum-v1") for _ in range(n)])
    venv.seed(seed)
    return EpisodeRecorder(venv)


def cartpole_teachers() -> list:
    space = gym.spaces.Discrete(2)
    return [
        as_teacher(lambda o: int(o[2] + 0.5 * o[3] > 0), space, name="balance"),
        as_teacher(lambda o: 0, space, name="left"),
    ]


def pendulum_teachers() -> list:
    space = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)
    return [
        as_teacher(lambda o: np.clip([-1.0 * o[2]], -2.0, 2.0), space, name="damping"),
        as_teacher(lambda o: np.array([2.0]), space, name="push"),
    ]


SMALL_AC_TEACH = dict(
    batch_size=16, buffer_size=2000, cycle_env_steps=50, cycle_grad_steps=5, mc_samples=8
)
SMALL_DQN = dict(learning_starts=50, batch_size=16, train_freq=20, gradient_steps=2)


# --------------------------------------------------------------------------- AC-Teach math
def test_switch_probability_hand_cases() -> None:
    # equal means: a coin flip, whatever the variances
    assert switch_probability(0.3, 0.2, 0.3, 0.1, 10.0) == pytest.approx(0.5)
    # new better by 1, variance 0.05 + 0.05 + 1/10 = 0.2: Phi(1 / sqrt(0.2)) = Phi(2.2360...)
    assert switch_probability(0.0, 0.05, 1.0, 0.05, 10.0) == pytest.approx(phi(1 / math.sqrt(0.2)))
    assert switch_probability(0.0, 0.05, 1.0, 0.05, 10.0) == pytest.approx(0.98733, abs=1e-5)
    # new worse by 0.5, variance 0 + 0 + 1/4: Phi(-0.5 / 0.5) = Phi(-1) = 0.158655
    assert switch_probability(1.0, 0.0, 0.5, 0.0, 4.0) == pytest.approx(0.158655, abs=1e-6)
    # the public code's formula is the complement: P(Q_current > Q_new)
    for args in [
        (0.0, 0.05, 1.0, 0.05, 10.0),
        (1.0, 0.0, 0.5, 0.0, 4.0),
        (2.0, 1.0, -1.0, 3.0, 10.0),
    ]:
        paper, code = switch_probability(*args), switch_probability(*args, sign="code")
        assert paper + code == pytest.approx(1.0, abs=1e-9)
    assert switch_probability(0.0, 0.05, 1.0, 0.05, 10.0, "code") == pytest.approx(
        0.01267, abs=1e-5
    )
    with pytest.raises(ConfigError, match="switch_sign"):
        switch_probability(0.0, 0.0, 0.0, 0.0, 1.0, "other")


def test_commitment_threshold_and_decision() -> None:
    assert commitment_threshold(0.6, 0.99, 0) == 0.6
    assert commitment_threshold(0.6, 0.99, 3) == pytest.approx(0.6 * 0.970299)
    assert commitment_threshold(0.6, 1.0, 50) == 0.6  # the "no decay" ablation
    # episode start: take the Thompson argmax, whatever the probability
    assert commitment_decision(-1, 1, 0.0, 0.6, 0.99, 0) == (1, 0)
    # the argmax agrees with the followed policy: keep it, counter unchanged
    assert commitment_decision(2, 2, 0.0, 0.6, 0.99, 4) == (2, 4)
    # confident: switch and reset the counter
    assert commitment_decision(0, 1, 0.61, 0.6, 0.99, 7) == (1, 0)
    # not confident: stay, one more declined switch
    assert commitment_decision(0, 1, 0.59, 0.6, 0.99, 0) == (0, 1)
    # without commitment every proposal is taken
    assert commitment_decision(0, 1, 0.0, 0.6, 0.99, 0, commitment=False) == (1, 0)


def test_commitment_decays_until_a_steady_proposal_wins() -> None:
    """A proposal with P = 0.55 is declined while 0.6 * 0.99**n >= 0.55, i.e. for
    n = 0..8 (0.6 * 0.99**8 = 0.5541), and taken at n = 9 (0.6 * 0.99**9 = 0.5486)."""
    current, n, steps = 0, 0, 0
    while current == 0:
        current, n = commitment_decision(current, 1, 0.55, 0.6, 0.99, n)
        steps += 1
    assert steps == 10 and n == 0
    # without decay the same proposal is never taken
    current, n = 0, 0
    for _ in range(200):
        current, n = commitment_decision(current, 1, 0.55, 0.6, 1.0, n)
    assert current == 0 and n == 200


def test_alpha_divergence_loss_hand_values() -> None:
    y = torch.tensor([0.0, 2.0])
    # all samples equal -> tau / 2 * (y - q)^2
    q = torch.tensor([[1.0, 1.5]]).expand(4, 2)
    expected = (10.0 / 2 * 1.0**2 + 10.0 / 2 * 0.5**2) / 2
    assert float(alpha_divergence_loss(q, y, 0.5, 10.0)) == pytest.approx(expected)
    # K = 2 samples {0, 1}, y = 0, alpha 0.5, tau 10: -2 * (log(1 + e^-2.5) - log 2)
    q2 = torch.tensor([[0.0], [1.0]])
    hand = -2.0 * (math.log(1.0 + math.exp(-2.5)) - math.log(2.0))
    assert float(alpha_divergence_loss(q2, torch.zeros(1), 0.5, 10.0)) == pytest.approx(hand)
    assert dropout_weight_decay(0.9, 0.01, 1e6, 10.0) == pytest.approx(4.5e-12)


def test_bayesian_critic_passes() -> None:
    torch.manual_seed(0)
    critic = BayesianCritic(obs_dim=5, action_dim=2, out_dim=1, hidden=[8, 8, 8], keep_prob=0.9)
    obs, act = torch.randn(3, 5), torch.randn(3, 2)
    det1, det2 = critic(obs, act), critic(obs, act)
    assert det1.shape == (3, 1) and torch.equal(det1, det2)  # no dropout in the deterministic pass
    mc = critic(obs, act, samples=20)
    assert mc.shape == (20, 3, 1)
    assert mc.std(dim=0).min() > 0  # independent masks give different samples
    discrete = BayesianCritic(obs_dim=5, action_dim=0, out_dim=4, hidden=[8, 8, 8], keep_prob=0.9)
    assert discrete(obs).shape == (3, 4) and discrete(obs, samples=6).shape == (6, 3, 4)


def test_dropout_masks_come_from_the_given_generator() -> None:
    # the masks are a function of the generator's state: a seed fixes them, a checkpoint of the
    # generator resumes them (AC-Teach passes its own generator to its critic)
    a = dropout_mask(np.random.default_rng(5), (4, 3, 8), 0.9)
    assert torch.equal(a, dropout_mask(np.random.default_rng(5), (4, 3, 8), 0.9))
    assert not torch.equal(a, dropout_mask(np.random.default_rng(6), (4, 3, 8), 0.9))
    assert set(a.unique().tolist()) <= {0.0, float(np.float32(1 / 0.9))}
    # keep probability 1: no dropout; an odd element count uses half of the last 64 random bits
    assert torch.equal(dropout_mask(np.random.default_rng(0), (3, 5), 1.0), torch.ones(3, 5))
    assert dropout_mask(np.random.default_rng(0), (3, 5), 0.5).shape == (3, 5)
    assert dropout_mask(np.random.default_rng(0), (3, 5), 1.0 - 1e-12).min() > 0  # no overflow
    # 1e6 draws at keep 0.3: the kept share within 5 standard errors of 0.3, the mean scale 1
    m = dropout_mask(np.random.default_rng(1), (1000, 1000), 0.3)
    assert abs(float((m > 0).float().mean()) - 0.3) < 5 * (0.3 * 0.7 / 1e6) ** 0.5
    assert abs(float(m.mean()) - 1.0) < 0.01
    torch.manual_seed(0)
    critics = [BayesianCritic(5, 0, 4, [8, 8], 0.9, rng=np.random.default_rng(2)) for _ in range(2)]
    critics[1].load_state_dict(critics[0].state_dict())
    obs = torch.randn(3, 5)
    assert torch.equal(critics[0](obs, samples=7), critics[1](obs, samples=7))


def test_batched_dropout_samples_equal_the_per_sample_loop() -> None:
    # K samples in one batched pass == K plain passes, each with its own slice of the masks
    torch.manual_seed(0)
    critic = BayesianCritic(5, 2, 1, [8, 8, 8], 0.9, rng=np.random.default_rng(3))
    obs, act = torch.randn(4, 5), torch.randn(4, 2)
    batched = critic(obs, act, samples=6)
    rng = np.random.default_rng(3)  # the same draws in the same order: one block per layer
    masks = [dropout_mask(rng, (6, 4, 8), 0.9) for _ in range(3)]
    for k in range(6):
        h = obs
        for i, (linear, norm) in enumerate(zip(critic.linears, critic.norms, strict=True)):
            h = torch.relu(norm(linear(h))) * masks[i][k]
            if i == 0:
                h = torch.cat([h, act], dim=-1)
        assert torch.allclose(critic.out(h), batched[k], atol=1e-6)


# --------------------------------------------------------------------------- DQN-TLQL math
def test_td_targets_and_epsilon() -> None:
    r = torch.tensor([1.0, 0.5, 0.0])
    term = torch.tensor([0.0, 1.0, 0.0])
    next_q = torch.tensor([[0.0, 2.0], [5.0, 1.0], [-1.0, -3.0]])
    y = td_targets(r, term, next_q, 0.9)
    assert y.tolist() == pytest.approx([1.0 + 0.9 * 2.0, 0.5, 0.9 * -1.0])
    assert linear_epsilon(0.0, 1.0, 0.01, 0.1) == 1.0
    assert linear_epsilon(0.05, 1.0, 0.01, 0.1) == pytest.approx(0.505)
    assert linear_epsilon(0.7, 1.0, 0.01, 0.1) == 0.01


def test_real_next_obs_bootstraps_truncation() -> None:
    next_obs = np.array([[0.0], [9.0], [9.0]])
    dones = np.array([False, True, True])
    infos = [
        {},
        {"terminal_observation": np.array([1.0])},
        {"terminal_observation": np.array([2.0]), "TimeLimit.truncated": True},
    ]
    real, terminated = real_next_obs(next_obs, dones, infos)
    assert real.ravel().tolist() == [0.0, 1.0, 2.0]
    assert terminated.tolist() == [0.0, 1.0, 0.0]  # the truncated episode is not terminal


# --------------------------------------------------------------------------- SB3 adapters
def test_sb3_kwargs_maps_presets() -> None:
    kw = sb3_kwargs(
        "a2c", {k: v for k, v in load_preset("doorkey", "a2c").items() if k != "n_envs"}
    )
    pk = kw["policy_kwargs"]
    assert pk["optimizer_class"] is RMSpropTFLike
    assert pk["optimizer_kwargs"] == {"alpha": 0.99, "eps": 1e-5, "weight_decay": 0}
    assert pk["net_arch"] == {"pi": [64, 64], "vf": [64, 64]}
    assert kw["n_steps"] == 5 and kw["gae_lambda"] == 0.9 and kw["normalize_advantage"] is True
    hop = {k: v for k, v in load_preset("hopper", "ppo").items() if k != "n_envs"}
    kw = sb3_kwargs("ppo", hop)
    assert kw["learning_rate"](1.0) == pytest.approx(5e-4) and kw["learning_rate"](
        0.0
    ) == pytest.approx(3e-5)
    assert kw["clip_range"](0.5) == pytest.approx(0.2)
    assert kw["_target_kl_schedule"](0.0) == pytest.approx(0.01)
    assert kw["use_sde"] is True and kw["policy_kwargs"]["log_std_init"] == -2.0
    assert kw["policy_kwargs"]["ortho_init"] is False
    with pytest.raises(ConfigError, match="n_epochs"):
        sb3_kwargs("a2c", {"n_epochs": 3})  # PPO's key given to A2C
    with pytest.raises(ConfigError, match="optimizer"):
        sb3_kwargs("a2c", {"optimizer": "sgd"})


@pytest.mark.parametrize("cls", [A2CBaseline, PPOBaseline])
@pytest.mark.parametrize("make_env", [cartpole, pendulum])
def test_sb3_baselines_run_save_load(cls, make_env, tmp_path: Path) -> None:
    env = make_env(n=2)
    hp = {"n_steps": 8, "net_arch": [16], "optimizer": "rmsprop_tf", "optimizer_eps": 1e-5}
    if cls is PPOBaseline:
        hp |= {"batch_size": 16, "n_epochs": 1, "target_kl": {"linear": [0.04, 0.01]}}
    if make_env is pendulum:
        hp |= {"use_sde": True, "sde_sample_freq": 4, "log_std_init": -2.0}
    recorder = Recorder(tmp_path, ["agent"], log_interval=16)
    model = cls(env, [], seed=0, recorder=recorder, **hp)
    calls: list[int] = []
    model.learn(64, callback=lambda algo: calls.append(algo.num_timesteps))
    assert model.num_timesteps >= 64 and calls and calls[0] == 16
    obs = env.reset()
    actions, state = model.predict(obs, deterministic=True)
    assert state is None and len(actions) == 2
    model.save(tmp_path / "model")
    assert (tmp_path / "model.zip").exists()
    loaded = cls.load(tmp_path / "model", trust_pickle=True)  # SB3's zip: a pickle
    assert np.allclose(loaded.predict(obs, deterministic=True)[0], actions)
    recorder.close(model.num_timesteps)
    assert "train/" in (tmp_path / "progress.csv").read_text()


def test_sb3_callback_false_stops_and_teachers_rejected() -> None:
    model = A2CBaseline(cartpole(), [], seed=0, recorder=None, n_steps=5)
    model.learn(10_000, callback=lambda algo: False)
    # the first rollout (5 steps) is collected and used; SB3 notices the stop on its next step
    assert 5 <= model.num_timesteps <= 6
    with pytest.raises(ConfigError, match="no teachers"):
        A2CBaseline(cartpole(), cartpole_teachers(), seed=0, recorder=None)


# --------------------------------------------------------------------------- DQN-TLQL
def test_dqn_tlql_runs_records_and_reloads(tmp_path: Path) -> None:
    env = cartpole(n=2)
    teachers = cartpole_teachers()
    recorder = Recorder(tmp_path, [t.name for t in teachers] + ["agent"], log_interval=100)
    model = DQNTLQL(env, teachers, seed=0, recorder=recorder, **SMALL_DQN)
    calls: list[int] = []
    model.learn(400, callback=lambda a: calls.append(a.num_timesteps))
    assert model.num_timesteps == 400 and calls[0] == 40  # train_freq 20 vec-steps x 2 envs
    recorder.close(model.num_timesteps)
    usage = (tmp_path / "teacher_usage.csv").read_text()
    assert "balance" in usage and "left" in usage and "agent" in usage
    obs = env.reset()
    actions, _ = model.predict(obs)
    assert actions.shape == (2,) and set(actions.tolist()) <= {0, 1}
    model.save(tmp_path / "model")
    loaded = DQNTLQL.load(tmp_path / "model", env=env, teachers=teachers)
    assert np.array_equal(loaded.predict(obs)[0], actions) and loaded.num_timesteps == 400
    loaded.learn(100)  # continues training
    assert loaded.num_timesteps == 500


def test_dqn_tlql_is_deterministic_given_a_seed() -> None:
    def run() -> list[torch.Tensor]:
        m = DQNTLQL(cartpole(seed=3), cartpole_teachers(), seed=3, recorder=None, **SMALL_DQN)
        m.learn(300)
        return [p.detach().clone() for p in m.q_low.parameters()]

    assert all(torch.equal(a, b) for a, b in zip(run(), run(), strict=True))


def test_dqn_tlql_rejects_continuous_and_bad_settings() -> None:
    with pytest.raises(ConfigError, match="Discrete"):
        DQNTLQL(pendulum(), pendulum_teachers(), seed=0, recorder=None)
    with pytest.raises(ConfigError, match="unknown dqn-tlql hyperparameter 'n_steps'"):
        DQNTLQL(cartpole(), [], seed=0, recorder=None, n_steps=5)
    with pytest.raises(ConfigError, match="tau"):
        DQNTLQL(cartpole(), [], seed=0, recorder=None, tau=0.0)


def test_bad_teacher_actions_raise() -> None:
    bad = [as_teacher(lambda o: 7, gym.spaces.Discrete(2), name="broken")]
    with pytest.raises(TeacherError, match="broken"):
        DQNTLQL(cartpole(), bad, seed=0, recorder=None, exploration_initial_eps=1.0).learn(50)
    bad_box = [
        as_teacher(lambda o: np.array([5.0]), gym.spaces.Box(-2, 2, (1,)), name="too-strong")
    ]
    with pytest.raises(TeacherError, match="too-strong"):
        ACTeach(pendulum(), bad_box, seed=0, recorder=None, **SMALL_AC_TEACH).learn(10)


# --------------------------------------------------------------------------- AC-Teach
@pytest.mark.parametrize(
    "flags",
    [
        {},
        {"commitment": False},
        {"meta_target": False},
        {"switch_sign": "code"},
        {"commitment_decay": 1.0},
    ],
    ids=["full", "no-commitment", "no-meta-target", "code-sign", "no-decay"],
)
def test_ac_teach_continuous_runs(flags: dict, tmp_path: Path) -> None:
    env = pendulum()
    teachers = pendulum_teachers()
    recorder = Recorder(tmp_path, [t.name for t in teachers] + ["agent"], log_interval=50)
    model = ACTeach(env, teachers, seed=0, recorder=recorder, **SMALL_AC_TEACH, **flags)
    model.learn(220)
    assert model.num_timesteps == 220
    recorder.close(model.num_timesteps)
    assert "damping" in (tmp_path / "teacher_usage.csv").read_text()
    assert "train/critic_loss" in (tmp_path / "progress.csv").read_text()
    obs = env.reset()
    actions, _ = model.predict(obs)
    assert actions.shape == (1, 1) and np.all(np.abs(actions) <= 2.0)


def test_ac_teach_discrete_runs_and_reloads(tmp_path: Path) -> None:
    env = cartpole(n=2)
    teachers = cartpole_teachers()
    model = ACTeach(env, teachers, seed=0, recorder=None, **SMALL_AC_TEACH)
    stops: list[int] = []
    model.learn(300, callback=lambda a: stops.append(a.num_timesteps))
    assert stops[0] == 50
    obs = env.reset()
    actions, _ = model.predict(obs)
    model.save(tmp_path / "m")
    loaded = ACTeach.load(tmp_path / "m.pt")
    assert np.array_equal(loaded.predict(obs)[0], actions)


def test_ac_teach_continuous_reload(tmp_path: Path) -> None:
    env = pendulum()
    model = ACTeach(env, pendulum_teachers(), seed=1, recorder=None, **SMALL_AC_TEACH)
    model.learn(60)
    obs = env.reset()
    model.save(tmp_path / "m")
    loaded = ACTeach.load(tmp_path / "m", env=env, teachers=pendulum_teachers())
    assert np.allclose(loaded.predict(obs)[0], model.predict(obs)[0])
    with pytest.raises(ConfigError, match="built for 2 teachers"):
        ACTeach.load(tmp_path / "m", env=env, teachers=[]).learn(10)


def test_ac_teach_is_deterministic_given_a_seed() -> None:
    def run() -> tuple[list[torch.Tensor], np.ndarray]:
        env = pendulum(seed=5)
        m = ACTeach(env, pendulum_teachers(), seed=5, recorder=None, **SMALL_AC_TEACH)
        m.learn(120)
        assert m.actor is not None
        return [p.detach().clone() for p in m.actor.parameters()], m._current.copy()

    (a, ca), (b, cb) = run(), run()
    assert all(torch.equal(x, y) for x, y in zip(a, b, strict=True)) and np.array_equal(ca, cb)


def test_thompson_with_commitment_follows_the_better_teacher() -> None:
    """With a critic that rates teacher 1's action far above the others, the behaviour policy
    picks teacher 1 and stays with it; with the code's sign it never leaves a first choice
    for it."""
    env = cartpole()
    model = ACTeach(env, cartpole_teachers(), seed=0, recorder=None, **SMALL_AC_TEACH)
    with torch.no_grad():  # Q(s, .) = [0, 5]: action 1 (never advised by "left") is best
        model.critic.out.weight.zero_()
        model.critic.out.bias.copy_(torch.tensor([0.0, 5.0]))
    obs = np.zeros((1, 4), np.float32)
    left_only = np.array([[0, 0]])  # both teachers advise action 0 here
    model._current, model._declined, model._switches = np.array([0]), np.array([0]), 0
    choices, candidates = model._behaviour(obs, left_only, eps=0.0)  # learner's greedy = 1
    assert choices.tolist() == [2] and candidates[0, 2] == 1  # switched to the agent
    model2 = ACTeach(
        env, cartpole_teachers(), seed=0, recorder=None, switch_sign="code", **SMALL_AC_TEACH
    )
    model2.critic.load_state_dict(model.critic.state_dict())
    model2._current, model2._declined, model2._switches = np.array([0]), np.array([0]), 0
    choices, _ = model2._behaviour(obs, left_only, eps=0.0)
    assert choices.tolist() == [0] and model2._declined.tolist() == [1]  # code sign: stays


# --------------------------------------------------------------------------- run folder
@pytest.mark.parametrize("algo", ["a2c", "ppo", "dqn-tlql", "ac-teach"])
def test_train_run_writes_the_run_folder(algo: str, tmp_path: Path) -> None:
    from tlac.run import RunSpec, train_run

    overrides = {
        "ac-teach": {"buffer_size": 2000, "mc_samples": 8, "cycle_grad_steps": 5},
        "dqn-tlql": {"gradient_steps": 2},
    }.get(algo, {})
    spec = RunSpec(
        env="doorkey",
        algo=algo,
        teachers=["optimal", "random"],
        steps=400,
        eval_episodes=1,
        log_interval=200,
        overrides=overrides,
    )
    result = train_run(spec, tmp_path)
    assert result["steps"] >= 400
    assert (tmp_path / "episodes.csv").read_text().startswith("timestep,return,length")
    model_file = tmp_path / ("model.zip" if algo in ("a2c", "ppo") else "model.pt")
    assert model_file.exists()
    trust = {"trust_pickle": True} if algo in ("a2c", "ppo") else {}  # SB3's zip: a pickle
    loaded = get_algorithm(algo).load(tmp_path / "model", **trust)
    obs = np.zeros((1, 147), np.float32)
    assert loaded.predict(obs)[0].shape == (1,)
    if algo in ("dqn-tlql", "ac-teach"):
        usage = (tmp_path / "teacher_usage.csv").read_text()
        assert "optimal" in usage and "agent" in usage


# --------------------------------------------------------------------------- learning checks
def doorkey_run(algo_cls: type, teachers: list[str], steps: int, **overrides) -> tuple[float, dict]:
    """Train on DoorKey; return the mean training return of the last 20 episodes (teacher
    actions included, as the paper reports) and the high level's choice fractions over the
    last quarter of training."""
    from tlac.domains import get_domain, make_teachers

    domain = get_domain("doorkey")
    venv = DummyVecEnv([domain.make_env])
    venv.seed(0)
    env = EpisodeRecorder(venv, window=20)
    algo = "dqn-tlql" if algo_cls is DQNTLQL else "ac-teach"
    team = make_teachers(domain, teachers, domain.make_env(), 0)
    recorder = Recorder(None, [t.name for t in team] + ["agent"], log_interval=steps // 4)
    preset = {k: v for k, v in load_preset("doorkey", algo).items() if k != "n_envs"}
    model = algo_cls(env, team, seed=0, recorder=recorder, **(preset | overrides))
    model.learn(steps)
    recorder.flush(model.num_timesteps)
    ret = env.mean_recent_return() if env.episode_returns else 0.0
    return ret, dict(recorder.last_usage)


# DoorKey, the check: with an optimal teacher the training return reaches a threshold
# that learning from random advice does not (following the optimal teacher returns ~0.95;
# random advice almost never reaches the goal within 490 steps). On its own it cannot tell
# learning from a selector that never learns: choosing uniformly at every step among
# {optimal, random, agent} already returns ~0.87 on DoorKey, because the optimal teacher
# recovers from any state. The CartPole checks below close that gap.
THRESHOLD = 0.6


@pytest.mark.slow
def test_dqn_tlql_doorkey_optimal_teacher_beats_random_advice() -> None:
    # learning_rate 1e-3 instead of Table 6's 1e-4 lets the check learn in 10k steps
    fast = {"learning_rate": 1e-3}
    good, usage = doorkey_run(DQNTLQL, ["optimal", "random"], 10_000, **fast)
    assert good >= THRESHOLD, (good, usage)
    bad, _ = doorkey_run(DQNTLQL, ["random", "random"], 10_000, **fast)
    assert bad < 0.2, bad


@pytest.mark.slow
def test_ac_teach_doorkey_optimal_teacher_beats_random_advice() -> None:
    # 10 dropout samples instead of 50 keep the check within CI time (docs/baselines/ac-teach.md)
    fast = {"mc_samples": 10}
    good, usage = doorkey_run(ACTeach, ["optimal", "random"], 8_000, **fast)
    assert good >= THRESHOLD, (good, usage)
    bad, _ = doorkey_run(ACTeach, ["random", "random"], 8_000, **fast)
    assert bad < 0.2, bad


# CartPole with a good teacher ("balance") and a harmful one ("left", always push left):
# here the CHOICE matters at every step, so a selector that does not learn fails.
def uniform_choice_return(episodes: int = 30) -> float:
    """Mean CartPole return when every step follows balance, left or a random action with
    probability 1/3 each: what a high level that never learns would get."""
    env, rng, returns = gym.make("CartPole-v1"), np.random.default_rng(0), []
    balance = cartpole_teachers()[0]
    for ep in range(episodes):
        obs, _ = env.reset(seed=ep)
        done, total = False, 0.0
        while not done:
            c = rng.integers(3)
            a = int(balance.predict(obs[None])[0]) if c == 0 else (0 if c == 1 else rng.integers(2))
            obs, r, terminated, truncated, _ = env.step(a)
            total += float(r)
            done = terminated or truncated
        returns.append(total)
    return float(np.mean(returns))


def cartpole_run(algo_cls: type, steps: int, **overrides) -> tuple[float, dict]:
    env = cartpole()
    teachers = cartpole_teachers()
    recorder = Recorder(None, [t.name for t in teachers] + ["agent"], log_interval=steps // 4)
    algo = "dqn-tlql" if algo_cls is DQNTLQL else "ac-teach"
    preset = {k: v for k, v in load_preset("doorkey", algo).items() if k != "n_envs"}
    model = algo_cls(env, teachers, seed=0, recorder=recorder, **(preset | overrides))
    model.learn(steps)
    recorder.flush(model.num_timesteps)
    return env.mean_recent_return(), dict(recorder.last_usage)


@pytest.mark.slow
def test_dqn_tlql_learns_which_teacher_to_follow() -> None:
    uniform = uniform_choice_return()
    assert uniform < 50, uniform  # ~28: the harmful teacher topples the pole quickly
    ret, usage = cartpole_run(DQNTLQL, 10_000, learning_rate=1e-3)
    assert ret >= 100, (ret, usage)  # seeds 0-2 reach 159-263


@pytest.mark.slow
def test_ac_teach_learns_which_teacher_to_follow() -> None:
    # tau 0.01 instead of 0.001 (and 10 dropout samples) lets the critic learn in 8k steps.
    # With an untrained critic, commitment keeps whatever Thompson drew at the episode start
    # (~1/3 "left"); a learned critic stops proposing "left" (seeds 0-2: 4-5% of choices).
    ret, usage = cartpole_run(ACTeach, 8_000, mc_samples=10, tau=0.01)
    assert usage["left"] < 0.15, (ret, usage)
    assert ret >= 50, (ret, usage)  # uniform choice: ~28
