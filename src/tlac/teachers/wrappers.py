"""Batched teacher wrappers: the paper's good, noisy, random and partial teachers.

Section 4 ("Teacher Set Details") and appendices A.1.1, A.2.1, A.3.1 build every teacher set
from one near-optimal policy: *good* and *noisy* teachers follow it with probability 0.8 and
0.2 and act randomly otherwise (DoorKey, Hopper), or add Gaussian action noise of scale 0.01
and 0.1 (Pick & Place); a *random* teacher acts uniformly; a *partial* teacher follows it in
part of the state space only (Teacher L / R, Pick / Place).

Every wrapper is batched (``predict(obs_batch)`` over environments), has a ``name``, and
owns a :class:`numpy.random.Generator` seeded by its ``seed`` argument, so a teacher set is
reproducible. Bad parameters raise :class:`tlac.errors.ConfigError` naming the value.

>>> import gymnasium as gym
>>> space = gym.spaces.Discrete(4)
>>> always_two = lambda obs: 2
>>> good = MixedRandomTeacher(always_two, 0.8, space, seed=0, name="good")
>>> actions = good.predict(np.zeros((10_000, 3)))
>>> round(float((actions == 2).mean()), 2)  # 0.8 + 0.2 / 4
0.85
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import gymnasium as gym
import numpy as np

from tlac.errors import ConfigError
from tlac.teachers.base import Teacher, advice_actions, advice_probabilities, as_teacher


def _check_probability(name: str, value: float) -> float:
    value = float(value)
    if not 0.0 <= value <= 1.0:  # also rejects NaN
        raise ConfigError(f"{name} must be a probability in [0, 1]; got {value}")
    return value


def _check_supported(space: gym.Space) -> gym.Space:
    if isinstance(space, gym.spaces.Discrete):
        return space
    if isinstance(space, gym.spaces.Box):
        if not (np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))):
            raise ConfigError(
                f"a random teacher needs a bounded action box; got {space} (infinite bounds)"
            )
        return space
    raise ConfigError(f"unsupported action space {space}; expected Discrete or Box")


def sample_uniform(space: gym.Space, rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` uniformly random actions of ``space``: ``(n,)`` int64 for ``Discrete``,
    ``(n, *shape)`` float32 for a bounded ``Box``.

    >>> sample_uniform(gym.spaces.Discrete(3, start=1), np.random.default_rng(0), 4).tolist()
    [3, 2, 2, 1]
    """
    if isinstance(space, gym.spaces.Discrete):
        start = int(space.start)
        return rng.integers(start, start + int(space.n), size=n, dtype=np.int64)
    if isinstance(space, gym.spaces.Box):
        low = space.low.astype(np.float64)
        high = space.high.astype(np.float64)
        return rng.uniform(low, high, size=(n, *space.shape)).astype(np.float32)
    raise ConfigError(f"unsupported action space {space}; expected Discrete or Box")


def _as_batch(obs: np.ndarray) -> np.ndarray:
    return np.asarray(obs)


