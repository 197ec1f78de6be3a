"""Generic teacher wrappers: statistics, bounds, partial advice, bad parameters."""

from __future__ import annotations

import doctest

import gymnasium as gym
import numpy as np
import pytest

import tlac.teachers.wrappers
from tlac.domains.doorkey.env import make_doorkey_env, region_of
from tlac.domains.doorkey.planner import DoorKeyOptimalTeacher
from tlac.errors import ConfigError, TeacherError
from tlac.evaluation import measure_teacher
from tlac.teachers import (
    GaussianNoiseTeacher,
    MixedRandomTeacher,
    PartialTeacher,
    RandomTeacher,
    as_teacher,
    check_actions,
)
from tlac.teachers.base import FunctionTeacher

N_SAMPLES = 6000
SIX = gym.spaces.Discrete(6)
BOX4 = gym.spaces.Box(-1.0, 1.0, (4,), dtype=np.float32)


def doorkey_states(n_layouts: int = 20) -> np.ndarray:
    """A few hundred DoorKey observations in both rooms: whole episodes of a teacher that
    follows the optimal one 70% of the time."""
    env = make_doorkey_env()
    walker = MixedRandomTeacher(DoorKeyOptimalTeacher(), 0.7, SIX, seed=123)
    out = []
    for seed in range(n_layouts):
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            out.append(obs)
            obs, _, terminated, truncated, _ = env.step(int(walker.predict(obs[None])[0]))
            done = terminated or truncated
    return np.stack(out)


@pytest.fixture(scope="module")
def states() -> np.ndarray:
    return doorkey_states()


def tiled(states: np.ndarray, n: int = N_SAMPLES) -> np.ndarray:
    return states[np.arange(n) % len(states)]


@pytest.mark.parametrize(("p", "name"), [(0.8, "good"), (0.2, "noisy")])
def test_mixed_teacher_agrees_with_base_at_the_expected_rate(states, p, name):
    obs = tiled(states)
    optimal = DoorKeyOptimalTeacher().predict(obs)
    mixed = MixedRandomTeacher(DoorKeyOptimalTeacher(), p, SIX, seed=1, name=name)
    actions = mixed.predict(obs)
    agreement = float((actions == optimal).mean())
    # The random branch draws the base action 1/|A| of the time too.
    expected = p + (1 - p) / 6
    assert abs(agreement - expected) < 0.025, (agreement, expected)
    # Disagreements are uniformly spread over the 5 other actions: each about 1/5.
    wrong = actions[actions != optimal]
    offsets = (wrong - optimal[actions != optimal]) % 6
    freq = np.bincount(offsets, minlength=6)[1:] / len(wrong)
    assert np.all(np.abs(freq - 0.2) < 0.05), freq
    assert mixed.name == name
    check_actions(name, actions, SIX, len(obs))


def test_mixed_teacher_extremes_and_reproducibility(states):
    obs = tiled(states, 600)
    optimal = DoorKeyOptimalTeacher().predict(obs)
    always = MixedRandomTeacher(DoorKeyOptimalTeacher(), 1.0, SIX, seed=0)
    np.testing.assert_array_equal(always.predict(obs), optimal)
    never = MixedRandomTeacher(DoorKeyOptimalTeacher(), 0.0, SIX, seed=0)
    assert abs(float((never.predict(obs) == optimal).mean()) - 1 / 6) < 0.06
    a = MixedRandomTeacher(DoorKeyOptimalTeacher(), 0.5, SIX, seed=7).predict(obs)
    b = MixedRandomTeacher(DoorKeyOptimalTeacher(), 0.5, SIX, seed=7).predict(obs)
    c = MixedRandomTeacher(DoorKeyOptimalTeacher(), 0.5, SIX, seed=8).predict(obs)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_mixed_teacher_on_a_box_uses_the_base_or_a_uniform_action():
    base = FunctionTeacher(lambda o: np.full(4, 0.5, dtype=np.float32), BOX4, "half")
    t = MixedRandomTeacher(base, 0.8, BOX4, seed=3)
    a = t.predict(np.zeros((N_SAMPLES, 2)))
    from_base = np.all(a == 0.5, axis=1)
    assert abs(from_base.mean() - 0.8) < 0.025
    assert a.shape == (N_SAMPLES, 4) and np.abs(a).max() <= 1.0
    assert t.name == "half-mixed0.8"


def test_random_teacher_is_uniform_discrete():
    t = RandomTeacher(SIX, seed=0)
    a = t.predict(np.zeros((N_SAMPLES, 147)))
    assert a.dtype == np.int64 and a.shape == (N_SAMPLES,)
    freq = np.bincount(a, minlength=6) / N_SAMPLES
    assert np.all(np.abs(freq - 1 / 6) < 0.02), freq
    assert t.name == "random"


