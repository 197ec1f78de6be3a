"""MiniGrid's egocentric 7x7 view, computed from tlac's fully observed DoorKey grid.

MiniGrid's default DoorKey observation is the agent's partial view: the 7x7 cells in front of
it, rotated so that it looks "up", with cells hidden behind walls and closed doors encoded as
``unseen`` (0, 0, 0), and the agent's own cell showing what it carries. The paper's DoorKey
teacher was a stable-baselines3 PPO agent (appendix A.1.1); MiniGrid's default observation is
this view, also 147 values. :func:`partial_view` derives it from the full grid, so that

* the PPO teacher trained on the partial view can advise a student that sees the full grid
  (it converts each observation before acting), and
* the ``doorkey-partial`` domain offers the partial view to the student itself.

It reproduces ``MiniGridEnv.gen_obs()["image"]`` exactly (tests/test_doorkey_view.py
compares them on random states): ``get_view_exts``, ``Grid.slice`` (cells outside the grid
are walls), ``rotate_left`` ``direction + 1`` times, ``Grid.process_vis`` and ``Grid.encode``.
The carried object is not in the full grid; in DoorKey the only object the agent can carry
is the key, which is carried exactly when no key cell is on the grid.

>>> from tlac.domains.doorkey.env import make_doorkey_env
>>> obs, _ = make_doorkey_env().reset(seed=0)
>>> partial_view(obs[None]).shape
(1, 147)
"""

from __future__ import annotations

import functools

import numpy as np
from minigrid.core.constants import COLOR_TO_IDX, OBJECT_TO_IDX, STATE_TO_IDX

VIEW = 7
"""MiniGrid's ``agent_view_size``."""

_AGENT = OBJECT_TO_IDX["agent"]
_WALL = (OBJECT_TO_IDX["wall"], COLOR_TO_IDX["grey"], 0)
_EMPTY = (OBJECT_TO_IDX["empty"], 0, 0)
_DOOR, _KEY = OBJECT_TO_IDX["door"], OBJECT_TO_IDX["key"]
_CARRIED_KEY = (_KEY, COLOR_TO_IDX["yellow"], 0)  # DoorKey's key is always yellow
_DOOR_OPEN = STATE_TO_IDX["open"]


def _blocks_sight(cell: np.ndarray) -> bool:
    """MiniGrid's ``not see_behind()``: walls, and doors that are not open."""
    return bool(cell[0] == _WALL[0] or (cell[0] == _DOOR and cell[2] != _DOOR_OPEN))


def _visible(view: np.ndarray) -> np.ndarray:
    """``Grid.process_vis`` with the agent at the bottom centre, on a ``(7, 7, 3)`` view
    indexed ``[x, y]``: the cells the agent sees."""
    width, height = view.shape[:2]
    mask = np.zeros((width, height), dtype=bool)
    mask[width // 2, height - 1] = True
    for j in reversed(range(height)):
        for i in range(width - 1):  # light spreads to the right ...
            if mask[i, j] and not _blocks_sight(view[i, j]):
                mask[i + 1, j] = True
                if j > 0:
                    mask[i + 1, j - 1] = mask[i, j - 1] = True
        for i in reversed(range(1, width)):  # ... and to the left, row by row upwards
            if mask[i, j] and not _blocks_sight(view[i, j]):
                mask[i - 1, j] = True
                if j > 0:
                    mask[i - 1, j - 1] = mask[i, j - 1] = True
    return mask


def partial_view_of_grid(grid: np.ndarray) -> np.ndarray:
    """One full grid ``(s, s, 3)`` indexed ``[x, y, channel]`` -> the agent's view
    ``(7, 7, 3)`` uint8, as ``MiniGridEnv.gen_obs()["image"]``."""
    size = grid.shape[0]
    agent = np.argwhere(grid[..., 0] == _AGENT)
    if len(agent) != 1:
        raise ValueError(f"a DoorKey grid must hold exactly one agent cell, found {len(agent)}")
    (ax, ay), direction = agent[0], int(grid[agent[0][0], agent[0][1], 2])
    half = VIEW // 2
    top_x, top_y = {
        0: (ax, ay - half),
        1: (ax - half, ay),
        2: (ax - VIEW + 1, ay - half),
        3: (ax - half, ay - VIEW + 1),
    }[direction]
    view = np.empty((VIEW, VIEW, 3), dtype=np.int64)
    view[:] = _WALL  # Grid.slice: outside the grid is wall
    xs, ys = np.arange(top_x, top_x + VIEW), np.arange(top_y, top_y + VIEW)
    ix, iy = np.flatnonzero((xs >= 0) & (xs < size)), np.flatnonzero((ys >= 0) & (ys < size))
    view[np.ix_(ix, iy)] = grid[np.ix_(xs[ix], ys[iy])]
    view[ax - top_x, ay - top_y] = _EMPTY  # the grid under the agent: see-through
    for _ in range(direction + 1):  # rotate_left: new[j, H - 1 - i] = old[i, j]
        view = view.transpose(1, 0, 2)[:, ::-1]
    mask = _visible(view)
    view = np.where(mask[..., None], view, 0)  # Grid.encode: unseen cells are (0, 0, 0)
    carrying = not (grid[..., 0] == _KEY).any()
    view[half, VIEW - 1] = _CARRIED_KEY if carrying else _EMPTY
    return view.astype(np.uint8)


@functools.lru_cache(maxsize=1 << 16)
def _cached_view(grid_bytes: bytes, side: int) -> np.ndarray:
    """:func:`partial_view_of_grid` of one grid given as its uint8 bytes (MiniGrid's codes are
    all below 256; 147 bytes a key, so a full cache stays near 20 MB), flattened and
    read-only. DoorKey 7x7 has a few thousand distinct states, which training visits again and
    again, so the cache turns ~0.1 ms of Python per observation into a lookup."""
    grid = np.frombuffer(grid_bytes, dtype=np.uint8).astype(np.int64).reshape(side, side, 3)
    view = partial_view_of_grid(grid).reshape(-1)
    view.flags.writeable = False
    return view


def partial_view(obs_batch: np.ndarray) -> np.ndarray:
    """Flattened full-grid observations ``(n, 3 * s * s)`` -> flattened agent views
    ``(n, 147)`` uint8 (``[x, y, channel]`` in C order, as MiniGrid's image)."""
    obs = np.asarray(obs_batch)
    if obs.ndim == 1:
        obs = obs[None]
    side = round(np.sqrt(obs.shape[1] // 3))
    grids = np.rint(obs).astype(np.uint8).reshape(len(obs), side * side * 3)
    return np.stack([_cached_view(g.tobytes(), side) for g in grids])
