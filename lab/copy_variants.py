"""A sweep case (by default Pendulum's q 0.97 SAC actor beside a random teacher, ``q1+random``),
TL-AC's default with one variant's overrides, the student alone scored as the sweep scores it
(benchmarks/teacher_sweep.deployed_alone); one JSON per run under results/teacher-sweep/variants
(results/teacher-sweep/NOTES.md, "The copy's capacity"):

    .venv/bin/python lab/copy_variants.py batch256 0
    .venv/bin/python lab/copy_variants.py batch256 0 --env MountainCar-v0
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import teacher_sweep  # noqa: E402

VARIANTS = {
    "imitation-only": {"low_level_data": "silent", "wean_imitation": False},
    "unweaned-batch256": {"wean_imitation": False, "imitation_batch_size": 256},
    "batch256": {"imitation_batch_size": 256},
}


def main() -> None:
    from tlac import TLAC

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("variant", choices=list(VARIANTS))
    parser.add_argument("seed", type=int)
    parser.add_argument("--env", default="Pendulum-v1", choices=list(teacher_sweep.SWEEP))
    parser.add_argument("--case", default="q1+random", choices=list(teacher_sweep.CASES))
    args = parser.parse_args()
    name, seed, env_id, case = args.variant, args.seed, args.env, args.case
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    out = ROOT / "results/teacher-sweep"
    teachers = teacher_sweep.case_teachers(env_id, case, out, seed)
    model = TLAC(teacher_sweep.make_env(env_id), teachers=teachers, seed=seed, **VARIANTS[name])
    model.learn(teacher_sweep.budget(env_id))
    run = {"env": env_id, "case": case, "variant": name, "seed": seed}
    run.update(teacher_sweep.deployed_alone(model, env_id))
    dest = out / "variants" / f"{env_id}__{case}__{name}__seed{seed}.json"
    dest.write_text(json.dumps(run, indent=1))
    print(f"{name} seed {seed}: student alone {run['student_alone']:.1f}")


if __name__ == "__main__":
    main()
