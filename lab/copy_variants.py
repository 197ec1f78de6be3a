"""Pendulum's q 0.97 SAC actor beside a random teacher (the sweep's ``q1+random``), TL-AC's default
with one variant's overrides, the student alone scored as the sweep scores it
(benchmarks/teacher_sweep.deployed_alone); one JSON per run under results/teacher-sweep/variants
(results/teacher-sweep/NOTES.md, "The copy's capacity"):

    .venv/bin/python lab/copy_variants.py batch256 0
"""

from __future__ import annotations

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
ENV_ID, CASE = "Pendulum-v1", "q1+random"


def main() -> None:
    from tlac import TLAC

    name, seed = sys.argv[1], int(sys.argv[2])
    if name not in VARIANTS:
        sys.exit(f"unknown variant {name!r}; expected one of {', '.join(VARIANTS)}")
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    out = ROOT / "results/teacher-sweep"
    teachers = teacher_sweep.case_teachers(ENV_ID, CASE, out, seed)
    model = TLAC(teacher_sweep.make_env(ENV_ID), teachers=teachers, seed=seed, **VARIANTS[name])
    model.learn(teacher_sweep.budget(ENV_ID))
    run = {"env": ENV_ID, "case": CASE, "variant": name, "seed": seed}
    run.update(teacher_sweep.deployed_alone(model, ENV_ID))
    dest = out / "variants" / f"{ENV_ID}__{CASE}__{name}__seed{seed}.json"
    dest.write_text(json.dumps(run, indent=1))
    print(f"{name} seed {seed}: student alone {run['student_alone']:.1f}")


if __name__ == "__main__":
    main()
