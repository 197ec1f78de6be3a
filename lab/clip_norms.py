"""How often the gradient clip binds in a TL-AC run: the norm of each update's gradient before
``max_grad_norm`` clips it, by fifths of the updates.

    python lab/clip_norms.py --steps 8000                          # the default on DoorKey
    python lab/clip_norms.py --steps 8000 --set distill_coef=0     # without the imitation term

DoorKey 1 optimal + 2 random, seed 0 (results/graduation-doorkey-clip/NOTES.md)."""

from __future__ import annotations

import argparse
import tempfile

import numpy as np
import torch
import yaml

import tlac.two_level.steps as steps
from tlac.run import RunSpec, train_run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="doorkey")
    parser.add_argument("--teachers", default="optimal,random,random")
    parser.add_argument("--steps", type=int, default=8000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    torch.set_num_threads(1)
    overrides = {}
    for item in args.set:
        key, value = item.split("=", 1)
        overrides[key] = yaml.safe_load(value)

    norms: list[float] = []
    clip = steps.clip_grad_norm

    def recording_clip(grads: list[torch.Tensor], max_norm: float) -> torch.Tensor:
        norm = clip(grads, max_norm)
        norms.append(float(norm))
        return norm

    steps.clip_grad_norm = recording_clip  # the joint rule's clip (the graduate variant's)
    spec = RunSpec(
        env=args.env,
        teachers=args.teachers.split(","),
        steps=args.steps,
        seed=args.seed,
        overrides=overrides,
    )
    with tempfile.TemporaryDirectory() as out:
        train_run(spec, out)
    bound = float(overrides.get("max_grad_norm", 0.5))  # every preset's clip is 0.5
    values = np.asarray(norms)
    for part in np.array_split(np.arange(len(values)), 5):
        chunk = values[part]
        print(
            f"updates {part[0]}-{part[-1]}: median norm {np.median(chunk):.2f}, "
            f"90th percentile {np.percentile(chunk, 90):.2f}, clipped {np.mean(chunk > bound):.2f}"
        )


if __name__ == "__main__":
    main()
