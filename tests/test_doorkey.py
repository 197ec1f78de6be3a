"""The DoorKey 7x7 domain and its scripted optimal teacher."""

from __future__ import annotations

import copy
import doctest
from collections import deque

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import tlac.domains.doorkey.env
import tlac.domains.doorkey.planner
from tlac.domains import get_domain, make_teachers
from tlac.domains.doorkey import DOMAIN
from tlac.domains.doorkey.env import (
    AGENT,
    DOOR,
    DOOR_LOCKED,
    DOOR_OPEN,
    FORWARD,
    GOAL,
    KEY,
    LEFT,
    MAX_STEPS,
    PICKUP,
    RIGHT,
    TOGGLE,
    WALL,
    make_doorkey_env,
    obs_to_grid,
    region_of,
)
from tlac.domains.doorkey.planner import DoorKeyOptimalTeacher, plan_first_action
from tlac.errors import UnknownNameError
from tlac.teachers.base import check_actions
from tlac.teachers.wrappers import MixedRandomTeacher, PartialTeacher


def run_episode(env: gym.Env, policy, seed: int, first_actions=()):
    """Run one episode; returns (return, length, terminated, observations)."""
    obs, _ = env.reset(seed=seed)
    total, steps, observations = 0.0, 0, [obs]
    actions = list(first_actions)
    while True:
        action = actions.pop(0) if actions else int(policy(obs))
        obs, reward, terminated, truncated, _ = env.step(action)
        total += float(reward)
        steps += 1
        observations.append(obs)
        if terminated or truncated:
            return total, steps, terminated, observations


def wall_x(env: gym.Env) -> int:
    """The splitting wall's x, read from MiniGrid's own grid (not from the observation)."""
    grid = env.unwrapped.grid
    for x in range(1, grid.width - 1):
        if all(grid.get(x, y) is not None for y in range(1, grid.height - 1)):
            return x
    raise AssertionError("no splitting wall")


def true_shortest_length(env: gym.Env) -> int:
    """Fewest steps to the goal from the env's current state, by breadth-first search that
    drives the real MiniGrid ``step`` with all 6 actions (nothing read from observations).

    A search state is (agent position, direction, key carried, key position, door open,
    door locked); it is written into one copy of the env before each step."""
    e = copy.deepcopy(env.unwrapped)
    e.gen_obs = dict  # speed only: the search never reads observations
    objects = [o for o in e.grid.grid if o is not None]
    door = next(o for o in objects if o.type == "door")
    key = next((o for o in objects if o.type == "key"), e.carrying)

    def read() -> tuple:
        key_pos = None if e.carrying is not None else tuple(int(v) for v in key.cur_pos)
        pos = tuple(int(v) for v in e.agent_pos)
        return (
            pos,
            int(e.agent_dir),
            e.carrying is not None,
            key_pos,
            door.is_open,
            door.is_locked,
        )

    def write(state: tuple) -> None:
        pos, direction, carried, key_pos, is_open, is_locked = state
        for i, o in enumerate(e.grid.grid):
            if o is key:
                e.grid.grid[i] = None
        if key_pos is not None:
            e.grid.set(*key_pos, key)
            key.cur_pos = key_pos
        e.carrying = key if carried else None
        e.agent_pos, e.agent_dir = pos, direction
        door.is_open, door.is_locked = is_open, is_locked
        e.step_count = 0

    start = read()
    queue, seen = deque([(start, 0)]), {start}
    while queue:
        state, depth = queue.popleft()
        for action in range(6):
            write(state)
            _, _, terminated, _, _ = e.step(action)
            if terminated:
                return depth + 1
            child = read()
            if child not in seen:
                seen.add(child)
                queue.append((child, depth + 1))
    raise AssertionError("goal unreachable")


def _plan_first_action_bfs(grid: np.ndarray) -> int | None:
    """The teacher's original planner, kept as the reference for its distance tables: a
    forward breadth-first search over (x, y, direction, key taken, door open), expanding
    forward, left, right, pickup, toggle in that order, until a ``forward`` reaches the
    goal; returns that plan's first action (None: no plan). About 0.3-0.5 ms a call."""
    dx, dy = (1, 0, -1, 0), (0, 1, 0, -1)
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
    blocked = objects == WALL
    is_goal = objects == GOAL
    needs_key = door_state == DOOR_LOCKED

    def encode(x: int, y: int, d: int, k: bool, o: bool) -> int:
        return (((x * side + y) * 4 + d) * 2 + k) * 2 + o

    seen = bytearray(side * side * 4 * 4)
    start = (ax, ay, adir, key_cell is None, door_state == DOOR_OPEN)
    seen[encode(*start)] = 1
    queue: deque = deque()  # (x, y, d, k, o, first action of the plan reaching it)

    def push(state: tuple, first: int) -> None:
        code = encode(*state)
        if not seen[code]:
            seen[code] = 1
            queue.append((*state, first))

    def expand(x: int, y: int, d: int, k: bool, o: bool, first: int | None) -> int | None:
        fx, fy = x + dx[d], y + dy[d]
        front_is_key = key_cell is not None and not k and (fx, fy) == key_cell
        front_is_door = (fx, fy) == door_cell
        for action in (FORWARD, LEFT, RIGHT, PICKUP, TOGGLE):
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
            elif action == TOGGLE and front_is_door and not o and (k or not needs_key):
                push((x, y, d, k, True), head)
        return None

    found = expand(*start, None)
    while found is None and queue:
        found = expand(*queue.popleft())
    return found


