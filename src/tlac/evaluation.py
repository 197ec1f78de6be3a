"""Evaluate the student alone (the low-level policy without any teacher): what a user deploys."""

from __future__ import annotations

from typing import Any

import numpy as np

from tlac.domains import Domain


def evaluate_policy(
    act: Any,
    domain: Domain,
    episodes: int,
    seed: int,
    n_envs: int = 1,
) -> np.ndarray:
    """Run ``act(obs_batch) -> actions`` for ``episodes`` full episodes on fresh environments
    seeded ``seed, seed+1, ...`` and return the undiscounted return of each episode."""
    envs = [domain.make_env() for _ in range(max(1, min(n_envs, episodes)))]
    returns: list[float] = []
    next_seed = seed
    try:
        obs, live, acc = [], [], []
        for env in envs:
            o, _ = env.reset(seed=next_seed)
            next_seed += 1
            obs.append(o)
            live.append(True)
            acc.append(0.0)
        started = len(envs)
        while any(live):
            idx = [i for i, alive in enumerate(live) if alive]
            actions = np.asarray(act(np.stack([obs[i] for i in idx])))
            for a, i in zip(actions, idx, strict=True):
                o, r, terminated, truncated, _ = envs[i].step(a)
                acc[i] += float(r)
                obs[i] = o
                if terminated or truncated:
                    returns.append(acc[i])
                    acc[i] = 0.0
                    if started < episodes:
                        obs[i], _ = envs[i].reset(seed=next_seed)
                        next_seed += 1
                        started += 1
                    else:
                        live[i] = False
    finally:
        for env in envs:
            env.close()
    return np.asarray(returns[:episodes], dtype=np.float64)


def evaluate_student(
    model: Any, domain: Domain, episodes: int, seed: int, deterministic: bool = True
) -> np.ndarray:
    """Returns of ``model.predict`` alone (no teacher) over ``episodes`` episodes."""
    return evaluate_policy(
        lambda o: model.predict(o, deterministic=deterministic)[0], domain, episodes, seed
    )
