"""The user-environment suite's scripted teachers (benchmarks/user_envs.py) do what the suite
claims: each controller far outscores the random policy of its environment."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "user_envs.py"
_spec = importlib.util.spec_from_file_location("user_envs", _PATH)
user_envs = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(user_envs)


def _mean_return(env_id: str, act, episodes: int = 3) -> float:
    return float(user_envs.evaluate(user_envs.one_by_one(act), env_id, episodes).mean())


@pytest.mark.parametrize(
    "env_id, controller, at_least",
    [
        ("MountainCar-v0", user_envs.mountain_car_energy, -140.0),  # random: -200
        ("Acrobot-v1", user_envs.acrobot_swing, -120.0),  # random: ~-500
        ("Pendulum-v1", user_envs.pendulum_swing_up, -400.0),  # random: ~-1200
        ("CartPole-v1", user_envs.cartpole_pd, 475.0),  # random: ~22
    ],
)
def test_scripted_teacher_solves_its_environment(env_id, controller, at_least):
    space = gym.make(env_id).action_space
    assert _mean_return(env_id, controller) >= at_least
    assert _mean_return(env_id, user_envs.random_teacher(space, 0)) < at_least


def test_suite_teachers_are_valid_actions_and_normalisation():
    for env_id, make_teachers in user_envs.SUITE.items():
        env = gym.make(env_id)
        obs, _ = env.reset(seed=0)
        for teacher in make_teachers(0, env.action_space):
            assert env.action_space.contains(
                np.asarray(teacher(obs), dtype=env.action_space.dtype)
            ), (
                env_id,
                teacher.__name__,
            )
    assert user_envs.normalised(-150.0, -200.0, -100.0) == pytest.approx(0.5)
    assert user_envs.parse_settings(["n_steps=32", "optimizer=adam"]) == {
        "n_steps": 32,
        "optimizer": "adam",
    }
