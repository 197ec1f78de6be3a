"""The greedy path of an SB3 teacher (tlac.teachers.sb3.GreedyPolicy) against SB3's own
``predict(obs, deterministic=True)``: the same actions, bit for bit, on trained-looking
(perturbed) and untrained networks, and SB3's predict wherever the path does not apply."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3 import A2C, DQN, PPO, SAC

from tlac.errors import TeacherError
from tlac.teachers.base import as_teacher, ask_teacher
from tlac.teachers.sb3 import GreedyPolicy, SB3Teacher

ROOT = Path(__file__).resolve().parent.parent


def _perturbed(model, seed: int, scale: float):
    """``model`` with its weights moved by Gaussian noise (logits far from uniform, near ties
    among rows as well)."""
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in model.policy.parameters():
            p.add_(torch.randn(p.shape, generator=gen) * scale)
    return model


def _observations(env_id: str, n: int, seed: int, dtype=np.float32) -> np.ndarray:
    space = gym.make(env_id).observation_space
    rng = np.random.default_rng(seed)
    low = np.maximum(space.low, -5.0)
    high = np.minimum(space.high, 5.0)
    return rng.uniform(low, high, size=(n, *space.shape)).astype(dtype)


CASES = [
    (PPO, "Acrobot-v1", {}),
    (PPO, "CartPole-v1", {"policy_kwargs": {"net_arch": [8], "activation_fn": torch.nn.ReLU}}),
    (PPO, "Pendulum-v1", {}),
    (PPO, "Pendulum-v1", {"policy_kwargs": {"share_features_extractor": False}}),
    (A2C, "Acrobot-v1", {}),
    (DQN, "CartPole-v1", {"learning_starts": 0}),
]


@pytest.mark.parametrize(("algo", "env_id", "kwargs"), CASES)
def test_the_greedy_path_gives_sb3s_actions_bit_for_bit(algo, env_id, kwargs):
    torch.set_num_threads(1)
    model = algo("MlpPolicy", gym.make(env_id), seed=0, device="cpu", **kwargs)
    fast = GreedyPolicy.of(model)
    assert fast is not None
    for scale in (0.0, 0.3, 3.0):
        _perturbed(model, 1, scale)
        for n, dtype in ((1, np.float32), (7, np.float32), (513, np.float32), (5, np.float64)):
            obs = _observations(env_id, n, n, dtype)
            expected = model.predict(obs, deterministic=True)[0]
            got = fast(obs)
            assert got is not None
            assert got.dtype == expected.dtype and got.shape == expected.shape
            assert np.array_equal(got, expected)
        # the teacher as TL-AC builds it (as_teacher), through ask_teacher
        teacher = as_teacher(model, model.action_space)
        assert isinstance(teacher, SB3Teacher) and teacher.greedy is not None
        obs = _observations(env_id, 64, 9)
        plain = np.asarray(model.predict(obs, deterministic=True)[0])
        space = model.action_space
        assert np.array_equal(
            ask_teacher(teacher, obs, space), ask_teacher(plain_teacher(model), obs, space)
        )
        assert np.array_equal(teacher.predict(obs), plain)


def plain_teacher(model):
    teacher = SB3Teacher(model, "plain")
    teacher.greedy = None
    return teacher


def test_ties_and_the_sweeps_teacher_network():
    """Equal logits in a row (an untrained net's zeroed action layer) take SB3's first
    action; a saved sweep teacher acts as through SB3."""
    model = PPO("MlpPolicy", gym.make("Acrobot-v1"), seed=0, device="cpu")
    with torch.no_grad():
        model.policy.action_net.weight.zero_()
        model.policy.action_net.bias.zero_()
    obs = _observations("Acrobot-v1", 32, 0)
    assert np.array_equal(GreedyPolicy.of(model)(obs), model.predict(obs, deterministic=True)[0])
    saved = ROOT / "results" / "teacher-sweep" / "teachers" / "Acrobot-v1" / "q0.25.pt"
    if saved.exists():
        model.policy.load_state_dict(torch.load(saved, weights_only=True), strict=False)
        obs = _observations("Acrobot-v1", 4096, 1)
        expected = model.predict(obs, deterministic=True)[0]
        assert np.array_equal(GreedyPolicy.of(model)(obs), expected)
        fast = GreedyPolicy.of(model)
        for row in obs[:300, None]:  # one row at a time, as a teacher leading an episode is asked
            assert np.array_equal(fast(row), model.predict(row, deterministic=True)[0])


def test_sb3s_predict_answers_where_the_path_does_not_apply():
    env = gym.make("Acrobot-v1")
    model = PPO("MlpPolicy", env, seed=0, device="cpu")
    fast = GreedyPolicy.of(model)
    one = _observations("Acrobot-v1", 1, 0)[0]
    assert fast(one) is None  # one observation, not a batch: SB3 squeezes it
    assert fast(np.zeros((2, 5), np.float32)) is None  # the wrong shape: SB3's error
    assert fast(np.array([["a"] * 6])) is None
    nan = np.full((1, 6), np.nan, np.float32)
    assert fast(nan) is None  # Categorical refuses NaN logits
    teacher = as_teacher(model, env.action_space)
    with pytest.raises(TeacherError):
        ask_teacher(teacher, nan, env.action_space)
    # sampled actions, SAC, dropout in the network: SB3's predict every time
    assert SB3Teacher(model, "ppo", deterministic=False).greedy is None
    assert GreedyPolicy.of(SAC("MlpPolicy", gym.make("Pendulum-v1"), device="cpu")) is None
    model.policy.mlp_extractor.policy_net.append(torch.nn.Dropout(0.5))
    assert GreedyPolicy.of(model) is None


def test_the_training_mode_is_left_as_sb3s_predict_leaves_it():
    model = PPO("MlpPolicy", gym.make("CartPole-v1"), seed=0, device="cpu")
    model.policy.set_training_mode(True)
    GreedyPolicy.of(model)(_observations("CartPole-v1", 3, 0))
    assert not any(m.training for m in model.policy.modules())
