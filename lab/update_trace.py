"""Every update of one teacher-sweep case, traced (issue 63: Pendulum's adversarial + random,
seed 5, where the student fell below the random policy while no teacher was judged to help).

Trains the case as the sweep builds it (benchmarks/teacher_sweep.make_learner) for ``STEPS``
and prints, before each update, the audition's state (still auditioning, no teacher helps, the
weaning, each teacher's led episodes) and, after it, the imitation weight and loss it used and,
on a Box, the low level's mean action on the rollout's solo rows (mean of its absolute value):

    .venv/bin/python lab/update_trace.py Pendulum-v1 adversarial+random 5 --steps 8192
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import teacher_sweep  # noqa: E402

from tlac.two_level import update as update_module  # noqa: E402


def solo_mean_action(model: Any, rollout: Any) -> float | None:
    """The mean |low-level mean action| on the rollout's solo rows (Box actions), else None."""
    data = rollout.flat()
    solo = data["solo"].bool()
    if model.nets.discrete or not solo.any():
        return None
    obs = data["obs"] if model.nets.normalizer is None else data["net_obs"]
    with torch.no_grad():
        low_out = model.nets.heads(model.nets.update_rows(obs))[1]
    return float(low_out[solo].abs().mean())


def traced(original: Any) -> Any:
    def update(model: Any, rollout: Any, progress_remaining: float) -> dict[str, float]:
        solo = model.solo
        led = np.round(solo.led_sums / np.maximum(solo.led_counts, 1), 1).tolist()
        print(
            f"update at {model.num_timesteps}: auditioning {solo.auditioning}, "
            f"no teacher helps {solo.no_teacher_helps}, weaning {solo.weaning:.3f}, "
            f"led {led} x {solo.led_counts.tolist()}",
            flush=True,
        )
        out = original(model, rollout, progress_remaining)
        action = solo_mean_action(model, rollout)
        print(
            f"    imitation weight {out.get('train/distill_coef', 0.0):.3f}, "
            f"loss {out.get('train/imitation_loss', float('nan')):.2f}; "
            f"mean |action| on solo rows after it {'-' if action is None else f'{action:.2f}'}",
            flush=True,
        )
        return out

    return update


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", choices=list(teacher_sweep.SWEEP))
    parser.add_argument("case", choices=list(teacher_sweep.CASES))
    parser.add_argument("seed", type=int)
    parser.add_argument("--steps", type=int, default=8192)
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    update_module.update = traced(update_module.update)
    model = teacher_sweep.make_learner(
        args.env, args.case, args.seed, ROOT / "results/teacher-sweep"
    )
    if model.solo is None:
        parser.error(f"case {args.case!r} trains no TL-AC student with solo episodes")
    model.learn(args.steps)


if __name__ == "__main__":
    main()
