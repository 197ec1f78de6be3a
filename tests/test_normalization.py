"""Observation / reward normalisation inside TL-AC (SB3 VecNormalize's statistics), with the
teachers still given raw observations."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.running_mean_std import RunningMeanStd as SB3RunningMeanStd

from tlac import TLAC
from tlac.algorithms.normalization import Normalizer, add_to_running_stats
from tlac.errors import ConfigError


def test_observation_statistics_are_sb3s_and_survive_a_state_round_trip() -> None:
    rng = np.random.default_rng(0)
    norm, sb3 = (
        Normalizer(3, 1, 0.99, obs=True, reward=False, clip=10.0),
        SB3RunningMeanStd(shape=(3,)),
    )
    for _ in range(20):
        batch = rng.normal(5.0, 3.0, size=(int(rng.integers(1, 9)), 3))
        norm.update_obs(batch)
        sb3.update(batch)
    np.testing.assert_allclose(norm.obs_rms.mean, sb3.mean)
    np.testing.assert_allclose(norm.obs_rms.var, sb3.var)
    copy = Normalizer(3, 1, 0.99, obs=True, reward=False, clip=10.0)
    copy.set_state(norm.state())
    x = rng.normal(size=(4, 3)).astype(np.float32)
    np.testing.assert_array_equal(copy.obs_numpy(x), norm.obs_numpy(x))


def test_reward_scaling_by_hand() -> None:
    norm = Normalizer(1, 2, gamma=0.5, obs=False, reward=True, clip=10.0)
    first = norm.scale_rewards(np.array([2.0, 4.0], np.float32), np.array([False, True]))
    # returns [2, 4]: count 1e-4 + 2, mean ~3, var ~1 -> rewards / sqrt(var + 1e-8)
    var = norm.ret_rms.var
    np.testing.assert_allclose(first, np.array([2.0, 4.0]) / np.sqrt(var + 1e-8), rtol=1e-6)
    assert norm.returns.tolist() == [2.0, 0.0]  # the second episode ended: its return resets
    norm.scale_rewards(np.array([1.0, 1.0], np.float32), np.array([False, False]))
    assert norm.returns.tolist() == [2.0, 1.0]  # 0.5 * 2 + 1, 0.5 * 0 + 1


class _Shifted(gym.ObservationWrapper):
    """Pendulum with every observation shifted by +100: raw and normalised obs differ plainly."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        low, high = env.observation_space.low + 100, env.observation_space.high + 100
        self.observation_space = gym.spaces.Box(low, high, dtype=np.float32)

    def observation(self, obs: np.ndarray) -> np.ndarray:
        return (obs + 100.0).astype(np.float32)


def test_teachers_see_raw_observations_and_the_statistics_are_saved(tmp_path) -> None:
    seen: list[np.ndarray] = []

    def teacher(obs: np.ndarray) -> np.ndarray:
        seen.append(np.asarray(obs).copy())
        return np.zeros(1, dtype=np.float32)

    env = _Shifted(gym.make("Pendulum-v1"))
    model = TLAC(
        env,
        teachers=[teacher],
        seed=0,
        normalize_obs=True,
        normalize_reward=True,
        n_steps=32,
        batch_size=32,
    )
    model.learn(1280, progress_bar=False)  # (past the audition: 1,000 solo steps)
    assert len(seen) > 10 and min(float(o.min()) for o in seen) > 90.0  # raw: shifted by 100
    mean = model.nets.normalizer.obs_rms.mean
    assert mean.min() > 90.0  # the statistics are of the raw observations
    obs = np.stack([env.observation_space.sample() for _ in range(5)])
    x = model.nets.normalizer.obs_numpy(obs.astype(np.float32))
    assert np.abs(x).max() <= 10.0 and np.abs(x.mean()) < np.abs(obs.mean())
    before = model.predict(obs, deterministic=True)[0]
    loaded = TLAC.load(model.save(tmp_path / "m"))
    np.testing.assert_array_equal(loaded.predict(obs, deterministic=True)[0], before)
    np.testing.assert_array_equal(loaded.nets.normalizer.obs_rms.mean, mean)


def test_a_model_saved_normalised_is_not_loaded_raw(tmp_path) -> None:
    """A Pendulum model saved when ``auto`` normalised it (before 2026-11-29) holds statistics
    that ``auto`` no longer builds: one error with the way to load it, not a student reading
    raw observations with networks trained on normalised ones."""
    model = TLAC(gym.make("Pendulum-v1"), teachers=[], seed=0, normalize_obs=True)
    path = model.save(tmp_path / "m")
    with pytest.raises(ConfigError, match=r"custom_objects=\{'normalize_obs': True\}"):
        TLAC.load(path, custom_objects={"normalize_obs": "auto"})
    loaded = TLAC.load(path, custom_objects={"normalize_obs": True})
    assert loaded.nets.normalizer is not None


