"""Observation encodings for TL-AC's networks.

Many environments observe CATEGORIES written as integers: MiniGrid's cells are
``(object, colour, state)`` indices, where ``door = 4`` is not "twice" ``wall = 2``. Fed as
numbers, an MLP has to learn to undo that order; one-hot features make each category its own
input. ``onehot`` expands every dimension of an integer Box into ``high - low + 1`` indicators;
``auto`` does so when the observation space is an integer-dtype Box with small finite ranges
(and leaves float observations as they are). docs/graduation.md measures the effect.

>>> import gymnasium as gym
>>> space = gym.spaces.Box(low=0, high=np.array([2, 1]), dtype=np.uint8)
>>> enc = make_encoder("auto", space)
>>> enc.out_dim, enc.numpy(np.array([[2, 0], [0, 1]])).tolist()
(5, [[0.0, 0.0, 1.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0, 1.0]])
>>> make_encoder("auto", gym.spaces.Box(-1.0, 1.0, (3,))) is None   # floats: left raw
True
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import torch

from tlac.errors import ConfigError

ENCODINGS = ("raw", "onehot", "auto")
MAX_CATEGORIES = 64
"""Largest ``high - low + 1`` of a dimension that ``auto`` one-hot encodes."""


def categorical_sizes(space: gym.Space) -> np.ndarray | None:
    """Categories per flattened dimension of an integer-dtype Box with finite bounds of at
    most :data:`MAX_CATEGORIES` values each, else ``None``."""
    if not isinstance(space, gym.spaces.Box) or not np.issubdtype(space.dtype, np.integer):
        return None
    low, high = space.low.reshape(-1), space.high.reshape(-1)
    sizes = high.astype(np.int64) - low.astype(np.int64) + 1
    if (sizes < 1).any() or (sizes > MAX_CATEGORIES).any():
        return None
    return sizes


class OneHotEncoder:
    """Dimension ``d`` with value ``v`` -> indicator ``offsets[d] + v - low[d]``."""

    def __init__(self, low: np.ndarray, sizes: np.ndarray):
        self.low = low.astype(np.int64)
        self.offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        self.sizes = sizes
        self.out_dim = int(sizes.sum())
        self._max = (sizes - 1).astype(np.int64)
        self._low_t = torch.from_numpy(self.low)
        self._offsets_t = torch.from_numpy(self.offsets)
        self._max_t = torch.from_numpy(self._max)

    def numpy(self, x: np.ndarray) -> np.ndarray:
        # called for every acting step: in-place integer ops and one fancy assignment (half
        # the time of np.clip and np.put_along_axis on a row of DoorKey's 147 values)
        idx = np.rint(x).astype(np.int64)
        idx -= self.low
        np.maximum(idx, 0, out=idx)
        np.minimum(idx, self._max, out=idx)
        idx += self.offsets
        out = np.zeros((len(x), self.out_dim), dtype=np.float32)
        out[np.arange(len(x))[:, None], idx] = 1.0
        return out

    def torch(self, x: torch.Tensor) -> torch.Tensor:
        v = torch.round(x).long() - self._low_t
        idx = torch.minimum(v.clamp(min=0), self._max_t) + self._offsets_t
        return torch.zeros(len(x), self.out_dim).scatter_(1, idx, 1.0)


def make_encoder(encoding: str, space: gym.Space) -> OneHotEncoder | None:
    """The encoder for ``encoding`` on ``space``; ``None`` means raw observations."""
    if encoding not in ENCODINGS:
        raise ConfigError(f"obs_encoding must be one of {', '.join(ENCODINGS)}, got {encoding!r}")
    if encoding == "raw":
        return None
    sizes = categorical_sizes(space)
    if sizes is None:
        if encoding == "onehot":
            raise ConfigError(
                "obs_encoding 'onehot' needs an integer-dtype Box observation space with at most "
                f"{MAX_CATEGORIES} values per dimension, got {space}"
            )
        return None
    return OneHotEncoder(space.low.reshape(-1), sizes)
