"""Running observation and reward normalisation, as stable-baselines3's ``VecNormalize`` does
it, kept INSIDE TL-AC so that teachers still receive the raw observations they were written or
trained for (issue 9's hopper question; docs/reproduction.md).

* Observations: ``clip((obs - mean) / sqrt(var + eps), -clip, clip)`` with the running mean and
  variance of every observation seen while training (SB3's own ``RunningMeanStd``).
* Rewards: divided by the running standard deviation of the discounted return
  ``R_t = gamma R_{t-1} + r_t`` (reset at episode ends), then clipped; never centred.

>>> norm = Normalizer(1, 1, gamma=0.99, obs=True, reward=False, clip=10.0)
>>> norm.update_obs(np.array([[1.0], [3.0]]))
>>> norm.obs_numpy(np.array([[3.0]], dtype=np.float32)).round(3).tolist()   # (3 - ~2) / ~1
[[1.0]]
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from stable_baselines3.common.running_mean_std import RunningMeanStd

EPSILON = 1e-8


UNIT_SCALE = (1.0, 10.0)
"""The half-ranges (``(high - low) / 2``) a Box's declared bounds must all fall within for
``normalize_obs: auto`` to leave its observations raw: every coordinate already on the scale a
freshly initialised network reads well."""


def declares_unit_scale(space: Any) -> bool:
    """Whether a Box observation space declares every coordinate's range, each half-range within
    :data:`UNIT_SCALE`, so that ``normalize_obs: auto`` reads it raw (issue 63: running
    normalisation cost PPO on Pendulum, measured in docs/graduation.md). Unbounded coordinates
    (CartPole's velocities), narrow ones (MountainCar's +-0.07) and wide ones (Acrobot's
    +-28.3) are normalised.

    >>> from gymnasium.spaces import Box
    >>> declares_unit_scale(Box(np.array([-1, -1, -8.0]), np.array([1, 1, 8.0])))   # Pendulum
    True
    >>> declares_unit_scale(Box(np.array([-1.2, -0.07]), np.array([0.6, 0.07])))   # MountainCar
    False
    >>> declares_unit_scale(Box(-np.inf, np.inf, (4,)))
    False
    """
    low, high = np.asarray(space.low, dtype=np.float64), np.asarray(space.high, dtype=np.float64)
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
        return False
    half_range = (high - low) / 2.0
    return bool(np.all((half_range >= UNIT_SCALE[0]) & (half_range <= UNIT_SCALE[1])))


def rms_state(rms: RunningMeanStd) -> dict[str, Any]:
    """SB3 ``RunningMeanStd`` statistics as tensors and a float: a checkpoint of them loads
    with ``weights_only=True``."""
    return {
        "mean": torch.from_numpy(np.array(rms.mean)),
        "var": torch.from_numpy(np.array(rms.var)),
        "count": float(rms.count),
    }


def set_rms_state(rms: RunningMeanStd, state: dict[str, Any]) -> None:
    rms.mean = np.asarray(state["mean"], dtype=np.float64).copy()
    rms.var = np.asarray(state["var"], dtype=np.float64).copy()
    rms.count = float(state["count"])


def vec_normalize_state(vec_normalize: Any) -> dict[str, Any]:
    """A user's SB3 ``VecNormalize`` statistics as tensors and numbers, with the settings that
    its ``normalize_obs`` reads (what ``TLAC.save`` stores beside the networks; no pickle)."""
    return {
        "obs_rms": rms_state(vec_normalize.obs_rms),
        "ret_rms": rms_state(vec_normalize.ret_rms),
        "norm_obs": bool(vec_normalize.norm_obs),
        "clip_obs": float(vec_normalize.clip_obs),
        "epsilon": float(vec_normalize.epsilon),
    }


def set_vec_normalize_state(vec_normalize: Any, state: dict[str, Any]) -> None:
    """Put saved statistics (:func:`vec_normalize_state`) into a ``VecNormalize``, and the
    settings its observations were normalised with where the file holds them (as SB3's
    ``VecNormalize.load`` restores them)."""
    set_rms_state(vec_normalize.obs_rms, state["obs_rms"])
    set_rms_state(vec_normalize.ret_rms, state["ret_rms"])
    for name in ("norm_obs", "clip_obs", "epsilon"):
        if name in state:
            setattr(vec_normalize, name, state[name])


def add_to_running_stats(rms: RunningMeanStd, batch: np.ndarray) -> None:
    """``rms.update(batch)``, bit for bit. One float row (one environment's step, the usual
    case) is its own mean with variance 0, so its moments are passed as they are: NumPy's
    ``mean`` and ``var`` of a single row cost ~15 us, most of a step's statistics.

    >>> a, b = RunningMeanStd(shape=(2,)), RunningMeanStd(shape=(2,))
    >>> row = np.array([[0.1, -3.0]], dtype=np.float32)
    >>> a.update(row); add_to_running_stats(b, row)
    >>> bool((a.mean == b.mean).all() and (a.var == b.var).all() and a.count == b.count)
    True
    """
    if batch.ndim == 2 and batch.shape[0] == 1 and batch.dtype.kind == "f":
        row = batch[0]
        rms.update_from_moments(row, np.zeros_like(row), 1)
    else:
        rms.update(batch)


class Normalizer:
    """Observation and/or reward normalisation for ``n_envs`` parallel environments."""

    def __init__(
        self,
        obs_dim: int,
        n_envs: int,
        gamma: float,
        obs: bool,
        reward: bool,
        clip: float = 10.0,
    ):
        self.normalize_obs, self.normalize_reward, self.clip = obs, reward, float(clip)
        self.gamma = float(gamma)
        self.obs_rms = RunningMeanStd(shape=(obs_dim,))
        self.ret_rms = RunningMeanStd(shape=())
        self.returns = np.zeros(n_envs, dtype=np.float64)
        self._refresh()

    def _refresh(self) -> None:
        self._mean = self.obs_rms.mean.astype(np.float32)
        self._std = np.sqrt(self.obs_rms.var + EPSILON).astype(np.float32)
        # their tensors when obs_torch first needs them (collecting refreshes every step)
        self._mean_t: torch.Tensor | None = None
        self._std_t: torch.Tensor | None = None

    def update_obs(self, obs: np.ndarray) -> None:
        """Add a batch of raw observations to the statistics (while training only)."""
        if self.normalize_obs:
            add_to_running_stats(self.obs_rms, obs)
            self._refresh()

    def obs_numpy(self, obs: np.ndarray) -> np.ndarray:
        if not self.normalize_obs:
            return obs
        return np.clip((obs - self._mean) / self._std, -self.clip, self.clip).astype(np.float32)

    def obs_torch(self, obs: torch.Tensor) -> torch.Tensor:
        if not self.normalize_obs:
            return obs
        if self._mean_t is None or self._std_t is None:
            self._mean_t, self._std_t = torch.from_numpy(self._mean), torch.from_numpy(self._std)
        return torch.clamp((obs - self._mean_t) / self._std_t, -self.clip, self.clip)

    def scale_rewards(self, rewards: np.ndarray, dones: np.ndarray) -> np.ndarray:
        """The training rewards of one step of every environment: divided by the running std
        of the discounted return (updated with this step's returns), clipped."""
        if not self.normalize_reward:
            return rewards
        self.returns = self.returns * self.gamma + rewards
        self.ret_rms.update(self.returns)
        scaled = np.clip(rewards / np.sqrt(self.ret_rms.var + EPSILON), -self.clip, self.clip)
        self.returns[np.asarray(dones, dtype=bool)] = 0.0
        return scaled.astype(np.float32)

    def state(self) -> dict[str, Any]:
        return {
            "obs_rms": rms_state(self.obs_rms),
            "ret_rms": rms_state(self.ret_rms),
            "returns": torch.from_numpy(self.returns.copy()),
        }

    def set_state(self, state: dict[str, Any]) -> None:
        set_rms_state(self.obs_rms, state["obs_rms"])
        set_rms_state(self.ret_rms, state["ret_rms"])
        self.returns = np.asarray(state["returns"], dtype=np.float64).copy()
        self._refresh()
