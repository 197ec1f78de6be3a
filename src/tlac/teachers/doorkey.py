"""A scripted optimal teacher for DoorKey, acting from the fully observed grid only.

The paper trained its "optimal" DoorKey teacher with PPO (appendix A.1.1: 0.77 +- 0.38 over
1000 test episodes, so it failed now and then). A scripted teacher is exactly optimal and
needs no training: it runs a breadth-first search over the states the agent can reach,

    (x, y, direction, key taken, door open)

with the actions turn left, turn right, forward, pickup (when facing the key) and toggle
(when facing the door: opens a locked door only while carrying the key, a closed unlocked
door always), until a ``forward`` steps onto the goal. Its advice is the first action of a
shortest such plan, so it picks up the key, opens the door and walks to the goal in the
fewest steps, whatever happened before (a dropped key, a door closed again): the plan is
recomputed from each observation. Everything is read from the observation of
:mod:`tlac.envs.doorkey`: carrying the key shows as the key missing from the grid, and an
agent standing in the wall column stands in the open doorway. ``drop`` is never advised.

Observations repeat a lot (one layout yields a few thousand distinct states), so advice is
memoised by the observation's bytes.

>>> from tlac.envs.doorkey import make_doorkey_env
>>> env, teacher = make_doorkey_env(), DoorKeyOptimalTeacher()
>>> obs, _ = env.reset(seed=1)
>>> done = False
>>> while not done:
...     obs, reward, terminated, truncated, _ = env.step(int(teacher.predict(obs[None])[0]))
...     done = terminated or truncated
>>> terminated, reward > 0.9
(True, True)
"""

from __future__ import annotations

from collections import deque

import numpy as np

from tlac.envs.doorkey import (
    AGENT,
    DOOR,
    DOOR_LOCKED,
    DOOR_OPEN,
    FORWARD,
    GOAL,
    KEY,
    LEFT,
    PICKUP,
    RIGHT,
    TOGGLE,
    WALL,
    obs_to_grid,
)

# MiniGrid's direction vectors: 0 = +x (east), 1 = +y (south), 2 = -x, 3 = -y.
_DX = (1, 0, -1, 0)
_DY = (0, 1, 0, -1)
# Order in which equally short plans are preferred (any order gives a shortest plan).
_ACTION_ORDER = (FORWARD, LEFT, RIGHT, PICKUP, TOGGLE)


def plan_first_action(grid: np.ndarray) -> int | None:
    """First action of a shortest plan to the goal from one ``(s, s, 3)`` DoorKey grid
    (indexed ``[x, y, channel]``), or None if the goal cannot be reached."""
    side = grid.shape[0]
    objects = grid[..., 0]
    agent = np.argwhere(objects == AGENT)
    if len(agent) != 1:
        return None
    ax, ay = (int(v) for v in agent[0])
    adir = int(grid[ax, ay, 2])

    keys = np.argwhere(objects == KEY)
    key_cell = (int(keys[0][0]), int(keys[0][1])) if len(keys) else None
    doors = np.argwhere(objects == DOOR)
    if len(doors):
        door_cell = (int(doors[0][0]), int(doors[0][1]))
        door_state = int(grid[door_cell[0], door_cell[1], 2])
    else:  # the agent hides the door: it stands in the (necessarily open) doorway
        door_cell, door_state = (ax, ay), DOOR_OPEN
    # Cells the agent may step onto when the door is open and the key is gone: everything
    # but walls, the key and a shut door. Goal cells end the plan.
    blocked = objects == WALL
    is_goal = objects == GOAL

    start_key = key_cell is None  # key already carried
    start_open = door_state == DOOR_OPEN
    needs_key = door_state == DOOR_LOCKED

    def encode(x: int, y: int, d: int, k: bool, o: bool) -> int:
        return (((x * side + y) * 4 + d) * 2 + k) * 2 + o

    seen = bytearray(side * side * 4 * 4)
    start = (ax, ay, adir, start_key, start_open)
    seen[encode(*start)] = 1
    # Each queue entry carries the first action of the plan that reached it.
    queue: deque[tuple[int, int, int, bool, bool, int]] = deque()

    def push(state: tuple[int, int, int, bool, bool], first: int) -> None:
        code = encode(*state)
        if not seen[code]:
            seen[code] = 1
            queue.append((*state, first))

    def expand(x: int, y: int, d: int, k: bool, o: bool, first: int | None) -> int | None:
        """Push the successors; return the plan's first action if ``forward`` reaches the
        goal from here."""
        fx, fy = x + _DX[d], y + _DY[d]
        front_is_key = key_cell is not None and not k and (fx, fy) == key_cell
        front_is_door = (fx, fy) == door_cell
        for action in _ACTION_ORDER:
            head = action if first is None else first
            if action == FORWARD:
                if is_goal[fx, fy]:
                    return head
                if blocked[fx, fy] or front_is_key or (front_is_door and not o):
                    continue
                push((fx, fy, d, k, o), head)
            elif action == LEFT:
                push((x, y, (d + 3) % 4, k, o), head)
            elif action == RIGHT:
                push((x, y, (d + 1) % 4, k, o), head)
            elif action == PICKUP:
                if front_is_key:
                    push((x, y, d, True, o), head)
            elif action == TOGGLE:
                # MiniGrid's Door.toggle: a locked door opens only for the key's carrier.
                if front_is_door and not o and (k or not needs_key):
                    push((x, y, d, k, True), head)
        return None

    found = expand(*start, None)
    while found is None and queue:
        x, y, d, k, o, first = queue.popleft()
        found = expand(x, y, d, k, o, first)
    return found


class DoorKeyOptimalTeacher:
    """The scripted shortest-path DoorKey teacher (see the module docstring); batched.

    If no plan exists (never in DoorKey's layouts) it advises turning left.
    """

    def __init__(self, name: str = "optimal", cache_size: int = 200_000):
        self.name = name
        self.cache_size = cache_size
        self._cache: dict[bytes, int] = {}

    def predict(self, obs: np.ndarray) -> np.ndarray:
        grids = obs_to_grid(obs)
        actions = np.empty(len(grids), dtype=np.int64)
        for i, grid in enumerate(grids):
            key = grid.astype(np.uint8).tobytes()
            action = self._cache.get(key)
            if action is None:
                planned = plan_first_action(grid)
                action = LEFT if planned is None else planned
                if len(self._cache) >= self.cache_size:
                    self._cache.clear()
                self._cache[key] = action
            actions[i] = action
        return actions


__all__ = ["DoorKeyOptimalTeacher", "plan_first_action"]