def silent_actions(space: gym.Space, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(actions, information)`` of advice that says nothing in ``n`` rows of a Box: the box's
    centre (never copied: its information is 0)."""
    if not isinstance(space, gym.spaces.Box):
        raise ConfigError(f"informative actions need a Box action space; got {space}")
    centre = ((space.low.astype(np.float64) + space.high.astype(np.float64)) / 2).astype(np.float32)
    return np.repeat(centre[None], n, axis=0), np.zeros(n)


def uniform_probabilities(space: gym.Space, n: int) -> np.ndarray:
    """``(n, space.n)``: the uniform distribution over a Discrete space's actions, per row."""
    if not isinstance(space, gym.spaces.Discrete):
        raise ConfigError(f"action probabilities need a Discrete action space; got {space}")
    return np.full((n, int(space.n)), 1.0 / int(space.n))


class RandomTeacher:
    """Uniformly random advice over the action space (paper: the *random teacher*).

    >>> t = RandomTeacher(gym.spaces.Box(-1.0, 1.0, (2,)), seed=0)
    >>> a = t.predict(np.zeros((5, 3)))
    >>> a.shape, bool(np.abs(a).max() <= 1.0)
    ((5, 2), True)
    """

    def __init__(self, action_space: gym.Space, seed: int, name: str = "random"):
        self.action_space = _check_supported(action_space)
        self.name = name
        self.rng = np.random.default_rng(seed)

    def predict(self, obs: np.ndarray) -> np.ndarray:
        return sample_uniform(self.action_space, self.rng, len(_as_batch(obs)))

    def action_probabilities(self, obs: np.ndarray) -> np.ndarray:
        """Discrete: uniform in every row (draws nothing)."""
        return uniform_probabilities(self.action_space, len(_as_batch(obs)))

    def informative_actions(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Box: information 0 in every row (draws nothing)."""
        return silent_actions(self.action_space, len(_as_batch(obs)))


class MixedRandomTeacher:
    """Per row, the base teacher's action with probability ``p_teacher``, a uniformly random
    action otherwise (appendix A.1.1 / A.2.1: good = 0.8, noisy = 0.2).

    The random action may coincide with the base one, so a Discrete teacher agrees with its
    base with probability ``p_teacher + (1 - p_teacher) / n_actions``. The base is queried
    only for the rows that follow it.
    """

    def __init__(
        self,
        base: Any,
        p_teacher: float,
        action_space: gym.Space,
        seed: int,
        name: str | None = None,
    ):
        self.p_teacher = _check_probability("p_teacher", p_teacher)
        self.action_space = _check_supported(action_space)
        self.base: Teacher = as_teacher(base, action_space)
        self.name = name or f"{self.base.name}-mixed{self.p_teacher:g}"
        self.rng = np.random.default_rng(seed)

    def predict(self, obs: np.ndarray) -> np.ndarray:
        obs = _as_batch(obs)
        n = len(obs)
        follow = self.rng.random(n) < self.p_teacher
        actions = sample_uniform(self.action_space, self.rng, n)
        if follow.any():
            actions[follow] = np.asarray(self.base.predict(obs[follow]), dtype=actions.dtype)
        return actions

    def action_probabilities(self, obs: np.ndarray) -> np.ndarray:
        """Discrete: ``p_teacher`` times the base's distribution plus ``1 - p_teacher`` times
        the uniform one (draws nothing from this teacher's generator).

        >>> t = MixedRandomTeacher(lambda o: 0, 0.8, gym.spaces.Discrete(4), seed=0)
        >>> t.action_probabilities(np.zeros((1, 2))).round(2).tolist()
        [[0.85, 0.05, 0.05, 0.05]]
        """
        obs = _as_batch(obs)
        base = advice_probabilities(self.base, obs, self.action_space)
        uniform = uniform_probabilities(self.action_space, len(obs))
        return self.p_teacher * base + (1.0 - self.p_teacher) * uniform

    def informative_actions(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Box: the base's action, with information ``p_teacher`` times the base's (draws
        nothing from this teacher's generator).

        >>> box = gym.spaces.Box(-1.0, 1.0, (1,))
        >>> t = MixedRandomTeacher(lambda o: np.array([0.5]), 0.8, box, seed=0)
        >>> actions, information = t.informative_actions(np.zeros((1, 2)))
        >>> actions.tolist(), information.tolist()
        ([[0.5]], [0.8])
        """
        actions, information = advice_actions(self.base, _as_batch(obs), self.action_space)
        return actions, self.p_teacher * information


class GaussianNoiseTeacher:
    """The base action plus Gaussian noise (appendix A.3.1: sigma 0.01 = good, 0.1 = noisy).

    ``N(0, sigma)`` noise is added to the first ``dims`` action components (all when
    ``dims`` is None; Pick & Place uses ``dims=3``, the xyz displacement, and keeps the
    gripper command). Then, with ``rescale=True`` (AC-Teach's convention, which the paper
    reuses), the noised part is divided by ``max(1, max |component|)`` per row, so the
    direction is kept and no component leaves ``[-1, 1]``; this needs the box to be
    ``[-1, 1]`` on those components. With ``rescale=False`` the result is clipped to the box.

    >>> base = lambda obs: np.array([1.0, 0.0, -1.0, 1.0], dtype=np.float32)
    >>> box = gym.spaces.Box(-1.0, 1.0, (4,))
    >>> t = GaussianNoiseTeacher(base, 0.5, box, seed=0, dims=3)
    >>> a = t.predict(np.zeros((1000, 2)))
    >>> bool(np.abs(a).max() <= 1.0), bool((a[:, 3] == 1.0).all())
    (True, True)
    """

    def __init__(
        self,
        base: Any,
        sigma: float,
        action_space: gym.Space,
        seed: int,
        dims: int | None = None,
        rescale: bool = True,
        name: str | None = None,
    ):
        if not isinstance(action_space, gym.spaces.Box) or len(action_space.shape) != 1:
            raise ConfigError(
                f"GaussianNoiseTeacher needs a 1-D Box action space; got {action_space}"
            )
        sigma = float(sigma)
        if not (np.isfinite(sigma) and sigma >= 0.0):
            raise ConfigError(f"sigma must be a finite number >= 0; got {sigma}")
        act_dim = int(action_space.shape[0])
        if dims is None:
            dims = act_dim
        if not 1 <= int(dims) <= act_dim:
            raise ConfigError(f"dims must be in [1, {act_dim}] for {action_space}; got {dims}")
        dims = int(dims)
        if rescale and not (
            np.all(action_space.low[:dims] == -1.0) and np.all(action_space.high[:dims] == 1.0)
        ):
            raise ConfigError(
                "rescale=True needs the action box to be [-1, 1] on the noised components; "
                f"got low={action_space.low[:dims].tolist()}, "
                f"high={action_space.high[:dims].tolist()} (use rescale=False to clip)"
            )
        self.sigma, self.dims, self.rescale = sigma, dims, bool(rescale)
        self.action_space = action_space
        self.base: Teacher = as_teacher(base, action_space)
        self.name = name or f"{self.base.name}-gauss{sigma:g}"
        self.rng = np.random.default_rng(seed)

    def _base_actions(self, obs: np.ndarray) -> np.ndarray:
        return np.array(self.base.predict(obs), dtype=np.float64).reshape(
            len(obs), *self.action_space.shape
        )

    def _in_box(self, actions: np.ndarray) -> np.ndarray:
        return np.clip(actions, self.action_space.low, self.action_space.high).astype(np.float32)

    def predict(self, obs: np.ndarray) -> np.ndarray:
        obs = _as_batch(obs)
        actions = self._base_actions(obs)
        part = actions[:, : self.dims] + self.rng.normal(0.0, self.sigma, (len(obs), self.dims))
        if self.rescale:
            scale = np.maximum(1.0, np.abs(part).max(axis=1, keepdims=True))
            part = part / scale
        actions[:, : self.dims] = part
        # Rescaling keeps [-1, 1] up to rounding; clipping makes the box exact either way.
        return self._in_box(actions)

    def informative_actions(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The base's action before the noise, clipped to the box as ``predict`` clips, with
        information 1 whatever ``sigma`` (draws nothing)."""
        obs = _as_batch(obs)
        return self._in_box(self._base_actions(obs)), np.ones(len(obs))


class PartialTeacher:
    """Good advice in part of the state space only (section 5.2; Teacher L / R, Pick / Place).

    Where ``region_of(obs)`` is one of ``inside_regions`` the base teacher's action is
    returned, elsewhere a uniformly random action. ``region_of`` maps an observation batch
    to integer region indices (a :class:`tlac.domains.Domain`'s ``region_of``).

    >>> space = gym.spaces.Discrete(5)
    >>> left = PartialTeacher(lambda o: 4, lambda b: (b[:, 0] > 0).astype(int), [0], space, 0)
    >>> obs = np.array([[-1.0], [1.0], [-2.0]])
    >>> left.applies(obs).tolist()
    [True, False, True]
    >>> left.predict(obs)[left.applies(obs)].tolist()
    [4, 4]
    """

    def __init__(
        self,
        base: Any,
        region_of: Callable[[np.ndarray], np.ndarray],
        inside_regions: Iterable[int],
        action_space: gym.Space,
        seed: int,
        name: str | None = None,
    ):
        if not callable(region_of):
            raise ConfigError(
                f"region_of must be a function of the observation batch; got {region_of!r}"
            )
        self.inside_regions = np.asarray(sorted({int(r) for r in inside_regions}), dtype=np.int64)
        if self.inside_regions.size == 0:
            raise ConfigError("inside_regions is empty; a partial teacher must apply somewhere")
        self.region_of = region_of
        self.action_space = _check_supported(action_space)
        self.base: Teacher = as_teacher(base, action_space)
        regions = ",".join(str(r) for r in self.inside_regions)
        self.name = name or f"{self.base.name}-in{regions}"
        self.rng = np.random.default_rng(seed)

    def applies(self, obs: np.ndarray) -> np.ndarray:
        """Boolean per row: True where the base teacher's advice is given."""
        regions = np.asarray(self.region_of(_as_batch(obs)))
        return np.isin(regions, self.inside_regions)

    def predict(self, obs: np.ndarray) -> np.ndarray:
        obs = _as_batch(obs)
        inside = self.applies(obs)
        actions = sample_uniform(self.action_space, self.rng, len(obs))
        if inside.any():
            actions[inside] = np.asarray(self.base.predict(obs[inside]), dtype=actions.dtype)
        return actions

    def action_probabilities(self, obs: np.ndarray) -> np.ndarray:
        """Discrete: the base's distribution inside the regions, uniform outside them."""
        obs = _as_batch(obs)
        inside = self.applies(obs)
        probs = uniform_probabilities(self.action_space, len(obs))
        if inside.any():
            probs[inside] = advice_probabilities(self.base, obs[inside], self.action_space)
        return probs

    def informative_actions(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Box: the base's action and information inside the regions, information 0 outside
        them (draws nothing)."""
        obs = _as_batch(obs)
        inside = self.applies(obs)
        actions, information = silent_actions(self.action_space, len(obs))
        if inside.any():
            actions[inside], information[inside] = advice_actions(
                self.base, obs[inside], self.action_space
            )
        return actions, information


__all__ = [
    "GaussianNoiseTeacher",
    "MixedRandomTeacher",
    "PartialTeacher",
    "RandomTeacher",
    "sample_uniform",
    "silent_actions",
    "uniform_probabilities",
]
