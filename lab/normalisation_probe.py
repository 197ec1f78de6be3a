"""Does running observation normalisation cost PPO's own learning on an environment? Two probes
behind ``normalize_obs: auto``'s unit-scale rule (issue 63, Pendulum):

* ``sb3``: SB3 PPO with its defaults (as the teacher sweep's PPO alone) inside
  ``VecNormalize(norm_obs=True, norm_reward=False)``: does the normalisation cost SB3's PPO too?
* ``frozen``: TL-AC with no teachers and ``normalize_obs: true``, its statistics frozen after the
  first ``--freeze`` steps: is it the statistics' drift that costs, or the scaling itself?

Each prints the greedy student over the user suite's 30 evaluation episodes
(benchmarks/user_envs.py), as lab/no_teachers.py does for TL-AC's own settings:

    .venv/bin/python lab/normalisation_probe.py sb3 Pendulum-v1 0
    .venv/bin/python lab/normalisation_probe.py frozen Pendulum-v1 0 --freeze 2048
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import peers
import user_envs

from tlac import TLAC


def sb3_with_vec_normalize(env_id: str, seed: int, steps: int) -> Any:
    """SB3 PPO (its defaults) trained inside VecNormalize; returns its greedy batch policy."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = VecNormalize(DummyVecEnv([lambda: gym.make(env_id)]), norm_obs=True, norm_reward=False)
    model = PPO("MlpPolicy", venv, seed=seed, device="cpu")
    model.learn(steps)
    venv.training = False
    return lambda obs: model.predict(venv.normalize_obs(np.asarray(obs)), deterministic=True)[0]


def tlac_frozen_statistics(env_id: str, seed: int, steps: int, freeze: int) -> Any:
    """TL-AC with no teachers, normalised observations whose statistics stop after ``freeze``
    steps; returns its greedy batch policy."""
    model = TLAC(gym.make(env_id), teachers=[], seed=seed, normalize_obs=True)
    normalizer = model.nets.normalizer
    update = normalizer.update_obs
    seen = [0]

    def update_until_frozen(obs: np.ndarray) -> None:
        seen[0] += len(obs)
        if seen[0] <= freeze:
            update(obs)

    normalizer.update_obs = update_until_frozen
    model.learn(steps)
    return peers.greedy(model)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("probe", choices=["sb3", "frozen"])
    parser.add_argument("env")
    parser.add_argument("seed", type=int)
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--freeze", type=int, default=2048, help="frozen: steps of statistics")
    args = parser.parse_args()
    torch.set_num_threads(1)
    start = time.process_time()
    if args.probe == "sb3":
        act = sb3_with_vec_normalize(args.env, args.seed, args.steps)
        what = "SB3 PPO in VecNormalize"
    else:
        act = tlac_frozen_statistics(args.env, args.seed, args.steps, args.freeze)
        what = f"TL-AC, no teachers, statistics frozen after {args.freeze} steps"
    cpu = time.process_time() - start
    alone = user_envs.evaluate(act, args.env, user_envs.EVAL_EPISODES)
    print(
        f"{args.env} seed {args.seed}, {what}: student alone {alone.mean():.1f} "
        f"({args.steps} steps, {cpu:.0f} CPU s)",
        flush=True,
    )


if __name__ == "__main__":
    main()
