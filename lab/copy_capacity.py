"""Can the student's low level (a 64x64 tanh MLP) copy the sweep's q 1 teacher of an environment?
Offline DAgger, no reinforcement learning: the states of 100 of the teacher's episodes with
exploration noise (Box: Gaussian action noise, sd 0.3; Discrete: a uniformly random action 10%
of the time), then of 50 of the fitted network's own episodes per round, all labelled with the
teacher's greedy action and fitted (Box: squared error; Discrete: cross-entropy; Adam 1e-3,
20,000 steps of 256 rows; the inputs standardised by the states' mean and spread where the
student's ``normalize_obs: auto`` normalises them); each round's network scored greedily on the sweep's 30
evaluation episodes. It asks whether a sweep shortfall beside the near-optimal teacher is the
network's: Pendulum's q 0.97 + random (the student alone -151.9 against the mark -146.9 before
cbd8f0f0) and MountainCar's (-105.2 against its teacher's -101.9; results/teacher-sweep/NOTES.md,
"The copy's capacity" and "MountainCar's copy"):

    .venv/bin/python lab/copy_capacity.py [--env MountainCar-v0]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import peers  # noqa: E402
import teacher_sweep  # noqa: E402

from tlac.algorithms.normalization import declares_unit_scale  # noqa: E402


def rollouts(env_id: str, act, episodes: int, noise: float, seed: int) -> np.ndarray:
    """The states of ``episodes`` episodes of ``act`` (a batch -> actions) with exploration
    noise ``noise`` (Box: the Gaussian's sd; Discrete: the share of uniformly random actions)."""
    env, rng, states = gym.make(env_id), np.random.default_rng(seed), []
    space = env.action_space
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed * 1000 + episode)
        done = False
        while not done:
            states.append(obs)
            action = act(obs[None])[0]
            if isinstance(space, gym.spaces.Box):
                noisy = action + noise * rng.standard_normal(space.shape)
                action = np.clip(noisy, space.low, space.high).astype(np.float32)
            elif rng.random() < noise:
                action = int(rng.integers(space.n))
            obs, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
    return np.array(states, dtype=np.float32)


def fit(
    width: int,
    states: np.ndarray,
    labels: np.ndarray,
    outputs: int,
    standardise: bool,
    steps: int = 20000,
) -> torch.nn.Module:
    """A ``width`` x ``width`` tanh MLP fitted to ``labels``: by squared error to ``outputs``
    values, or (``labels`` integers) by cross-entropy over ``outputs`` logits; its inputs
    standardised by the states' mean and spread where ``standardise``."""
    torch.manual_seed(0)
    mean, spread = states.mean(0), states.std(0) + 1e-8
    if not standardise:
        mean, spread = np.zeros_like(mean), np.ones_like(spread)
    net = torch.nn.Sequential(
        torch.nn.Linear(states.shape[1], width),
        torch.nn.Tanh(),
        torch.nn.Linear(width, width),
        torch.nn.Tanh(),
        torch.nn.Linear(width, outputs),
    )
    optimizer = torch.optim.Adam(net.parameters(), 1e-3)
    x = torch.as_tensor((states - mean) / spread)
    discrete = np.issubdtype(labels.dtype, np.integer)
    y = torch.as_tensor(labels) if discrete else torch.as_tensor(labels, dtype=torch.float32)
    generator = torch.Generator().manual_seed(0)
    for _ in range(steps):
        rows = torch.randint(len(x), (256,), generator=generator)
        out = net(x[rows])
        if discrete:
            loss = torch.nn.functional.cross_entropy(out, y[rows])
        else:
            loss = ((out - y[rows]) ** 2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return torch.nn.Sequential(Standardise(mean, spread), net)


class Standardise(torch.nn.Module):
    """(x - mean) / spread, with the statistics of the fitted states."""

    def __init__(self, mean: np.ndarray, spread: np.ndarray) -> None:
        super().__init__()
        self.mean, self.spread = torch.as_tensor(mean), torch.as_tensor(spread)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.mean) / self.spread


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    envs = [e for e in teacher_sweep.SWEEP if e != teacher_sweep.DOORKEY]
    parser.add_argument("--env", default="Pendulum-v1", choices=envs)
    env_id = parser.parse_args().env
    torch.set_num_threads(1)
    path = ROOT / "results/teacher-sweep/teachers" / env_id / "q1.pt"
    teacher = teacher_sweep.load_teacher_model(env_id, path)
    env = gym.make(env_id)
    space = env.action_space
    box = isinstance(space, gym.spaces.Box)
    standardise = not declares_unit_scale(env.observation_space)

    def label(batch: np.ndarray) -> np.ndarray:
        return teacher.predict(batch, deterministic=True)[0]

    print(f"the teacher: {peers.evaluate(label, env_id, 30).mean():.1f}", flush=True)
    for width in (64, 256):
        states = rollouts(env_id, label, 100, 0.3 if box else 0.1, seed=1)
        for round_ in range(3):
            labels = label(states) if box else label(states).astype(np.int64)
            net = fit(width, states, labels, space.shape[0] if box else int(space.n), standardise)

            def act(batch: np.ndarray, net: torch.nn.Module = net) -> np.ndarray:
                with torch.no_grad():
                    out = net(torch.as_tensor(np.asarray(batch), dtype=torch.float32)).numpy()
                return np.clip(out, space.low, space.high) if box else out.argmax(1)

            score = peers.evaluate(act, env_id, 30).mean()
            print(f"{width}x{width}, round {round_}: {len(states)} states, greedy {score:.1f}")
            states = np.concatenate([states, rollouts(env_id, act, 50, 0.0, seed=10 + round_)])


if __name__ == "__main__":
    main()
