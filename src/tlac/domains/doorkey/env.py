"""MiniGrid DoorKey 7x7, fully observed and flattened (paper, section 5 and appendix A.1).

The paper uses ``MiniGrid-DoorKey-7x7-v0``; today's MiniGrid no longer registers a 7x7 id,
so the environment is built from ``minigrid.envs.DoorKeyEnv(size=7)`` directly.

Observation
    The whole grid, fully observed (``minigrid.wrappers.FullyObsWrapper``): every cell is
    MiniGrid's 3-tuple ``(object, colour, state)``; the agent's cell holds
    ``(agent=10, red=0, direction)``. The ``(width, height, 3)`` array, indexed
    ``[x, y, channel]``, is flattened in C order to 147 ``uint8`` values (raw indices, not
    normalised; integer-typed, since they are categories). The paper: "the state is a 3-tuple
    vector". Teachers and the agent see the same full state, so a scripted teacher and the
    region labels can be read off it.
Actions
    6 discrete actions, as the paper says: MiniGrid's left, right, forward, pickup, drop and
    toggle. MiniGrid's 7th action, ``done``, does nothing in DoorKey (it only spends a step),
    so :class:`FirstActions` drops it; the remaining ids are MiniGrid's own.
Reward and time limit
    MiniGrid's: ``1 - 0.9 * step_count / max_steps`` on reaching the goal, else 0, with
    ``max_steps = 10 * 7**2 = 490``. Reaching the goal is ``terminated``; running out of
    steps is ``truncated`` (MiniGrid signals it itself, so no extra ``TimeLimit`` is added).
Regions
    ``left`` (the key's room, where the agent starts) and ``right`` (the goal's room). The
    agent counts as in the right room from the wall column on, i.e. when it stands in the
    open doorway: from there only navigation to the goal remains (Teacher R's sub-task).

>>> env = make_doorkey_env()
>>> obs, info = env.reset(seed=0)
>>> obs.shape, env.action_space
((147,), Discrete(6))
>>> region_of(obs[None]).tolist()  # the agent starts in the left room
[0]
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from minigrid.core.constants import COLOR_TO_IDX, OBJECT_TO_IDX, STATE_TO_IDX
from minigrid.envs import DoorKeyEnv
from minigrid.wrappers import FullyObsWrapper

from tlac.domains.doorkey.view import VIEW, partial_view
from tlac.errors import ConfigError

GRID_SIZE = 7
"""Side of the square grid, outer walls included (the paper's DoorKey 7x7)."""
MAX_STEPS = 10 * GRID_SIZE**2
"""MiniGrid's default episode limit for DoorKey: ``10 * size**2`` = 490 steps."""
N_ACTIONS = 6
"""left, right, forward, pickup, drop, toggle (MiniGrid ids 0..5); ``done`` (6) is dropped."""

# MiniGrid action ids (minigrid.core.actions.Actions), kept as plain ints for numpy code.
LEFT, RIGHT, FORWARD, PICKUP, DROP, TOGGLE = range(6)
ACTION_NAMES = ("left", "right", "forward", "pickup", "drop", "toggle")

# Cell encodings (MiniGrid's constants, re-exported for the teacher and the tests).
EMPTY = OBJECT_TO_IDX["empty"]
WALL = OBJECT_TO_IDX["wall"]
DOOR = OBJECT_TO_IDX["door"]
KEY = OBJECT_TO_IDX["key"]
GOAL = OBJECT_TO_IDX["goal"]
AGENT = OBJECT_TO_IDX["agent"]
DOOR_OPEN, DOOR_CLOSED, DOOR_LOCKED = (STATE_TO_IDX[s] for s in ("open", "closed", "locked"))

# Largest value each channel can take: object index, colour index, state (door state or the
# agent's direction, both <= 3).
_CHANNEL_HIGH = np.array(
    [max(OBJECT_TO_IDX.values()), max(COLOR_TO_IDX.values()), 3], dtype=np.uint8
)


class FlatFullGrid(gym.ObservationWrapper):
    """Keep only the fully observed grid of a :class:`FullyObsWrapper` env and flatten it.

    The output is ``grid[x, y, c]`` flattened in C order (index ``(x * height + y) * 3 + c``),
    as ``uint8``: the values are category indices, and an integer observation space tells a
    learner so (TL-AC's graduate variant one-hot encodes such spaces; tlac.algorithms.encoding).
    """

    def __init__(self, env: gym.Env):
        super().__init__(env)
        width, height = env.unwrapped.width, env.unwrapped.height
        high = np.tile(_CHANNEL_HIGH, width * height)
        self.observation_space = gym.spaces.Box(low=np.zeros_like(high), high=high, dtype=np.uint8)

    def observation(self, observation: dict[str, Any]) -> np.ndarray:
        return np.asarray(observation["image"], dtype=np.uint8).reshape(-1)


class FirstActions(gym.ActionWrapper):
    """Expose only the first ``n`` actions of a ``Discrete`` action space, ids unchanged.

    Used to drop MiniGrid's no-op ``done`` action, leaving the paper's 6 actions.
    """

    def __init__(self, env: gym.Env, n: int):
        super().__init__(env)
        space = env.action_space
        if not isinstance(space, gym.spaces.Discrete) or not 1 <= n <= space.n:
            raise ConfigError(f"FirstActions needs a Discrete space with at least {n} actions")
        self.action_space = gym.spaces.Discrete(n, start=int(space.start))

    def action(self, action: Any) -> int:
        a = int(action)
        if not self.action_space.contains(a):
            # Without this check MiniGrid would silently run its hidden actions.
            raise ValueError(f"action {action!r} is outside {self.action_space}")
        return a


_EMPTY_CELL = (OBJECT_TO_IDX["empty"], 0, 0)


class FullyObservedDoorKey(DoorKeyEnv):
    """DoorKey whose observation is the full grid, built directly.

    MiniGrid's ``step`` always computes the agent's 7x7 egocentric view (slicing, rotating and
    a visibility pass) and :class:`FullyObsWrapper` then throws it away and encodes the
    whole grid. Producing the full encoding in ``gen_obs`` gives the same observation as
    ``FullyObsWrapper`` (checked in the tests) at about a quarter of the cost per step.
    """

    def gen_obs(self) -> dict[str, Any]:
        # MiniGrid's Grid.encode, without its per-cell get() and visibility-mask checks: the
        # flat cell list is row-major (index y * width + x), the observation is [x, y, channel]
        cells = [_EMPTY_CELL if v is None else v.encode() for v in self.grid.grid]
        full = (
            np.array(cells, dtype=np.uint8)
            .reshape(self.height, self.width, 3)
            .transpose(1, 0, 2)
            .copy()
        )
        x, y = self.agent_pos
        full[x, y] = (AGENT, COLOR_TO_IDX["red"], self.agent_dir)
        return {"image": full, "direction": self.agent_dir, "mission": self.mission}


def make_doorkey_env(
    render_mode: str | None = None, size: int = GRID_SIZE, max_steps: int | None = None
) -> gym.Env:
    """Build one DoorKey env (default: the paper's 7x7) with the observation and action
    spaces described in the module docstring. ``max_steps=None`` keeps MiniGrid's default,
    ``10 * size**2``."""
    base = FullyObservedDoorKey(size=size, max_steps=max_steps, render_mode=render_mode)
    return FirstActions(FlatFullGrid(base), N_ACTIONS)


def make_reference_doorkey_env(size: int = GRID_SIZE) -> gym.Env:
    """The same environment through MiniGrid's own :class:`FullyObsWrapper` (slower); kept
    to check that :class:`FullyObservedDoorKey` observes exactly the same."""
    return FirstActions(FlatFullGrid(FullyObsWrapper(DoorKeyEnv(size=size))), N_ACTIONS)


def obs_to_grid(obs_batch: np.ndarray) -> np.ndarray:
    """Flattened observations ``(n, 3 * s * s)`` -> integer grids ``(n, s, s, 3)``, indexed
    ``[row, x, y, channel]``. A single observation ``(3 * s * s,)`` is accepted too."""
    obs = np.asarray(obs_batch)
    if obs.ndim == 1:
        obs = obs[None]
    cells = obs.shape[1] // 3
    side = round(np.sqrt(cells))
    if obs.ndim != 2 or side * side * 3 != obs.shape[1]:
        raise ConfigError(
            f"expected flattened DoorKey observations of shape (n, 3*s*s); got {obs.shape}"
        )
    return np.rint(obs).astype(np.int64).reshape(obs.shape[0], side, side, 3)


def agent_positions(grids: np.ndarray) -> np.ndarray:
    """``(n, s, s, 3)`` grids -> ``(n, 2)`` agent ``(x, y)``."""
    is_agent = grids[..., 0] == AGENT
    found = is_agent.reshape(len(grids), -1)
    if not found.any(axis=1).all():
        raise ConfigError("a DoorKey observation has no agent cell")
    flat = found.argmax(axis=1)
    side = grids.shape[1]
    return np.stack([flat // side, flat % side], axis=1)


def wall_columns(grids: np.ndarray) -> np.ndarray:
    """The x of the splitting wall per grid: the inner column with the most wall cells
    (it is all wall but the door; every other inner column has none)."""
    inner = grids[:, 1:-1, 1:-1, 0] == WALL  # (n, x, y) without the outer walls
    return inner.sum(axis=2).argmax(axis=1) + 1


def region_of(obs_batch: np.ndarray) -> np.ndarray:
    """Region index per observation: 0 = ``left`` (agent's x below the wall column),
    1 = ``right`` (agent in the doorway or beyond). Vectorised over the batch."""
    grids = obs_to_grid(obs_batch)
    return (agent_positions(grids)[:, 0] >= wall_columns(grids)).astype(np.int64)


REGION_NAMES = ("left", "right")


class PartialView(gym.ObservationWrapper):
    """The agent's egocentric 7x7 view (MiniGrid's default observation), flattened to 147
    ``uint8`` values, computed from the full grid
    (:func:`tlac.domains.doorkey.view.partial_view`)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        high = np.tile(_CHANNEL_HIGH, VIEW * VIEW)
        self.observation_space = gym.spaces.Box(low=np.zeros_like(high), high=high, dtype=np.uint8)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        return partial_view(observation[None])[0]


def make_partial_doorkey_env(render_mode: str | None = None) -> gym.Env:
    """DoorKey 7x7 observed through the agent's partial view, 6 actions."""
    base = FullyObservedDoorKey(size=GRID_SIZE, render_mode=render_mode)
    return FirstActions(PartialView(FlatFullGrid(base)), N_ACTIONS)
