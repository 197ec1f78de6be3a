"""Probe (issue 63): one DoorKey teacher-sweep case trained as the sweep trains it, its student
alone scored greedy and sampled every 2.5e4 steps (10 episodes) and at the end (30 episodes, the
sweep's final ones, and 100 sampled).

    .venv/bin/python lab/sampled_probe.py "q0.25+random" 1

Prints each point and writes sampled_CASE_SEED.json into ``--out``. The sampled evaluations
during training draw from the model's acting generator, which the training draws from too, so
the run is not the sweep's own run of that seed (the sweep scores the sampled student once,
after training).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import peers  # noqa: E402
import teacher_sweep as sweep  # noqa: E402

EVERY = 25_000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", choices=list(sweep.CASES))
    parser.add_argument("seed", type=int)
    parser.add_argument("--out", type=Path, default=Path("/tmp"))
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    env = sweep.DOORKEY
    model = sweep.make_learner(env, args.case, args.seed, ROOT / "results/teacher-sweep")
    greedy, sampled = sweep.greedy_act(model), peers.sampled(model)
    points: list[tuple[int, float, float]] = []

    def after_update(m) -> bool:
        if m.num_timesteps // EVERY > len(points):
            scores = [float(peers.evaluate(act, env, 10).mean()) for act in (greedy, sampled)]
            points.append((m.num_timesteps, *scores))
            print(points[-1], flush=True)
        return True

    start = time.time()
    model.learn(sweep.budget(env), callback=after_update)
    record = {
        "case": args.case,
        "seed": args.seed,
        "greedy30": float(peers.evaluate(greedy, env, 30).mean()),
        "sampled30": float(peers.evaluate(sampled, env, 30).mean()),
        "sampled100": float(peers.evaluate(sampled, env, 100).mean()),
        "points (steps, greedy, sampled)": points,
        "seconds": round(time.time() - start),
    }
    print(record, flush=True)
    (args.out / f"sampled_{args.case}_{args.seed}.json").write_text(json.dumps(record))


if __name__ == "__main__":
    main()
