"""Running observation and reward normalisation, as stable-baselines3's ``VecNormalize`` does
it, kept INSIDE TL-AC so that teachers still receive the raw observations they were written or
trained for (issue 9's hopper question; docs/reproduction.md).

* Observations: ``clip((obs - mean) / sqrt(var + eps), -clip, clip)`` with the running mean and
  variance of every observation seen while training (Chan et al.'s parallel update).
* Rewards: divided by the running standard deviation of the discounted return
  ``R_t = gamma R_{t-1} + r_t`` (reset at episode ends), then clipped; never centred.

>>> rms = RunningMeanStd(shape=(1,))
>>> rms.update(np.array([[1.0], [3.0]]))
>>> round(float(rms.mean[0]), 4), round(float(rms.var[0]), 4)   # the count starts at 1e-4
(1.9999, 1.0002)
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

EPSILON = 1e-8


class RunningMeanStd:
    """Mean and variance of a stream of batches (``VecNormalize``'s statistics)."""

    def __init__(self, shape: tuple[int, ...], epsilon: float = 1e-4):
        self.mean = np.zeros(shape, dtype=np.float64)
        self.var = np.ones(shape, dtype=np.float64)
        self.count = float(epsilon)

    def update(self, batch: np.ndarray) -> None:
        batch = np.asarray(batch, dtype=np.float64)
        self.mean, self.var, self.count = combine_moments(
            self.mean, self.var, self.count, batch.mean(axis=0), batch.var(axis=0), len(batch)
        )

    def state(self) -> dict[str, Any]:
        """Tensors and a float: a checkpoint of them loads with ``weights_only=True``."""
        return {
            "mean": torch.from_numpy(np.array(self.mean)),
            "var": torch.from_numpy(np.array(self.var)),
            "count": self.count,
        }

    def set_state(self, state: dict[str, Any]) -> None:
        self.mean = np.asarray(state["mean"], dtype=np.float64).copy()
        self.var = np.asarray(state["var"], dtype=np.float64).copy()
        self.count = float(state["count"])


def combine_moments(
    mean: np.ndarray,
    var: np.ndarray,
    count: float,
    batch_mean: np.ndarray,
    batch_var: np.ndarray,
    batch_count: int,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Mean, variance and count of two samples pooled (Chan et al. 1979).

    >>> m, v, n = combine_moments(np.array(0.0), np.array(1.0), 2, np.array(2.0), np.array(1.0), 2)
    >>> float(m), float(v), n     # samples -1, 1, 1, 3
    (1.0, 2.0, 4)
    """
    delta = batch_mean - mean
    total = count + batch_count
    new_mean = mean + delta * batch_count / total
    m2 = var * count + batch_var * batch_count + delta**2 * count * batch_count / total
    return new_mean, m2 / total, total


class Normalizer:
    """Observation and/or reward normalisation for ``n_envs`` parallel environments."""

    def __init__(
        self, obs_dim: int, n_envs: int, gamma: float, obs: bool, reward: bool, clip: float
    ):
        self.normalize_obs, self.normalize_reward, self.clip = obs, reward, float(clip)
        self.gamma = float(gamma)
        self.obs_rms = RunningMeanStd((obs_dim,))
        self.ret_rms = RunningMeanStd(())
        self.returns = np.zeros(n_envs, dtype=np.float64)
        self._refresh()

    def _refresh(self) -> None:
        self._mean = self.obs_rms.mean.astype(np.float32)
        self._std = np.sqrt(self.obs_rms.var + EPSILON).astype(np.float32)
        self._mean_t, self._std_t = torch.from_numpy(self._mean), torch.from_numpy(self._std)

    def update_obs(self, obs: np.ndarray) -> None:
        """Add a batch of raw observations to the statistics (while training only)."""
        if self.normalize_obs:
            self.obs_rms.update(obs)
            self._refresh()

    def obs_numpy(self, obs: np.ndarray) -> np.ndarray:
        if not self.normalize_obs:
            return obs
        return np.clip((obs - self._mean) / self._std, -self.clip, self.clip).astype(np.float32)

    def obs_torch(self, obs: torch.Tensor) -> torch.Tensor:
        if not self.normalize_obs:
            return obs
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
            "obs_rms": self.obs_rms.state(),
            "ret_rms": self.ret_rms.state(),
            "returns": torch.from_numpy(self.returns.copy()),
        }

    def set_state(self, state: dict[str, Any]) -> None:
        self.obs_rms.set_state(state["obs_rms"])
        self.ret_rms.set_state(state["ret_rms"])
        self.returns = np.asarray(state["returns"], dtype=np.float64).copy()
        self._refresh()
