"""Speed of AC-Teach (tlac's rebuild) beside stable-baselines3's closest off-policy learner.

Two measurements, one CPU thread each:

* ``run``: a whole ``tlac train --algo ac-teach`` run of ``--run-steps`` DoorKey steps with
  three teachers (optimal, random, random), start-up included (imports, networks, the final
  evaluation of 20 episodes): the issue's "5e3-step run" figure, in steps per wall-second and
  per CPU-second of that process (the CPU figure does not move with background load).
* ``learn``: ``learn()`` alone, in process, in alternating chunks (so that background load falls
  on both alike), steps per CPU-second: AC-Teach against SB3 DQN on DoorKey (the closest
  off-policy learner for discrete actions; its defaults) and against SB3 DDPG on hopper-bullet
  (AC-Teach's learner is DDPG; its defaults), each AC-Teach with the domain's preset and the
  teachers optimal, random, random.

    python benchmarks/ac_teach_speed.py --run-steps 5000 --steps 4000 --rounds 2

The hopper-bullet half needs PyBullet (``--domains doorkey`` skips it).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import torch
from throughput import _timed

TEACHERS = ["optimal", "random", "random"]
SB3_PEER = {"doorkey": "DQN", "hopper-bullet": "DDPG"}
"""Each domain's stable-baselines3 learner beside AC-Teach."""


def whole_run(steps: int, seed: int) -> dict[str, float]:
    """Steps per wall-second and per CPU-second of a whole ``tlac train`` AC-Teach run on
    DoorKey (a fresh process: start-up and the final evaluation included)."""
    with tempfile.TemporaryDirectory() as tmp:
        command = [
            sys.executable, "-m", "tlac", "train", "--algo", "ac-teach",
            "--teachers", ",".join(TEACHERS), "--steps", str(steps), "--seed", str(seed),
            "--out", str(Path(tmp) / "run"), "--no-progress",
        ]  # fmt: skip
        start, cpu = time.perf_counter(), _children_cpu()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - start
        return {"wall": steps / wall, "cpu": steps / (_children_cpu() - cpu)}


def _children_cpu() -> float:
    """CPU seconds (user + system) of this process's finished child processes."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def make_ac_teach(domain_name: str, seed: int):
    from tlac.baselines.ac_teach import ACTeach
    from tlac.domains import get_domain, make_teachers, make_vec_env
    from tlac.presets import load_preset

    domain = get_domain(domain_name)
    env = make_vec_env(domain, 1, seed, None)
    teachers = make_teachers(domain, TEACHERS, domain.make_env(), seed)
    preset = load_preset(domain.presets["ac-teach"], "ac-teach")
    model = ACTeach(env, teachers, seed=seed, **preset)
    return lambda steps: model.learn(steps, progress_bar=False)


def make_sb3_peer(domain_name: str, seed: int):
    import stable_baselines3

    from tlac.domains import get_domain, make_vec_env

    env = make_vec_env(get_domain(domain_name), 1, seed, None)
    model = getattr(stable_baselines3, SB3_PEER[domain_name])(
        "MlpPolicy", env, seed=seed, device="cpu"
    )
    return lambda steps: model.learn(steps, reset_num_timesteps=False)


def learn_rates(domain_name: str, steps: int, seed: int, rounds: int) -> dict[str, float]:
    """Steps per CPU-second of AC-Teach's and the SB3 peer's ``learn`` on one domain, after a
    warm-up chunk each (the replay buffers fill and both start training)."""
    learners = {
        "ac_teach": make_ac_teach(domain_name, seed),
        SB3_PEER[domain_name].lower(): make_sb3_peer(domain_name, seed),
    }
    chunk = steps // rounds
    for learn in learners.values():
        learn(chunk)  # warm-up
    cpu = dict.fromkeys(learners, 0.0)
    for _ in range(rounds):
        for name, learn in learners.items():
            cpu[name] += _timed(lambda learn=learn: learn(chunk))[1]
    return {name: chunk * rounds / seconds for name, seconds in cpu.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run-steps", type=int, default=5000, help="0 skips the whole run")
    parser.add_argument("--steps", type=int, default=4000, help="learn() steps per learner")
    parser.add_argument("--rounds", type=int, default=2, help="alternating chunks per learner")
    parser.add_argument("--domains", nargs="*", default=["doorkey", "hopper-bullet"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    unknown = sorted(set(args.domains) - set(SB3_PEER))
    if unknown:
        parser.error(f"--domains: unknown {unknown}; expected some of {sorted(SB3_PEER)}")
    torch.set_num_threads(1)
    result: dict = {"torch": torch.__version__}
    if args.run_steps:
        for clock, rate in whole_run(args.run_steps, args.seed).items():
            result[f"doorkey_run_steps_per_{clock}_s"] = round(rate, 1)
    for name in args.domains:
        for learner, rate in learn_rates(name, args.steps, args.seed, args.rounds).items():
            result[f"{name}_{learner}_steps_per_cpu_s"] = round(rate, 1)
    if args.json:
        print(json.dumps(result))
        return
    for key, value in result.items():
        print(f"{key:44s} {value}")


if __name__ == "__main__":
    main()