@pytest.fixture
def env() -> gym.Env:
    return make_doorkey_env()


def test_spaces_and_check_env(env):
    assert env.action_space == gym.spaces.Discrete(6)
    assert env.observation_space.shape == (147,)
    assert env.observation_space.dtype == np.uint8  # category indices (tlac.algorithms.encoding)
    check_env(env.unwrapped, skip_render_check=True)
    check_env(env, skip_render_check=True)


def test_hidden_done_action_is_rejected(env):
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action 6 is outside Discrete\(6\)"):
        env.step(6)


def test_teacher_on_a_terminal_observation_gives_a_valid_action(env):
    """On the last observation the agent covers the goal: no plan exists, and the teacher
    still answers (AC-Teach's meta target queries teachers on terminal observations)."""
    teacher = DoorKeyOptimalTeacher()
    last = run_episode(env, lambda o: teacher.predict(o[None])[0], seed=2)[3][-1]
    assert not (obs_to_grid(last)[0, ..., 0] == GOAL).any()
    assert teacher.predict(last[None]).tolist() == [LEFT]
    assert region_of(last[None]).tolist() == [1]


def test_observation_is_the_full_grid(env):
    obs, _ = env.reset(seed=3)
    grid = obs_to_grid(obs)[0]
    u = env.unwrapped
    x, y = u.agent_pos
    assert tuple(grid[x, y]) == (AGENT, 0, u.agent_dir)
    key = next(
        (i, j)
        for i in range(7)
        for j in range(7)
        if u.grid.get(i, j) is not None and u.grid.get(i, j).type == "key"
    )
    assert grid[key][0] == KEY
    door = next(
        (i, j)
        for i in range(7)
        for j in range(7)
        if u.grid.get(i, j) is not None and u.grid.get(i, j).type == "door"
    )
    assert tuple(grid[door]) == (DOOR, 4, 2)  # yellow, locked
    assert obs in env.observation_space


def test_reward_time_limit_and_truncation():
    env = make_doorkey_env()
    assert env.unwrapped.max_steps == MAX_STEPS == DOMAIN.max_episode_steps == 490
    # Turning on the spot never reaches the goal: truncated (not terminated) at 490 steps.
    total, steps, terminated, _ = run_episode(env, lambda o: 0, seed=0)
    assert (total, steps, terminated) == (0.0, 490, False)
    short = make_doorkey_env(max_steps=20)
    short.reset(seed=0)
    for t in range(1, 21):
        _obs, _reward, terminated, truncated, _ = short.step(1)
        assert (terminated, truncated) == (False, t == 20)
    # Success: MiniGrid's reward 1 - 0.9 * steps / max_steps, terminated, not truncated.
    teacher = DoorKeyOptimalTeacher()
    total, steps, terminated, _ = run_episode(env, lambda o: teacher.predict(o[None])[0], 0)
    assert terminated and total == pytest.approx(1 - 0.9 * steps / 490)


def test_optimal_teacher_solves_100_seeds(env):
    teacher = DoorKeyOptimalTeacher()
    returns = []
    for seed in range(100):
        total, _, terminated, _ = run_episode(env, lambda o: teacher.predict(o[None])[0], seed)
        assert terminated, f"seed {seed} not solved"
        returns.append(total)
    assert np.mean(returns) >= 0.9 and min(returns) > 0.9


