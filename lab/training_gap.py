"""Training return per window of steps, seed means, for two groups of run folders: the check of
issue 8's target "training return never more than 0.05 below the paper variant in any 1e4
window after 2e4 steps" (docs/graduation.md).

    python lab/training_gap.py 'results/graduation-doorkey-keep-best/runs/*' \\
        'results/graduation-doorkey/runs/*__paper__*' --steps 100000
"""

from __future__ import annotations

import argparse
import glob

import numpy as np
import pandas as pd

from tlac.experiments.metrics import window_mean


def window_means(pattern: str, window: int, start: int, steps: int) -> np.ndarray:
    """Seed-mean training return in each window (t, t + window], t = start, start + window, ...
    (episodes by the step they ended at, as the reports count them)."""
    runs = sorted(glob.glob(pattern))
    if not runs:
        raise SystemExit(f"error: no run folder matches {pattern!r}")
    edges = np.arange(start, steps, window)
    per_run = []
    for run in runs:
        ep = pd.read_csv(f"{run}/episodes.csv")
        per_run.append([window_mean(ep.timestep, ep["return"], t, t + window) for t in edges])
    return np.nanmean(np.array(per_run), axis=0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", help="glob of the run folders to check")
    parser.add_argument("reference", help="glob of the reference run folders (the paper variant)")
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--window", type=int, default=10_000)
    parser.add_argument("--start", type=int, default=20_000)
    args = parser.parse_args()
    ours = window_means(args.runs, args.window, args.start, args.steps)
    ref = window_means(args.reference, args.window, args.start, args.steps)
    for t, a, b in zip(range(args.start, args.steps, args.window), ours, ref, strict=True):
        print(f"[{t}, {t + args.window}): {a:.3f} vs {b:.3f} (gap {b - a:+.3f})")
    print(f"largest gap: {np.max(ref - ours):.3f}")


if __name__ == "__main__":
    main()
