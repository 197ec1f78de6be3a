"""A scripted optimal teacher for DoorKey, acting from the fully observed grid only.

The paper trained its "optimal" DoorKey teacher with PPO (appendix A.1.1: 0.77 +- 0.38 over
1000 test episodes, so it failed now and then). A scripted teacher is exactly optimal and
needs no training. It plans over the states the agent can reach,

    (x, y, direction, key taken, door open)

with the actions turn left, turn right, forward, pickup (when facing the key) and toggle
(when facing the door: opens a locked door only while carrying the key, a closed unlocked
door always); a ``forward`` onto the goal ends a plan. Its advice is the first action of a
shortest plan, so it picks up the key, opens the door and walks to the goal in the fewest
steps, whatever happened before (a dropped key, a door closed again): the advice is derived
afresh from each observation. Everything is read from the observation of
:mod:`tlac.domains.doorkey.env`: carrying the key shows as the key missing from the grid, and an
agent standing in the wall column stands in the open doorway. ``drop`` is never advised.

How it is computed: the exact distance to the goal of every state is tabulated once per
layout, by a backward breadth-first search, and cached. The states split into four modes
(key taken, door open); pickup and toggle only ever leave a mode for a later one, so each
mode's table depends only on what its moves can bump into (the walls and goal; the key's
cell while the key is on the floor; the door's cell, and whether it is locked, while it is
shut) and is built from the tables of the modes it leads to. A DoorKey 7x7 layout needs
three or four tables of 196 entries; there are a few hundred distinct ones in all. The
advice is then the first of forward, left, right, pickup, toggle whose successor is closest
to the goal: exactly the first action of the plan that a forward breadth-first search
expanding the actions in that order finds (the lexicographically first shortest plan),
which is what this teacher computed before the tables (the tests compare the two). Advice
is also memoised by the observation's bytes.

>>> from tlac.domains.doorkey.env import make_doorkey_env
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

import math

import numpy as np

from tlac.domains.doorkey.env import (
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

_INF = 1 << 30
"""Distance of a state from which the goal cannot be reached."""
# Cell codes of a layout: what a cell is for every state of the episode.
_FREE, _WALL, _GOAL = 0, 1, 2


class _DistanceTables:
    """Exact distance to the goal (in actions) of every abstract state, one table per
    layout and mode, computed on first use and cached.

    A cell is ``x * side + y`` (the flattened observation's order) and a state of a mode is
    ``cell * 4 + direction``. ``cells`` is the layout: one byte per cell, ``_WALL``,
    ``_GOAL`` or ``_FREE``. A mode is (key taken ``k``, door open ``o``); its table depends
    only on what the mode's moves can see: the key's cell while ``not k``, the door's cell
    while ``not o`` and whether the door is locked while neither.
    """

    def __init__(self, max_tables: int = 20_000):
        self.max_tables = max_tables
        self._tables: dict[tuple[bytes, bool, bool, int, int, bool], list[int]] = {}

    def get(
        self, cells: bytes, k: bool, o: bool, key_cell: int, door_cell: int, needs_key: bool
    ) -> list[int]:
        if k:
            key_cell = -1
        if o:
            door_cell = -1
        needs_key = needs_key and not (k or o)
        tag = (cells, k, o, key_cell, door_cell, needs_key)
        table = self._tables.get(tag)
        if table is None:
            table = self._compute(cells, k, o, key_cell, door_cell, needs_key)
            if len(self._tables) >= self.max_tables:
                self._tables.clear()
            self._tables[tag] = table
        return table

    def _compute(
        self, cells: bytes, k: bool, o: bool, key_cell: int, door_cell: int, needs_key: bool
    ) -> list[int]:
        """Backward breadth-first search from the states one action from leaving the mode:
        facing the goal (``forward`` ends the episode: distance 1), facing the key (pickup:
        1 + the distance in mode ``(True, o)``) and facing the door when it can be opened
        (toggle: 1 + the distance in mode ``(k, True)``). Those exits have different
        distances, so the search takes them in by increasing distance (Dial's buckets)."""
        n = len(cells)
        side = round(n**0.5)
        steps = (side, 1, -side, -1)  # cell offset of one step in each direction
        passable = [c == _FREE for c in cells]
        if not k:
            passable[key_cell] = False
        if not o:
            passable[door_cell] = False

        by_value: dict[int, list[int]] = {}

        def add_exits(target: int, upper: list[int] | None) -> None:
            """Seed the states facing ``target`` with 1 + their distance in ``upper``
            (1 if ``upper`` is None: target is the goal)."""
            for d in range(4):
                c = target - steps[d]
                if 0 <= c < n and passable[c]:
                    v = 1 if upper is None else upper[c * 4 + d] + 1
                    if v < _INF:
                        by_value.setdefault(v, []).append(c * 4 + d)

        for g in range(n):
            if cells[g] == _GOAL:
                add_exits(g, None)
        if not k:
            add_exits(key_cell, self.get(cells, True, o, key_cell, door_cell, needs_key))
        if not o and (k or not needs_key):
            add_exits(door_cell, self.get(cells, k, True, key_cell, door_cell, needs_key))

        dist = [_INF] * (4 * n)
        if not by_value:
            return dist
        v = min(by_value)
        frontier = by_value.pop(v)
        while True:
            nxt: list[int] = []
            for s in frontier:
                if dist[s] != _INF:
                    continue
                dist[s] = v
                d = s & 3
                # Predecessors: the turns into direction d, and a forward step from behind.
                q = s - d + ((d + 1) & 3)
                if dist[q] == _INF:
                    nxt.append(q)
                q = s - d + ((d + 3) & 3)
                if dist[q] == _INF:
                    nxt.append(q)
                p = (s >> 2) - steps[d]
                if 0 <= p < n and passable[p]:
                    q = p * 4 + d
                    if dist[q] == _INF:
                        nxt.append(q)
            v += 1
            if v in by_value:
                nxt += by_value.pop(v)
            if not nxt:
                if not by_value:
                    return dist
                v = min(by_value)
                nxt = by_value.pop(v)
            frontier = nxt

    def first_action(
        self, cells: bytes, agent: int, d: int, key_cell: int, door_cell: int, door_state: int
    ) -> int | None:
        """First action of the shortest plan that the former forward search found:
        among the actions in the order forward, left, right, pickup, toggle, the first
        whose successor is closest to the goal. ``key_cell`` / ``door_cell`` are -1 when
        the key is carried / the door is hidden by the agent (standing in the doorway)."""
        n = len(cells)
        side = round(n**0.5)
        front = agent + (side, 1, -side, -1)[d]
        if cells[front] == _GOAL:
            return FORWARD
        k = key_cell < 0
        o = door_cell < 0 or door_state == DOOR_OPEN
        needs_key = door_state == DOOR_LOCKED
        here = self.get(cells, k, o, key_cell, door_cell, needs_key)
        base = agent * 4
        # A blocked front cell (wall, key, shut door) has distance _INF in ``here``.
        best, action = here[front * 4 + d], FORWARD
        v = here[base + ((d + 3) & 3)]
        if v < best:
            best, action = v, LEFT
        v = here[base + ((d + 1) & 3)]
        if v < best:
            best, action = v, RIGHT
        if not k and front == key_cell:
            v = self.get(cells, True, o, key_cell, door_cell, needs_key)[base + d]
            if v < best:
                best, action = v, PICKUP
        if not o and front == door_cell and (k or not needs_key):
            v = self.get(cells, k, True, key_cell, door_cell, needs_key)[base + d]
            if v < best:
                best, action = v, TOGGLE
        return None if best >= _INF else action

    def first_action_of(self, grid: bytes) -> int | None:
        """:meth:`first_action` for one observation given as the bytes of its ``uint8``
        grid ``[x, y, channel]`` in C order (decoded with bytes methods: faster than numpy
        for one small grid). None if there is no plan (or not exactly one agent)."""
        objects = grid[0::3]
        if objects.count(AGENT) != 1:
            return None
        agent = objects.find(AGENT)
        key_cell = objects.find(KEY)  # -1: carried
        door_cell = objects.find(DOOR)  # -1: the agent stands in the doorway
        door_state = grid[3 * door_cell + 2] if door_cell >= 0 else DOOR_OPEN
        return self.first_action(
            objects.translate(_CELL_CODES),
            agent,
            grid[3 * agent + 2],
            key_cell,
            door_cell,
            door_state,
        )


_CELL_CODES = bytes(_WALL if i == WALL else _GOAL if i == GOAL else _FREE for i in range(256))
"""``bytes.translate`` table: object index -> cell code."""
_SHARED_TABLES = _DistanceTables()


def _observation_bytes(obs_batch: np.ndarray) -> list[bytes]:
    """Flattened observations ``(n, 3 * s * s)`` (or one, ``(3 * s * s,)``) -> one
    ``bytes`` per observation: its grid ``[x, y, channel]`` as ``uint8`` in C order, the
    values of :func:`~tlac.domains.doorkey.env.obs_to_grid` (a few microseconds cheaper than
    calling it, which matters for one observation per call)."""
    obs = np.asarray(obs_batch)
    if obs.ndim == 1:
        obs = obs[None]
    if obs.ndim != 2 or math.isqrt(obs.shape[1] // 3) ** 2 * 3 != obs.shape[1]:
        obs_to_grid(obs)  # raises its ConfigError
    flat = np.rint(obs).astype(np.int64).astype(np.uint8)
    width, buf = flat.shape[1], flat.tobytes()
    return [buf[i : i + width] for i in range(0, len(buf), width)]


def plan_first_action(grid: np.ndarray) -> int | None:
    """First action of a shortest plan to the goal from one ``(s, s, 3)`` DoorKey grid
    (indexed ``[x, y, channel]``), or None if the goal cannot be reached."""
    return _SHARED_TABLES.first_action_of(_observation_bytes(np.asarray(grid).reshape(-1))[0])


class DoorKeyOptimalTeacher:
    """The scripted shortest-path DoorKey teacher (see the module docstring); batched.

    If no plan exists (never in DoorKey's layouts) it advises turning left. ``cache_size``
    bounds the advice memo (by observation); the distance tables (one per layout and mode,
    a few hundred in DoorKey 7x7) are bounded by ``_DistanceTables.max_tables``.
    """

    def __init__(self, name: str = "optimal", cache_size: int = 200_000):
        self.name = name
        self.cache_size = cache_size
        self._cache: dict[bytes, int] = {}
        self._tables = _DistanceTables()

    def predict(self, obs: np.ndarray) -> np.ndarray:
        grids = _observation_bytes(obs)
        actions = np.empty(len(grids), dtype=np.int64)
        cache = self._cache
        for i, grid in enumerate(grids):
            action = cache.get(grid)
            if action is None:
                planned = self._tables.first_action_of(grid)
                action = LEFT if planned is None else planned
                if len(cache) >= self.cache_size:
                    cache.clear()
                cache[grid] = action
            actions[i] = action
        return actions


__all__ = ["DoorKeyOptimalTeacher", "plan_first_action"]
