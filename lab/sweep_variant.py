"""One teacher-sweep case trained with TL-AC settings on top of the default (issue 63's probes).

``benchmarks/teacher_sweep.py`` trains every case with TL-AC's defaults; this trains the case
``CASE`` of ``ENV`` (teachers from results/teacher-sweep/teachers, the sweep's own
``train_run``: the same curve, the same 30 final evaluation episodes) with ``SETTINGS`` (JSON)
passed to ``TLAC`` as well, and writes one JSON per seed under ``--out`` (skipped when there).
The setting ``"_step_weaning": true`` is not TL-AC's: it replaces the weaning's linear fade
(the copy's weight ``1 - competence``) by a step (the copy in full until the student's solo
episodes match the best teacher's led ones, then none), by patching ``SoloEpisodes.weaning``.

    .venv/bin/python lab/sweep_variant.py MountainCar-v0 q1+random nowean 0 1 2 3 4 \\
        --settings '{"wean_imitation": false}'
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import teacher_sweep as sweep  # noqa: E402

import tlac  # noqa: E402


def step_weaning() -> None:
    """``SoloEpisodes.weaning`` as a step: 1 (nothing copied) where the linear rule says 1
    (auditioning, no teacher helps, or a student at its best teacher's level), else 0."""
    from tlac.two_level import graduation

    linear = graduation.SoloEpisodes.weaning.fget
    graduation.SoloEpisodes.weaning = property(lambda self: float(linear(self) >= 1.0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", choices=list(sweep.SWEEP))
    parser.add_argument("case", choices=list(sweep.CASES))
    parser.add_argument("tag", help="the variant's name in the files' names")
    parser.add_argument("seeds", type=int, nargs="+")
    parser.add_argument("--settings", default="{}", help="JSON: TLAC keywords on top")
    parser.add_argument("--out", type=Path, default=ROOT / "results/teacher-sweep/variants")
    args = parser.parse_args()
    settings = json.loads(args.settings)
    if settings.pop("_step_weaning", False):
        step_weaning()
    tlac.TLAC = functools.partial(tlac.TLAC, **settings)
    args.out.mkdir(parents=True, exist_ok=True)
    for seed in args.seeds:
        dest = args.out / f"{args.env}__{args.case}__{args.tag}__seed{seed}.json"
        if dest.exists():
            continue
        run = sweep.train_run(args.env, args.case, seed, ROOT / "results/teacher-sweep", 4096, 10)
        run["settings"] = json.loads(args.settings)
        dest.write_text(json.dumps(run, indent=1))
        print(
            f"{args.tag} {args.env} {args.case} seed {seed}: {run['student_alone']:.1f}", flush=True
        )


if __name__ == "__main__":
    main()