def test_normalize_obs_refuses_one_hot_categories() -> None:
    with pytest.raises(ConfigError, match="normalize_obs needs raw observations"):
        TLAC("doorkey", normalize_obs=True, obs_encoding="onehot")
    TLAC("doorkey", normalize_obs=True, obs_encoding="raw")  # raw indices may be normalised


def test_normalize_obs_auto_normalises_raw_observations_only() -> None:
    """``auto`` (presets/default.yaml): on for a Box read raw unless its bounds declare every
    coordinate on a unit scale, off (not refused) where the observations are one-hot encoded,
    so the same preset serves every space."""
    box = TLAC(gym.make("MountainCar-v0"), teachers=[lambda obs: 0], normalize_obs="auto")
    assert box.nets.normalizer is not None and box.nets.normalizer.normalize_obs
    grid = TLAC(gym.make("FrozenLake-v1"), teachers=[lambda obs: 0], normalize_obs="auto")
    assert grid.nets.normalizer is None
    with pytest.raises(ConfigError, match="normalize_obs needs raw observations"):
        TLAC(gym.make("FrozenLake-v1"), teachers=[lambda obs: 0], normalize_obs=True)
    # a Box whose bounds declare unit-scale coordinates stays raw (Pendulum: +-1, +-1, +-8);
    # true still normalises it
    pendulum = TLAC(gym.make("Pendulum-v1"), teachers=[], normalize_obs="auto")
    assert pendulum.nets.normalizer is None
    forced = TLAC(gym.make("Pendulum-v1"), teachers=[], normalize_obs=True)
    assert forced.nets.normalizer is not None and forced.nets.normalizer.normalize_obs
    # NumPy's true is true, not silently off
    on = TLAC(gym.make("MountainCar-v0"), teachers=[lambda obs: 0], normalize_obs=np.True_)
    assert on.nets.normalizer is not None and on.nets.normalizer.normalize_obs
    with pytest.raises(ConfigError, match="normalize_obs needs raw observations"):
        TLAC(gym.make("FrozenLake-v1"), teachers=[lambda obs: 0], normalize_obs=np.True_)


def test_a2c_normalize_wraps_vecnormalize_and_predicts_from_saved_statistics(tmp_path) -> None:
    from stable_baselines3.common.env_util import make_vec_env

    from tlac.baselines.sb3_baselines import A2CBaseline

    env = make_vec_env(lambda: _Shifted(gym.make("Pendulum-v1")), n_envs=2, seed=0)
    model = A2CBaseline(env, seed=0, normalize=True, n_steps=8)
    model.learn(400)
    venv = model.model.get_vec_normalize_env()
    assert venv is not None and venv.obs_rms.mean.min() > 90.0  # raw statistics
    obs = np.stack([env.observation_space.sample() for _ in range(4)])
    expected = model.model.predict(venv.normalize_obs(obs), deterministic=True)[0]
    np.testing.assert_array_equal(model.predict(obs, deterministic=True)[0], expected)
    loaded = A2CBaseline.load(model.save(tmp_path / "a2c"), trust_pickle=True)
    np.testing.assert_allclose(loaded.predict(obs, deterministic=True)[0], expected, rtol=1e-6)
    with pytest.raises(ConfigError, match="normalize must be true or false"):
        A2CBaseline.check_hyperparameters({"normalize": "yes"})


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_one_row_at_a_time_adds_to_the_statistics_bit_for_bit_as_sb3(dtype: type) -> None:
    # the single-row path (moments passed as they are) against SB3's own update, over a stream
    # of rows of very different scales, and a batch of two rows through the general path
    rng = np.random.default_rng(0)
    ours, sb3 = SB3RunningMeanStd(shape=(3,)), SB3RunningMeanStd(shape=(3,))
    for t in range(500):
        batch = (rng.standard_normal((1 if t % 50 else 2, 3)) * [1e-3, 1.0, 1e3]).astype(dtype)
        add_to_running_stats(ours, batch)
        sb3.update(batch)
    assert ours.count == sb3.count
    assert ours.mean.tobytes() == sb3.mean.tobytes()
    assert ours.var.tobytes() == sb3.var.tobytes()


@pytest.mark.parametrize(
    ("low", "high", "raw"),
    [
        ([-1.0, -1.0, -8.0], [1.0, 1.0, 8.0], True),  # Pendulum: half-ranges 1, 1, 8
        ([-10.0], [10.0], True),  # the upper end of the unit scale is in it
        ([0.0], [1.0], False),  # half-range 0.5: narrower than the unit scale
        ([-1.2, -0.07], [0.6, 0.07], False),  # MountainCar's velocity
        ([-1.0, -28.27], [1.0, 28.27], False),  # Acrobot's second joint speed
        ([-4.8, -np.inf], [4.8, np.inf], False),  # CartPole's undeclared velocity
    ],
)
def test_declares_unit_scale_reads_every_coordinates_half_range(low, high, raw) -> None:
    from tlac.algorithms.normalization import declares_unit_scale

    space = gym.spaces.Box(np.array(low, dtype=np.float32), np.array(high, dtype=np.float32))
    assert declares_unit_scale(space) is raw
