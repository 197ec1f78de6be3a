"""Steps per CPU second of TL-AC and of SB3 PPO alone on a teacher-sweep case.

The sweep (benchmarks/teacher_sweep.py) records wall-clock seconds, which a loaded machine
decides more than the learners do. This times ``learn`` in CPU seconds of this process
(``time.process_time``: every thread), building each learner exactly as the sweep does (PPO
alone: SB3's defaults; a case: ``TLAC(env, teachers=case_teachers(...))`` with the sweep's
saved teachers), the learners interleaved over ``--repeats`` rounds, and prints the best
of each and TL-AC's CPU per step as a share of PPO's.

    .venv/bin/python benchmarks/cpu_per_step.py Acrobot-v1 q0.25+random adversarial+random
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import teacher_sweep  # (the sweep's teachers)


def steps_per_cpu_second(env_id: str, case: str, steps: int, seed: int, out: Path) -> float:
    """One ``learn`` of ``steps``: ``ppo`` (SB3 PPO alone) or a sweep case (TL-AC)."""
    import torch

    torch.set_num_threads(1)
    model = teacher_sweep.make_learner(env_id, case, seed, out)
    start = time.process_time()
    model.learn(steps)
    return model.num_timesteps / (time.process_time() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("env", choices=list(teacher_sweep.SWEEP))
    parser.add_argument("cases", nargs="+", choices=list(teacher_sweep.CASES))
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("results/teacher-sweep"))
    args = parser.parse_args()
    learners = ["ppo", *args.cases]
    best = dict.fromkeys(learners, 0.0)
    for round_ in range(args.repeats):
        for learner in learners:
            rate = steps_per_cpu_second(args.env, learner, args.steps, args.seed, args.out)
            best[learner] = max(best[learner], rate)
            print(f"round {round_ + 1}: {learner} {rate:.0f} steps per CPU second", flush=True)
    print(f"{args.env}, {args.steps} steps, seed {args.seed}, best of {args.repeats}:")
    for learner in learners:
        share = best["ppo"] / best[learner]
        note = "" if learner == "ppo" else f" (CPU per step {share:.2f}x PPO alone's)"
        print(f"  {learner}: {best[learner]:.0f} steps per CPU second{note}")


if __name__ == "__main__":
    main()