def test_optimal_teacher_is_shortest(env):
    """Episode length under the teacher == brute-force shortest length, from start states of
    20 layouts and from 20 states reached by random actions (key carried or dropped, door
    open or closed again)."""
    teacher = DoorKeyOptimalTeacher()
    # Half-random walker: reaches carried keys, dropped keys, open and re-closed doors.
    walker = MixedRandomTeacher(DoorKeyOptimalTeacher(), 0.5, env.action_space, seed=1)
    rng = np.random.default_rng(1)
    situations = set()
    for seed in range(40):
        obs, _ = env.reset(seed=seed)
        if seed >= 20:
            for _ in range(int(rng.integers(5, 40))):
                obs, _, terminated, truncated, _ = env.step(int(walker.predict(obs[None])[0]))
                if terminated or truncated:
                    obs, _ = env.reset(seed=seed)
        grid = obs_to_grid(obs)[0]
        door = grid[..., 2][grid[..., 0] == DOOR]
        situations.add((bool((grid[..., 0] == KEY).any()), int(door[0]) if len(door) else 0))
        expected = true_shortest_length(env)
        steps, terminated = 0, False
        while not terminated and steps <= expected:
            obs, _, terminated, _, _ = env.step(int(teacher.predict(obs[None])[0]))
            steps += 1
        assert terminated and steps == expected, (seed, steps, expected)
    # (key on the floor, door state): locked with / without the key, and open, were covered.
    assert {(True, 2), (False, 2), (False, 0)} <= situations, situations


def test_optimal_teacher_recovers_from_any_state(env):
    """After random actions (dropped keys, doors closed again, turns) the teacher still
    reaches the goal from wherever the agent is."""
    teacher = DoorKeyOptimalTeacher()
    rng = np.random.default_rng(0)
    for seed in range(40):
        prefix = rng.integers(0, 6, size=int(rng.integers(0, 80))).tolist()
        _total, steps, terminated, _ = run_episode(
            env, lambda o: teacher.predict(o[None])[0], seed, first_actions=prefix
        )
        assert terminated or steps == 490
        if steps <= len(prefix):
            continue  # the random prefix itself reached the goal
        assert terminated, f"seed {seed}: teacher failed after a random prefix"
    # Scripted detour: follow the teacher until it opens the door, then close the door
    # again, turn and drop the key. The door is now closed but unlocked, the key lies on
    # the floor: the teacher must reopen the door without fetching the key.
    for seed in range(10):
        obs, _ = env.reset(seed=seed)
        for _ in range(100):
            a = int(teacher.predict(obs[None])[0])
            obs, *_ = env.step(a)
            if a == 5:  # toggle: the door is open
                break
        for a in (5, 1, 4, 1, 4, 1, 4):  # close, then turn and drop until the key is down
            obs, *_ = env.step(a)
            if (obs_to_grid(obs)[0, ..., 0] == KEY).any():
                break
        grid = obs_to_grid(obs)[0]
        assert (grid[..., 0] == KEY).any() and (grid[..., 2][grid[..., 0] == DOOR] == 1).all()
        steps, terminated = 0, False
        while not terminated and steps < 30:
            a = int(teacher.predict(obs[None])[0])
            assert a != 3, "the teacher fetched a key it no longer needs"
            obs, _, terminated, _, _ = env.step(a)
            steps += 1
        assert terminated


