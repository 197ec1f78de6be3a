"""Throughput of TL-AC (with three teachers) against stable-baselines3 PPO, same settings.

Both run the paper's DoorKey preset (Table 5: 1 env, 16 steps per update, 5 epochs,
minibatch 16, RMSpropTFLike, [64, 64] networks) on the same DoorKey 7x7 environment, in one
process, in alternating chunks, on one thread. TL-AC has three teachers (optimal, random,
random) and its high level; PPO has no teachers. TL-AC is measured twice: its default
(variant graduate) and variant paper (Algorithm 1). Prints steps/s of each and the ratios.

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


def _timed(work) -> tuple[float, float]:
    """(wall seconds, CPU seconds of this process) spent in ``work()``."""
    wall, cpu = time.perf_counter(), time.process_time()
    work()
    return time.perf_counter() - wall, time.process_time() - cpu


def make_tlac(seed: int, variant: str):
    from tlac import TLAC
    from tlac.presets import load_preset

    preset = load_preset("doorkey", "tlac")
    model = TLAC(
        "doorkey", teachers=["optimal", "random", "random"], seed=seed, variant=variant, **preset
    )
    model.learn(1008, progress_bar=False)  # warm-up
    return lambda steps: model.learn(steps, reset_num_timesteps=False)


def make_sb3_ppo(seed: int):
    from stable_baselines3 import PPO

    from tlac.domains import get_domain, make_vec_env
    from tlac.presets import load_preset

    preset = load_preset("doorkey", "tlac")
    env = make_vec_env(get_domain("doorkey"), preset["n_envs"], seed, None)
    model = PPO("MlpPolicy", env, seed=seed, device="cpu", **sb3_ppo_settings(preset))
    model.learn(1008)  # warm-up
    return lambda steps: model.learn(steps, reset_num_timesteps=False)


def measure(steps: int, seed: int, rounds: int) -> dict[str, dict[str, float]]:
    """Alternate the two learners in ``rounds`` chunks of ``steps / rounds`` steps each, so
    that any background load on a shared machine falls on both alike."""
    learners = {
        "tlac": make_tlac(seed, "graduate"),
        "tlac_paper": make_tlac(seed, "paper"),
        "sb3_ppo": make_sb3_ppo(seed),
    }
    totals = {name: [0.0, 0.0] for name in learners}
    chunk = steps // rounds
    for _ in range(rounds):
        for name, learn in learners.items():
            wall, cpu = _timed(lambda learn=learn: learn(chunk))
            totals[name][0] += wall
            totals[name][1] += cpu
    done = chunk * rounds
    return {name: {"wall": done / w, "cpu": done / c} for name, (w, c) in totals.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--rounds", type=int, default=4, help="alternating chunks per learner")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    torch.set_num_threads(1)
    measured = measure(args.steps, args.seed, args.rounds)
    ppo = measured["sb3_ppo"]
    result: dict = {"steps": args.steps}
    for name in ("tlac", "tlac_paper", "sb3_ppo"):
        for clock in ("cpu", "wall"):
            result[f"{name}_steps_per_{clock}_s"] = round(measured[name][clock], 1)
    for name in ("tlac", "tlac_paper"):
        for clock in ("cpu", "wall"):
            suffix = "" if name == "tlac" else "_paper"
            result[f"ratio{suffix}_{clock}"] = round(measured[name][clock] / ppo[clock], 2)
    result["torch"] = torch.__version__
    if args.json:
        print(json.dumps(result))
        return
    labels = {
        "tlac": "TL-AC default",
        "tlac_paper": "TL-AC paper",
        "sb3_ppo": "SB3 PPO",
    }
    print(f"{'':16s} {'steps/CPU-s':>12s} {'steps/wall-s':>13s} {'/ PPO (CPU)':>12s}")
    for name, label in labels.items():
        m = measured[name]
        print(f"{label:16s} {m['cpu']:12.1f} {m['wall']:13.1f} {m['cpu'] / ppo['cpu']:12.2f}")


if __name__ == "__main__":
    main()
