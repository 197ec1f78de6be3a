"""Throughput of TL-AC (with three teachers) against stable-baselines3 PPO, same settings.

Both run the paper's DoorKey preset (Table 5: 1 env, 16 steps per update, 5 epochs,
minibatch 16, RMSpropTFLike, [64, 64] networks) on the same DoorKey 7x7 environment, in one
process, in alternating chunks, on one thread. TL-AC has three teachers (optimal, random,
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


def _timed(work) -> tuple[float, float]:
    """(wall seconds, CPU seconds of this process) spent in ``work()``."""
    wall, cpu = time.perf_counter(), time.process_time()
    work()
    return time.perf_counter() - wall, time.process_time() - cpu


def make_tlac(seed: int):
    from tlac import TLAC
    from tlac.presets import load_preset

    preset = load_preset("doorkey", "tlac")
    model = TLAC("doorkey", teachers=["optimal", "random", "random"], seed=seed, **preset)
    model.learn(1008, progress_bar=False)  # warm-up
    return lambda steps: model.learn(steps, progress_bar=False)


def make_sb3_ppo(seed: int):
    from stable_baselines3 import PPO

    from tlac.envs import get_domain
    from tlac.presets import load_preset
    from tlac.run import make_vec_env

    preset = load_preset("doorkey", "tlac")
    env = make_vec_env(get_domain("doorkey"), preset["n_envs"], seed, None)
    model = PPO("MlpPolicy", env, seed=seed, device="cpu", **sb3_ppo_settings(preset))
    model.learn(1008)  # warm-up
    return lambda steps: model.learn(steps, reset_num_timesteps=False)


def measure(steps: int, seed: int, rounds: int) -> dict[str, dict[str, float]]:
    """Alternate the two learners in ``rounds`` chunks of ``steps / rounds`` steps each, so
    that any background load on a shared machine falls on both alike."""
    learners = {"tlac": make_tlac(seed), "sb3_ppo": make_sb3_ppo(seed)}
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
    tlac, ppo = measured["tlac"], measured["sb3_ppo"]
    result = {
        "steps": args.steps,
        "tlac_steps_per_cpu_s": round(tlac["cpu"], 1),
        "sb3_ppo_steps_per_cpu_s": round(ppo["cpu"], 1),
        "ratio_cpu": round(tlac["cpu"] / ppo["cpu"], 2),
        "tlac_steps_per_wall_s": round(tlac["wall"], 1),
        "sb3_ppo_steps_per_wall_s": round(ppo["wall"], 1),
        "ratio_wall": round(tlac["wall"] / ppo["wall"], 2),
        "torch": torch.__version__,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"{'':20s} {'steps/CPU-s':>12s} {'steps/wall-s':>13s}")
        print(f"{'TL-AC (3 teachers)':20s} {tlac['cpu']:12.1f} {tlac['wall']:13.1f}")
        print(f"{'SB3 PPO':20s} {ppo['cpu']:12.1f} {ppo['wall']:13.1f}")
        print(
            f"{'ratio TL-AC / PPO':20s} {tlac['cpu'] / ppo['cpu']:12.2f} {tlac['wall'] / ppo['wall']:13.2f}"
        )


if __name__ == "__main__":
    main()