def test_distance_tables_give_the_forward_search_advice(env):
    """The table-driven teacher advises exactly what the original forward breadth-first
    search advised (same action, ties included) on thousands of distinct states of random
    and half-random play over 400 episodes: key on the floor where it started, carried or
    dropped elsewhere; door locked, closed again, open, or hidden by the agent in the
    doorway; terminal observations (no plan); and layouts made unsolvable."""
    rng = np.random.default_rng(0)
    seen, observations, dropped = set(), [], 0

    def key_cell(obs):
        return tuple(np.argwhere(obs_to_grid(obs)[0, ..., 0] == KEY).ravel())

    for seed in range(400):
        walker = MixedRandomTeacher(
            DoorKeyOptimalTeacher(), float(rng.choice([0.0, 0.4, 0.8])), env.action_space, seed
        )
        obs, _ = env.reset(seed=seed)
        start_key = key_cell(obs)
        for _ in range(int(rng.integers(20, 160))):
            if obs.tobytes() not in seen:
                seen.add(obs.tobytes())
                observations.append(obs)
                dropped += key_cell(obs) not in ((), start_key)  # on the floor, moved
            obs, _, terminated, truncated, _ = env.step(int(walker.predict(obs[None])[0]))
            if terminated or truncated:
                observations.append(obs)
                break
    assert dropped >= 100
    grids = obs_to_grid(np.stack(observations))
    # Unsolvable variants: the door walled up, the goal room shut off (unless the agent is
    # in it already).
    walled = grids[:: len(grids) // 30].copy()
    walled[walled[..., 0] == DOOR] = (WALL, 0, 0)
    grids = np.concatenate([grids, walled])

    situations, no_plan = set(), 0
    expected = []
    for grid in grids:
        objects = grid[..., 0]
        door = grid[..., 2][objects == DOOR]
        situations.add((bool((objects == KEY).any()), int(door[0]) if len(door) else -1))
        action = _plan_first_action_bfs(grid)
        no_plan += action is None
        assert plan_first_action(grid) == action
        expected.append(LEFT if action is None else action)
    assert len(grids) > 3000 and no_plan >= 20
    # (key on the floor, door state; -1: hidden by the agent in the doorway): all occur.
    assert situations >= {(k, s) for k in (True, False) for s in (-1, 0, 1, 2)}, situations
    flat = grids.reshape(len(grids), -1).astype(np.float32)
    teacher = DoorKeyOptimalTeacher()
    assert teacher.predict(flat).tolist() == expected
    assert [int(teacher.predict(o)[0]) for o in flat] == expected  # memoised, one by one
    assert [int(DoorKeyOptimalTeacher().predict(o)[0]) for o in flat[:300]] == expected[:300]


def test_batched_prediction_matches_single(env):
    teacher = DoorKeyOptimalTeacher()
    observations = []
    for seed in range(10):
        observations += run_episode(env, lambda o: teacher.predict(o[None])[0], seed)[3]
    batch = np.stack(observations)
    single = [int(DoorKeyOptimalTeacher().predict(o[None])[0]) for o in batch]
    assert DoorKeyOptimalTeacher().predict(batch).tolist() == single
    check_actions("optimal", teacher.predict(batch), env.action_space, len(batch))


def test_region_labels(env):
    teacher = DoorKeyOptimalTeacher()
    for seed in range(30):
        obs, _ = env.reset(seed=seed)
        split = wall_x(env)
        labels, truth = [], []
        done = False
        while not done:
            labels.append(int(region_of(obs[None])[0]))
            truth.append(int(env.unwrapped.agent_pos[0] >= split))
            obs, _, terminated, truncated, _ = env.step(int(teacher.predict(obs[None])[0]))
            done = terminated or truncated
        assert labels == truth
        assert labels[0] == 0, "the agent starts in the left room"
        assert labels[-1] == 1, "the goal is reached from the right room"
        # Left, then right once through the door: the optimal path never goes back.
        assert labels == sorted(labels)
    assert DOMAIN.region_names == ("left", "right")


def test_domain_registry_and_teachers(env):
    domain = get_domain("doorkey")
    assert domain is DOMAIN
    assert domain.teacher_names == (
        "optimal", "good", "noisy", "random", "L", "R",
        "ppo", "ppo-good", "ppo-noisy", "ppo-L", "ppo-R", "ppo-good80", "ppo-noisy20",
    )  # fmt: skip
    assert domain.default_teachers == ("optimal", "random", "random")
    assert set(domain.presets) == {"tlac", "a2c", "ppo", "dqn-tlql", "ac-teach"}
    teachers = make_teachers(domain, list(domain.teacher_names), env, seed=0)
    obs, _ = env.reset(seed=0)
    batch = np.repeat(obs[None], 5, axis=0)
    for t in teachers:
        check_actions(t.name, t.predict(batch), env.action_space, 5)
    with pytest.raises(UnknownNameError, match="'best'"):
        DOMAIN.make_teacher("best", env, 0)


def test_good_and_noisy_teachers_take_their_bases_action_with_their_share(env):
    """The appendix's shares (0.8, 0.2) on the scripted teacher and as ppo-good80 / ppo-noisy20;
    ppo-good / ppo-noisy calibrated to the paper's returns on our stronger PPO agent."""
    shares = {
        "good": 0.8, "noisy": 0.2, "ppo-good": 0.38, "ppo-noisy": 0.12,
        "ppo-good80": 0.8, "ppo-noisy20": 0.2,
    }  # fmt: skip
    for name, share in shares.items():
        teacher = DOMAIN.make_teacher(name, env, 0)
        assert isinstance(teacher, MixedRandomTeacher) and teacher.name == name
        assert teacher.p_teacher == share, name
        assert teacher.base.name == name  # the base is built under the derived teacher's name


def test_partial_teachers_cover_their_rooms(env):
    L = DOMAIN.make_teacher("L", env, 0)
    R = DOMAIN.make_teacher("R", env, 0)
    assert isinstance(L, PartialTeacher) and isinstance(R, PartialTeacher)
    optimal = DoorKeyOptimalTeacher()
    observations = []
    for seed in range(10):
        observations += run_episode(env, lambda o: optimal.predict(o[None])[0], seed)[3][:-1]
    batch = np.stack(observations)
    regions = region_of(batch)
    np.testing.assert_array_equal(L.applies(batch), regions == 0)
    np.testing.assert_array_equal(R.applies(batch), regions == 1)
    best = optimal.predict(batch)
    np.testing.assert_array_equal(L.predict(batch)[regions == 0], best[regions == 0])
    np.testing.assert_array_equal(R.predict(batch)[regions == 1], best[regions == 1])


@pytest.mark.parametrize("module", [tlac.domains.doorkey.env, tlac.domains.doorkey.planner])
def test_doctests(module):
    result = doctest.testmod(module)
    assert result.attempted > 0 and result.failed == 0
