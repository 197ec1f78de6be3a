"""How close MountainCar's strongest sweep teacher is to the best any policy can do.

Issue 63's sweep asks the student beside MountainCar's q 0.97 teacher (a DQN checkpoint that
scores -101.9 over the sweep's 30 final episodes) to end at or above it. This finds, for each
of those episodes' starts (``reset(seed=10_000 + i)``), a short action sequence to the goal by
breadth-first search: every step expands each kept state by the three actions, with
gymnasium's MountainCar-v0 dynamics in float64 as the environment computes them, and keeps one
state per cell of a (position, velocity) grid. Each sequence found is replayed in the real
environment, so its return is one a policy can get (the best any policy gets is at least
that); the grid merges near-equal states, so a sequence a little shorter can be missed. The
teacher is scored on the same episodes.

    .venv/bin/python lab/mountaincar_optimum.py --teacher results/teacher-sweep/teachers/MountainCar-v0/q1.pt
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

FORCE, GRAVITY, MAX_SPEED = 0.001, 0.0025, 0.07
MIN_POSITION, MAX_POSITION, GOAL = -1.2, 0.6, 0.5


def next_states(p: np.ndarray, v: np.ndarray, action: int) -> tuple[np.ndarray, np.ndarray]:
    """gymnasium's MountainCarEnv.step on arrays of float64 states."""
    v = np.clip(v + ((action - 1) * FORCE + np.cos(3 * p) * (-GRAVITY)), -MAX_SPEED, MAX_SPEED)
    p = np.clip(p + v, MIN_POSITION, MAX_POSITION)
    return p, np.where((p == MIN_POSITION) & (v < 0), 0.0, v)


def shortest_actions(start: float, cell: tuple[float, float], limit: int = 200) -> list[int]:
    """An action sequence from (start, 0) to the goal, found breadth-first keeping one state
    per grid cell of size ``cell`` (position, velocity); [] when none within ``limit``."""
    p, v = np.array([start]), np.array([0.0])
    parents: list[tuple[np.ndarray, np.ndarray]] = []  # per step: parent index, action
    for _ in range(limit):
        ps, vs, parent, acts = [], [], [], []
        for action in (0, 1, 2):
            np_, nv = next_states(p, v, action)
            ps.append(np_)
            vs.append(nv)
            parent.append(np.arange(len(p)))
            acts.append(np.full(len(p), action))
        p, v = np.concatenate(ps), np.concatenate(vs)
        parent_idx, actions = np.concatenate(parent), np.concatenate(acts)
        done = np.flatnonzero((p >= GOAL) & (v >= 0))
        if done.size:
            path, i = [int(actions[done[0]])], int(parent_idx[done[0]])
            for back_parent, back_action in reversed(parents):
                path.append(int(back_action[i]))
                i = int(back_parent[i])
            return path[::-1]
        key = np.round(p / cell[0]).astype(np.int64) * 1_000_003 + np.round(v / cell[1]).astype(
            np.int64
        )
        _, keep = np.unique(key, return_index=True)
        p, v = p[keep], v[keep]
        parents.append((parent_idx[keep], actions[keep]))
    return []


def replay(seed: int, actions: list[int]) -> float:
    """The return of ``actions`` in MountainCar-v0 reset with ``seed`` (-200 if it never ends)."""
    env = gym.make("MountainCar-v0")
    env.reset(seed=seed)
    total = 0.0
    for a in actions:
        _, r, terminated, truncated, _ = env.step(a)
        total += r
        if terminated or truncated:
            return total
    return -200.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--seed", type=int, default=10_000)
    parser.add_argument("--cell", type=float, nargs=2, default=[1e-3, 1e-4])
    parser.add_argument("--teacher", type=Path, help="a sweep teacher file (teachers/ENV/NAME.pt)")
    args = parser.parse_args()
    found = []
    for i in range(args.episodes):
        env = gym.make("MountainCar-v0")
        obs, _ = env.reset(seed=args.seed + i)
        start = float(env.unwrapped.state[0])
        actions = shortest_actions(start, tuple(args.cell))
        found.append(replay(args.seed + i, actions))
        print(f"episode {i}: start {obs[0]:.4f}, replayed {found[-1]}")
    print(f"search, {args.episodes} episodes: {np.mean(found):.2f}")
    if args.teacher is not None:
        import teacher_sweep
        import user_envs

        model = teacher_sweep.load_teacher_model("MountainCar-v0", args.teacher)
        act = teacher_sweep.greedy_act(model)
        returns = user_envs.evaluate(act, "MountainCar-v0", args.episodes, args.seed)
        print(f"teacher {args.teacher}: {returns.mean():.2f}")
        print("per episode, search - teacher:", (np.array(found) - returns).astype(int).tolist())


if __name__ == "__main__":
    main()