def test_random_teacher_is_uniform_box():
    box = gym.spaces.Box(np.array([-1.0, 0.0], np.float32), np.array([1.0, 4.0], np.float32))
    a = RandomTeacher(box, seed=0).predict(np.zeros((N_SAMPLES, 3)))
    assert a.shape == (N_SAMPLES, 2) and a.dtype == np.float32
    assert np.all(a >= box.low) and np.all(a <= box.high)
    np.testing.assert_allclose(a.mean(axis=0), [0.0, 2.0], atol=0.05)
    # Uniform on [low, high] has variance (high - low)^2 / 12.
    np.testing.assert_allclose(a.var(axis=0), [4 / 12, 16 / 12], rtol=0.08)


def test_gaussian_noise_adds_sigma_only_to_the_chosen_dims():
    base = FunctionTeacher(lambda o: np.array([0.0, 0.0, 0.0, -1.0]), BOX4, "zero")
    t = GaussianNoiseTeacher(base, 0.1, BOX4, seed=0, dims=3)
    a = t.predict(np.zeros((N_SAMPLES, 5)))
    # Noise of 0.1 around 0 never needs rescaling: the xyz part is the noise itself.
    np.testing.assert_allclose(a[:, :3].std(axis=0), 0.1, rtol=0.06)
    np.testing.assert_allclose(a[:, :3].mean(axis=0), 0.0, atol=0.01)
    assert np.all(a[:, 3] == -1.0)
    assert t.name == "zero-gauss0.1"


def test_gaussian_noise_stays_in_the_box_and_rescale_keeps_the_direction():
    base_action = np.array([1.0, -0.5, 0.9, 1.0], dtype=np.float32)
    base = FunctionTeacher(lambda o: base_action, BOX4, "edge")
    rescaled = GaussianNoiseTeacher(base, 0.3, BOX4, seed=0, dims=3).predict(np.zeros((2000, 1)))
    clipped = GaussianNoiseTeacher(base, 0.3, BOX4, seed=0, dims=3, rescale=False).predict(
        np.zeros((2000, 1))
    )
    for a in (rescaled, clipped):
        assert np.all(np.abs(a) <= 1.0)
        assert np.all(a[:, 3] == 1.0)
    # Same seed, same noise: rescaling divides the noised xyz by max(1, max|xyz|), so the
    # rescaled vector is parallel to the unclipped one, and its largest entry is exactly 1
    # where the noise pushed a component out of the box.
    xyz = rescaled[:, :3]
    out = np.abs(clipped[:, :3]).max(axis=1) >= 1.0 - 1e-6
    assert out.mean() > 0.3
    np.testing.assert_allclose(np.abs(xyz[out]).max(axis=1), 1.0, atol=1e-6)
    # Rows that needed no rescaling are identical in both modes.
    inside = np.abs(xyz).max(axis=1) < 1.0 - 1e-6
    np.testing.assert_allclose(xyz[inside], clipped[inside, :3], atol=1e-6)
    # Rescaling shrinks whole rows: the in-box components of a rescaled row differ from the
    # clipped ones (which keep them unchanged).
    assert np.any(np.abs(xyz[out] - clipped[out, :3]) > 1e-3)


def test_partial_teacher_follows_base_inside_and_is_random_outside(states):
    obs = tiled(states)
    optimal = DoorKeyOptimalTeacher().predict(obs)
    regions = region_of(obs)
    assert 0 < regions.mean() < 1, "the fixture needs states in both rooms"
    left = PartialTeacher(DoorKeyOptimalTeacher(), region_of, [0], SIX, seed=0, name="L")
    np.testing.assert_array_equal(left.applies(obs), regions == 0)
    actions = left.predict(obs)
    inside = regions == 0
    np.testing.assert_array_equal(actions[inside], optimal[inside])
    outside_freq = np.bincount(actions[~inside], minlength=6) / (~inside).sum()
    assert np.all(np.abs(outside_freq - 1 / 6) < 0.05), outside_freq
    assert abs(float((actions[~inside] == optimal[~inside]).mean()) - 1 / 6) < 0.05


