"""Throughput of TL-AC (with three teachers) against stable-baselines3 PPO, same settings.

Both run the paper's DoorKey preset (Table 5: 1 env, 16 steps per update, 5 epochs,
minibatch 16, RMSpropTFLike, [64, 64] networks) on the same DoorKey 7x7 environment, in one
process, one after the other, on one thread. TL-AC has three teachers (optimal, random,
random) and its high level; PPO has no teachers. Prints steps/s of each and their ratio.

    python benchmarks/throughput.py --steps 20000
"""

from __future__ import annotations

import argparse
import json
import time

import torch


def sb3_ppo_settings(preset: dict) -> dict:
    """The TL-AC preset expressed as stable-baselines3 PPO keyword arguments."""
    from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike

    arch = preset["net_arch_low"]
    return dict(
        n_steps=preset["n_steps"],
        batch_size=preset["batch_size"],
        n_epochs=preset["n_epochs"],
        learning_rate=preset["learning_rate"],
        clip_range=preset["clip_range"],
        target_kl=preset["target_kl"],
        ent_coef=preset["ent_coef"],
        vf_coef=preset["vf_coef"],
        max_grad_norm=preset["max_grad_norm"],
        gamma=preset["gamma"],
        gae_lambda=preset["gae_lambda"],
        normalize_advantage=preset["normalize_advantage"],
        policy_kwargs=dict(
            net_arch=dict(pi=arch, vf=arch),
            optimizer_class=RMSpropTFLike,
            optimizer_kwargs=dict(eps=preset["optimizer_eps"]),
        ),
    )


def time_tlac(steps: int, seed: int) -> float:
    from tlac import TLAC
    from tlac.presets import load_preset

    preset = load_preset("doorkey", "tlac")
    model = TLAC("doorkey", teachers=["optimal", "random", "random"], seed=seed, **preset)
    model.learn(1000, progress_bar=False)  # warm-up
    start = time.perf_counter()
    model.learn(steps, progress_bar=False)
    return steps / (time.perf_counter() - start)


def time_sb3_ppo(steps: int, seed: int) -> float:
    from stable_baselines3 import PPO

    from tlac.envs import get_domain
    from tlac.presets import load_preset
    from tlac.run import make_vec_env

    preset = load_preset("doorkey", "tlac")
    env = make_vec_env(get_domain("doorkey"), preset["n_envs"], seed, None)
    model = PPO("MlpPolicy", env, seed=seed, device="cpu", **sb3_ppo_settings(preset))
    model.learn(1008)  # warm-up
    start = time.perf_counter()
    model.learn(steps, reset_num_timesteps=False)
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    torch.set_num_threads(1)
    ppo = time_sb3_ppo(args.steps, args.seed)
    tlac = time_tlac(args.steps, args.seed)
    result = {"steps": args.steps, "tlac_steps_per_s": round(tlac, 1), "sb3_ppo_steps_per_s": round(ppo, 1),
              "ratio": round(tlac / ppo, 2), "torch": torch.__version__}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"TL-AC (3 teachers): {tlac:8.1f} steps/s")
        print(f"SB3 PPO           : {ppo:8.1f} steps/s")
        print(f"ratio TL-AC / PPO : {tlac / ppo:8.2f}")


if __name__ == "__main__":
    main()
