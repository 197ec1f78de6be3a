"""Can the student's low level (a 64x64 tanh MLP) copy Pendulum's q 0.97 SAC actor (-137.3)?
Offline DAgger, no reinforcement learning: the states of 100 of the teacher's episodes with
Gaussian action noise (sd 0.3), then of 50 of the fitted network's own episodes per round, all
labelled with the teacher's greedy action and fitted by mean squared error (Adam 1e-3, 20,000
steps of 256 rows); each round's network scored greedily on the sweep's 30 evaluation episodes.
It asks whether the sweep's shortfall on q 0.97 + random (the student alone -151.9 against the
mark -146.9 before cbd8f0f0; results/teacher-sweep/NOTES.md, "The copy's capacity") is the network's:

    .venv/bin/python lab/copy_capacity.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import peers  # noqa: E402
import teacher_sweep  # noqa: E402

ENV_ID = "Pendulum-v1"


def rollouts(act, episodes: int, noise: float, seed: int) -> np.ndarray:
    """The states of ``episodes`` episodes of ``act`` (a batch -> actions) with Gaussian noise."""
    env, rng, states = gym.make(ENV_ID), np.random.default_rng(seed), []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed * 1000 + episode)
        done = False
        while not done:
            states.append(obs)
            action = act(obs[None])[0] + noise * rng.standard_normal(1)
            obs, _, terminated, truncated, _ = env.step(np.clip(action, -2, 2).astype(np.float32))
            done = terminated or truncated
    return np.array(states, dtype=np.float32)


def fit(width: int, states: np.ndarray, labels: np.ndarray, steps: int = 20000) -> torch.nn.Module:
    """A ``width`` x ``width`` tanh MLP fitted to ``labels`` by mean squared error."""
    torch.manual_seed(0)
    net = torch.nn.Sequential(
        torch.nn.Linear(3, width),
        torch.nn.Tanh(),
        torch.nn.Linear(width, width),
        torch.nn.Tanh(),
        torch.nn.Linear(width, 1),
    )
    optimizer = torch.optim.Adam(net.parameters(), 1e-3)
    x, y = torch.as_tensor(states), torch.as_tensor(labels, dtype=torch.float32)
    generator = torch.Generator().manual_seed(0)
    for _ in range(steps):
        rows = torch.randint(len(x), (256,), generator=generator)
        loss = ((net(x[rows]) - y[rows]) ** 2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return net


def main() -> None:
    torch.set_num_threads(1)
    path = ROOT / "results/teacher-sweep/teachers" / ENV_ID / "q1.pt"
    teacher = teacher_sweep.load_teacher_model(ENV_ID, path)

    def label(batch: np.ndarray) -> np.ndarray:
        return teacher.predict(batch, deterministic=True)[0]

    print(f"the teacher: {peers.evaluate(label, ENV_ID, 30).mean():.1f}", flush=True)
    for width in (64, 256):
        states = rollouts(label, 100, 0.3, seed=1)
        for round_ in range(3):
            net = fit(width, states, label(states))

            def act(batch: np.ndarray, net: torch.nn.Module = net) -> np.ndarray:
                with torch.no_grad():
                    out = net(torch.as_tensor(np.asarray(batch), dtype=torch.float32))
                return np.clip(out.numpy(), -2, 2)

            score = peers.evaluate(act, ENV_ID, 30).mean()
            print(f"{width}x{width}, round {round_}: {len(states)} states, greedy {score:.1f}")
            states = np.concatenate([states, rollouts(act, 50, 0.0, seed=10 + round_)])


if __name__ == "__main__":
    main()
