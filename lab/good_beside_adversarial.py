"""A teacher set the sweep does not hold: the sweep's best teacher beside its own mirror image (the
adversarial teacher), with TL-AC's default (issue 63: a teacher whose own episodes show harm
must not be copied beside one whose show help; results/teacher-sweep/NOTES.md, "A good teacher
beside its mirror image" and "A teacher that harms is left out of the copy").

Trains ``TLAC(env, teachers=[q1, adversarial], seed=S)`` for the sweep's budget and scores the
deployed student alone as the sweep does (benchmarks/teacher_sweep.deployed_alone), one JSON per
seed under ``--out`` (skipped when there); ``TAG`` names the code it ran (run it from a checkout
of the commit to compare):

    .venv/bin/python lab/good_beside_adversarial.py Pendulum-v1 HEAD 0 1 2 3 4
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", choices=[e for e in teacher_sweep.SWEEP if e != "DoorKey"])
    parser.add_argument("tag", help="the code's name in the files' names")
    parser.add_argument("seeds", type=int, nargs="+")
    parser.add_argument(
        "--out", type=Path, default=ROOT / "results/teacher-sweep/good-beside-adversarial"
    )
    args = parser.parse_args()
    from tlac import TLAC

    folder = ROOT / "results/teacher-sweep/teachers" / args.env
    args.out.mkdir(parents=True, exist_ok=True)
    for seed in args.seeds:
        dest = args.out / f"{args.env}__q1+adversarial__{args.tag}__seed{seed}.json"
        if dest.exists():
            continue
        torch.set_num_threads(1)
        torch.manual_seed(seed)
        best = teacher_sweep.load_teacher_model(args.env, folder / "q1.pt")
        mirror = teacher_sweep.Adversarial(
            teacher_sweep.load_teacher_model(args.env, folder / "q1.pt")
        )
        model = TLAC(teacher_sweep.make_env(args.env), teachers=[best, mirror], seed=seed)
        model.learn(teacher_sweep.budget(args.env))
        run = {"env": args.env, "seed": seed, "tag": args.tag}
        run.update(teacher_sweep.deployed_alone(model, args.env))
        dest.write_text(json.dumps(run, indent=1))
        print(f"{args.tag} {args.env} seed {seed}: student alone {run['student_alone']:.1f}")


if __name__ == "__main__":
    main()
