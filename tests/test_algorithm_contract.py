"""ONE contract test over every registered algorithm (issue 12, item 2): each keeps the
:class:`tlac.algorithms.Algorithm` protocol -- the same signatures, a few hundred learning
steps on DoorKey (Discrete actions) and on Pendulum (Box actions, where the algorithm
supports them), ``predict``'s shapes and dtypes, a repeatable deterministic ``predict``,
``save`` returning the file's ``Path``, and ``load`` giving back identical predictions."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

from tlac.algorithms import NO_ADVICE, Algorithm, algorithm_names, get_algorithm
from tlac.algorithms.protocol import conforms
from tlac.domains import get_domain, make_teachers, make_vec_env
from tlac.errors import ConfigError
from tlac.recording import EpisodeRecorder
from tlac.teachers.wrappers import RandomTeacher

STEPS = 256
TINY: dict[str, dict] = {  # budgets small enough for a few hundred steps to update several times
    "tlac": {"n_steps": 16, "batch_size": 16},
    "ppo": {"n_steps": 64, "batch_size": 32, "n_epochs": 2},
    "a2c": {"n_steps": 8},
    "dqn-tlql": {"learning_starts": 32, "batch_size": 16, "train_freq": 16},
    "ac-teach": {
        "batch_size": 16,
        "buffer_size": 1000,
        "cycle_env_steps": 64,
        "cycle_grad_steps": 2,
        "mc_samples": 4,
    },
}
BOX_UNSUPPORTED = {"dqn-tlql"}  # "does not support continuous control" (paper, section 4.1)


def _doorkey(algo: str):
    domain = get_domain("doorkey")
    env = make_vec_env(domain, 2, 0, None)
    names = [] if algo in NO_ADVICE else ["optimal", "random"]
    return env, make_teachers(domain, names, domain.make_env(), 0)


def _pendulum(algo: str):
    venv = DummyVecEnv([lambda: gym.make("Pendulum-v1") for _ in range(2)])
    venv.seed(0)
    box = venv.action_space
    teachers = [] if algo in NO_ADVICE else [RandomTeacher(box, seed=0, name="random")]
    return EpisodeRecorder(venv), teachers


CASES = [(a, "doorkey") for a in algorithm_names()] + [
    (a, "pendulum") for a in algorithm_names() if a not in BOX_UNSUPPORTED
]


def test_every_algorithm_is_covered() -> None:
    assert set(TINY) == set(algorithm_names())


@pytest.mark.parametrize("algo", algorithm_names())
def test_signatures_match_the_protocol(algo: str) -> None:
    assert conforms(get_algorithm(algo)) == []


@pytest.mark.parametrize(("algo", "env_name"), CASES, ids=[f"{a}-{e}" for a, e in CASES])
def test_algorithm_contract(tmp_path: Path, algo: str, env_name: str) -> None:
    cls = get_algorithm(algo)
    env, teachers = (_doorkey if env_name == "doorkey" else _pendulum)(algo)
    extra = {"preset": None} if algo == "tlac" else {}
    model = cls(env, teachers=teachers, seed=0, recorder=None, **extra, **TINY[algo])
    assert isinstance(model, Algorithm)

    assert model.learn(STEPS, progress_bar=False) is model
    assert model.num_timesteps >= STEPS

    space = env.action_space
    obs = env.reset()  # a batch of 2
    one, state = model.predict(obs[0], deterministic=True)
    assert state is None
    batch, _ = model.predict(obs, deterministic=True)
    assert np.shape(one) == space.shape and np.shape(batch) == (2, *space.shape)
    if isinstance(space, gym.spaces.Discrete):
        assert np.issubdtype(np.asarray(batch).dtype, np.integer)
    else:
        assert np.issubdtype(np.asarray(batch).dtype, np.floating)
    assert all(space.contains(np.asarray(a, dtype=space.dtype)) for a in batch)
    sampled, _ = model.predict(obs)  # SB3's default, deterministic=False
    assert np.shape(sampled) == np.shape(batch)

    again, _ = model.predict(obs, deterministic=True)
    assert np.array_equal(again, batch)  # a deterministic predict is repeatable

    path = model.save(tmp_path / "model")
    assert isinstance(path, Path) and path.is_file()
    loaded = cls.load(path, trust_pickle=path.suffix == ".zip")  # SB3's zip: a pickle
    assert isinstance(loaded, Algorithm) and loaded.num_timesteps == model.num_timesteps
    assert np.array_equal(loaded.predict(obs, deterministic=True)[0], batch)

    if getattr(cls, "exact_resume", False):
        full = model.save(tmp_path / "full", training_state=True, run_state={"note": 1})
        resumed = cls.load(full, env=env, teachers=teachers, resume=True)
        assert np.array_equal(resumed.predict(obs, deterministic=True)[0], batch)
    else:
        with pytest.raises(ConfigError, match="training state"):
            model.save(tmp_path / "full", training_state=True)
        with pytest.raises(ConfigError, match="training state"):
            cls.load(path, env=env, resume=True)


@pytest.mark.parametrize("algo", algorithm_names())
@pytest.mark.parametrize("budget", [0, -5, True, 2.5, "100"])
def test_learn_refuses_a_budget_that_is_not_a_positive_integer(algo: str, budget) -> None:
    env, teachers = _doorkey(algo)
    model = get_algorithm(algo)(env, teachers=teachers, seed=0, recorder=None, **TINY[algo])
    with pytest.raises(ConfigError, match="total_timesteps must be a positive integer"):
        model.learn(budget)
    assert model.num_timesteps == 0


def test_a_mismatched_signature_is_reported() -> None:
    class Bad:
        num_timesteps = 0

        def learn(self, steps: int) -> Bad:
            return self

        def predict(self, observation, deterministic=False):
            return observation, None

        def save(self, path):
            return Path(path)

        def load(self, path):
            return self

    problems = conforms(Bad)
    assert "Bad.load is not a classmethod" in problems
    assert {p.split("(")[0].split("[")[0] for p in problems} >= {
        "Bad.learn",
        "Bad.predict",
        "Bad.save",
    }
