"""SB3's VecNormalize with tlac (issue 43, point 1): a user's normalised environments, and
teachers trained under normalisation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from tlac import TLAC
from tlac.errors import ConfigError
from tlac.recording import find_episode_recorder
from tlac.teachers import from_rl_zoo, from_sb3


class RawLog(gym.ObservationWrapper):
    """Keeps every observation the environment produced, before any VecNormalize."""

    def __init__(self, env: gym.Env, log: list[np.ndarray]):
        super().__init__(env)
        self.log = log

    def observation(self, observation: np.ndarray) -> np.ndarray:
        self.log.append(np.asarray(observation, dtype=np.float32).copy())
        return observation


def normalized_cartpole(log: list[np.ndarray] | None = None, **kwargs) -> VecNormalize:
    def make() -> gym.Env:
        env = gym.make("CartPole-v1")
        return env if log is None else RawLog(env, log)

    venv = DummyVecEnv([make])
    venv.seed(0)
    return VecNormalize(venv, **kwargs)


@pytest.fixture(scope="module")
def normalized_agent() -> tuple[PPO, VecNormalize]:
    """A PPO agent trained briefly under VecNormalize, with statistics far from zero mean."""
    venv = normalized_cartpole()
    model = PPO("MlpPolicy", venv, n_steps=256, batch_size=64, seed=0, device="cpu")
    model.learn(1024)
    venv.obs_rms.mean = venv.obs_rms.mean + np.array([0.5, -1.0, 0.1, 2.0])  # stats that matter
    return model, venv


def test_a_normalised_teacher_sees_what_its_agent_was_trained_on(normalized_agent, tmp_path):
    model, venv = normalized_agent
    obs = np.random.default_rng(0).normal(size=(64, 4)).astype(np.float32)
    expected = model.predict(venv.normalize_obs(obs), deterministic=True)[0]
    assert not np.array_equal(expected, model.predict(obs, deterministic=True)[0])  # it matters
    teacher = from_sb3(model, venv)
    assert np.array_equal(teacher.predict(obs), expected)
    assert venv.training  # the user's VecNormalize is left as it was (a frozen copy is used)
    venv.obs_rms.mean = venv.obs_rms.mean + 5.0
    assert np.array_equal(teacher.predict(obs), expected)
    venv.obs_rms.mean = venv.obs_rms.mean - 5.0
    # from files, and from an rl-zoo run folder (logs/ppo/CartPole-v1_1/...)
    model.save(tmp_path / "agent.zip")
    venv.save(tmp_path / "stats.pkl")
    with pytest.raises(ConfigError, match="trust_pickle=True"):  # pickles: opt in
        from_sb3(tmp_path / "agent.zip", algo="ppo")
    with pytest.raises(ConfigError, match="trust_pickle=True"):
        from_sb3(model, tmp_path / "stats.pkl")
    teacher = from_sb3(
        tmp_path / "agent.zip", tmp_path / "stats.pkl", algo="ppo", trust_pickle=True
    )
    assert np.array_equal(teacher.predict(obs), expected)
    run = tmp_path / "ppo" / "CartPole-v1_1"
    (run / "CartPole-v1").mkdir(parents=True)
    model.save(run / "CartPole-v1.zip")
    venv.save(run / "CartPole-v1" / "vecnormalize.pkl")
    with pytest.raises(ConfigError, match="trust_pickle=True"):
        from_rl_zoo(run)
    zoo = from_rl_zoo(run, trust_pickle=True)
    assert zoo.name == "ppo-CartPole-v1" and np.array_equal(zoo.predict(obs), expected)
    elsewhere = tmp_path / "models" / "CartPole-v1_1"
    elsewhere.mkdir(parents=True)
    with pytest.raises(ConfigError, match="cannot tell the algorithm"):
        from_rl_zoo(elsewhere)
    (tmp_path / "junk.pkl").write_bytes(b"not a pickle")
    with pytest.raises(ConfigError, match="not a saved VecNormalize"):
        from_sb3(model, tmp_path / "junk.pkl", trust_pickle=True)


def test_tlac_under_a_users_vecnormalize(tmp_path):
    """Teachers get the raw observations, episode returns stay in the environment's units,
    and SB3's callbacks find the VecNormalize: EvalCallback syncs it, CheckpointCallback saves
    it."""
    raw_log: list[np.ndarray] = []
    seen: list[np.ndarray] = []

    def teacher(obs: np.ndarray) -> int:
        seen.append(np.asarray(obs, dtype=np.float32))
        return int(obs[2] + obs[3] > 0)  # a balancing rule on the raw angle and its velocity

    venv = normalized_cartpole(raw_log)
    eval_env = normalized_cartpole(training=False, norm_reward=False)
    model = TLAC(venv, teachers=[teacher], seed=0, n_steps=256, batch_size=64)
    assert model.get_vec_normalize_env() is venv
    checkpoints = CheckpointCallback(512, str(tmp_path), save_vecnormalize=True)
    evaluation = EvalCallback(eval_env, eval_freq=512, n_eval_episodes=1, verbose=0)
    model.learn(1024, callback=[checkpoints, evaluation], progress_bar=False)
    raw = np.unique(np.stack(raw_log), axis=0)
    assert len(seen) > 100
    assert all(np.isclose(raw, o, atol=1e-6).all(axis=1).any() for o in seen[::10])
    assert eval_env.obs_rms.count == venv.obs_rms.count > 1000  # synced at the last evaluation
    assert sorted(p.name for p in tmp_path.glob("*vecnormalize*")) == [
        "rl_model_vecnormalize_1024_steps.pkl",
        "rl_model_vecnormalize_512_steps.pkl",
    ]
    recorder = find_episode_recorder(model.env)
    assert recorder is not None and recorder.episodes_done > 0
    assert list(recorder.episode_returns) == [float(n) for n in recorder.episode_lengths]
    # save / load keep the statistics (as tensors in the model file)
    path = model.save(tmp_path / "model")
    fresh = normalized_cartpole()
    TLAC.load(path, env=fresh)
    assert fresh.obs_rms.count == venv.obs_rms.count
    assert np.array_equal(fresh.obs_rms.mean, venv.obs_rms.mean)
    assert np.array_equal(fresh.ret_rms.var, venv.ret_rms.var)
