"""How well can a network copy an Acrobot controller? DAgger behaviour cloning, no RL.

Issue 8 asks the Acrobot student (alone) to match SB3 PPO alone, and TL-AC's student learns
by imitation. This probe asks whether imitation can get there at all: it clones a teacher of
benchmarks/user_envs.py (the heuristic ``acrobot_swing`` or the model-predictive
``AcrobotLookahead``) by DAgger (Ross et al. 2011): the teacher's own episodes first, then
rounds of the student's greedy episodes labelled by the teacher, each round training a fresh
cross-entropy fit on all labels so far. After every round it prints the student's greedy
agreement with the labels and its return over the suite's 30 evaluation episodes (seeds
10000-10029, as benchmarks/user_envs.py scores every learner).

    .venv/bin/python lab/acrobot_cloning.py --teacher lookahead --hidden 64 64
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from user_envs import (  # benchmarks/user_envs.py: the suite's teachers
    EVAL_EPISODES,
    AcrobotLookahead,
    acrobot_swing,
    evaluate,
    one_by_one,
)

Policy = Callable[[np.ndarray], int]


def play(policy: Policy, first_seed: int, episodes: int) -> tuple[np.ndarray, float]:
    """The states ``policy`` visits in Acrobot-v1 over ``episodes`` seeded episodes (DAgger's
    data), and its mean return there. Scores use the suite's own ``evaluate``."""
    env = gym.make("Acrobot-v1")
    states, returns = [], []
    for episode in range(episodes):
        obs, _ = env.reset(seed=first_seed + episode)
        total, done = 0.0, False
        while not done:
            states.append(obs)
            obs, reward, terminated, truncated, _ = env.step(policy(obs))
            total += float(reward)
            done = terminated or truncated
        returns.append(total)
    return np.array(states), float(np.mean(returns))


def labeller(teacher: str) -> Callable[[np.ndarray], np.ndarray]:
    """The teacher's actions for a batch of observations."""
    if teacher == "lookahead":
        return AcrobotLookahead().predict
    return lambda obs: np.array([acrobot_swing(o) for o in obs])


def mlp(hidden: list[int]) -> torch.nn.Sequential:
    layers: list[torch.nn.Module] = []
    width = 6
    for h in hidden:
        layers += [torch.nn.Linear(width, h), torch.nn.Tanh()]
        width = h
    return torch.nn.Sequential(*layers, torch.nn.Linear(width, 3))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--teacher", choices=["heuristic", "lookahead"], default="lookahead")
    parser.add_argument("--hidden", type=int, nargs="+", default=[64, 64])
    parser.add_argument("--rounds", type=int, default=8)
    parser.add_argument("--fit-steps", type=int, default=3000, help="Adam steps per round")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    label = labeller(args.teacher)
    # Acrobot-v1's velocity bounds, so that every input is within [-1, 1]
    scale = torch.tensor([1, 1, 1, 1, 4 * np.pi, 9 * np.pi], dtype=torch.float32)
    net = mlp(args.hidden)
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-3)

    def student(obs: np.ndarray) -> int:
        with torch.no_grad():
            return int(net(torch.as_tensor(obs, dtype=torch.float32)[None] / scale).argmax())

    started = time.time()
    states, teacher_return = play(lambda o: int(label(o[None])[0]), 0, 50)
    teacher_alone = evaluate(label, "Acrobot-v1", EVAL_EPISODES).mean()
    print(
        f"teacher {args.teacher}: {teacher_return:.1f} over its 50 training episodes, "
        f"{teacher_alone:.1f} over the {EVAL_EPISODES} evaluation episodes",
        flush=True,
    )
    xs, ys = [states], [label(states)]
    for round_ in range(args.rounds):
        x = torch.as_tensor(np.concatenate(xs), dtype=torch.float32) / scale
        y = torch.as_tensor(np.concatenate(ys))
        for _ in range(args.fit_steps):
            i = torch.randint(0, len(x), (256,))
            loss = torch.nn.functional.cross_entropy(net(x[i]), y[i])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        with torch.no_grad():
            agreement = float((net(x).argmax(1) == y).float().mean())
        visited, _ = play(student, 1000 * (round_ + 1), 20)  # DAgger: label the student's states
        xs.append(visited)
        ys.append(label(visited))
        alone = evaluate(one_by_one(student), "Acrobot-v1", EVAL_EPISODES).mean()
        print(
            f"round {round_}: {len(x)} labels, greedy agreement {agreement:.3f}, "
            f"student alone {alone:.1f} ({time.time() - started:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