def test_partial_teacher_generic_regions():
    space = gym.spaces.Discrete(3)
    t = PartialTeacher(lambda o: 2, lambda b: b[:, 0].astype(int), {1, 2}, space, seed=0)
    obs = np.array([[0], [1], [2], [3]] * 500, dtype=float)
    a = t.predict(obs)
    assert t.applies(obs[:4]).tolist() == [False, True, True, False]
    assert np.all(a[np.isin(obs[:, 0], [1, 2])] == 2)
    outside = a[np.isin(obs[:, 0], [0, 3])]
    assert set(np.unique(outside).tolist()) == {0, 1, 2}
    assert t.name == "<lambda>-in1,2"


@pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan")])
def test_bad_probability_raises_config_error_naming_the_value(bad):
    with pytest.raises(ConfigError, match=rf"p_teacher .*\[0, 1\].*{bad}"):
        MixedRandomTeacher(lambda o: 0, bad, SIX, seed=0)


def test_bad_wrapper_parameters_raise_config_error():
    base = lambda o: np.zeros(4)  # noqa: E731
    with pytest.raises(ConfigError, match=r"sigma .* -0.5"):
        GaussianNoiseTeacher(base, -0.5, BOX4, seed=0)
    with pytest.raises(ConfigError, match=r"dims must be in \[1, 4\].*got 5"):
        GaussianNoiseTeacher(base, 0.1, BOX4, seed=0, dims=5)
    with pytest.raises(ConfigError, match="1-D Box"):
        GaussianNoiseTeacher(base, 0.1, SIX, seed=0)
    wide = gym.spaces.Box(-2.0, 2.0, (4,), dtype=np.float32)
    with pytest.raises(ConfigError, match="rescale=True needs"):
        GaussianNoiseTeacher(base, 0.1, wide, seed=0)
    GaussianNoiseTeacher(base, 0.1, wide, seed=0, rescale=False)  # clipping is fine
    unbounded = gym.spaces.Box(-np.inf, np.inf, (2,), dtype=np.float32)
    with pytest.raises(ConfigError, match="bounded action box"):
        RandomTeacher(unbounded, seed=0)
    with pytest.raises(ConfigError, match="inside_regions is empty"):
        PartialTeacher(base, lambda b: np.zeros(len(b)), [], SIX, seed=0)
    with pytest.raises(ConfigError, match="unsupported action space"):
        RandomTeacher(gym.spaces.MultiBinary(3), seed=0)


def test_as_teacher_accepts_a_function_and_a_batched_object(states):
    fn = as_teacher(lambda obs: int(obs[0] > 0), SIX, name="sign")
    assert fn.name == "sign"
    assert fn.predict(np.array([[1.0], [-1.0]])).tolist() == [1, 0]
    optimal = DoorKeyOptimalTeacher()
    assert as_teacher(optimal, SIX) is optimal
    renamed = as_teacher(optimal, SIX, name="expert")
    assert renamed.name == "expert"
    np.testing.assert_array_equal(renamed.predict(states), optimal.predict(states))
    # Wrappers accept plain functions as the base teacher.
    t = MixedRandomTeacher(lambda obs: 5, 1.0, SIX, seed=0)
    assert t.predict(states[:3]).tolist() == [5, 5, 5]


def test_check_actions_rejects_what_a_broken_teacher_returns():
    with pytest.raises(TeacherError, match="outside"):
        check_actions("broken", np.array([6]), SIX, 1)


def test_measure_teacher_on_doorkey_is_reproducible():
    a = measure_teacher("doorkey", "good", episodes=12, seed=5, n_envs=4)
    b = measure_teacher("doorkey", "good", episodes=12, seed=5, n_envs=4)
    assert a == b and a["episodes"] == 12 and len(a["returns"]) == 12
    opt = measure_teacher("doorkey", DoorKeyOptimalTeacher(), episodes=12, seed=5, n_envs=3)
    assert opt["success_rate"] == 1.0 and opt["mean"] > 0.9
    # The optimal teacher is deterministic: the batch size does not change its episodes.
    assert measure_teacher("doorkey", "optimal", 12, seed=5, n_envs=1)["returns"] == opt["returns"]
    rnd = measure_teacher("doorkey", "random", episodes=4, seed=0, n_envs=4)
    assert rnd["mean"] < opt["mean"]
    never = measure_teacher("doorkey", lambda o: 0, 2, seed=0, success_fn=lambda r, i: True)
    assert never["success_rate"] == 1.0 and never["mean"] == 0.0
    with pytest.raises(ConfigError, match="episodes must be >= 1; got 0"):
        measure_teacher("doorkey", "optimal", 0, seed=0)
    with pytest.raises(ConfigError, match="unknown teacher for doorkey 'expert'"):
        measure_teacher("doorkey", "expert", 1, seed=0)


@pytest.mark.parametrize("module", [tlac.teachers.wrappers])
def test_doctests(module):
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0
