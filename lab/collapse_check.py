"""Did any run of an experiment collapse? Issue 41's rule, run by run.

A run collapses when, after the best 5e4-step window of its training return, some later window
falls below half of that best (windows every 1e4 steps, each the mean return of the episodes
that end in it). Reads an experiment folder, its runs as folders or packed in runs.tar.xz.

    python lab/collapse_check.py results/graduation-doorkey-noisy-labels
"""

from __future__ import annotations

import argparse

import numpy as np

from tlac.experiments.rundata import read_experiment

WINDOW = 50_000
STRIDE = 10_000


def window_means(steps: np.ndarray, returns: np.ndarray) -> np.ndarray:
    """The mean return of the episodes ending in each window ``(start, start + WINDOW]``,
    ``start`` = 0, STRIDE, ... (windows without an episode are skipped).

    >>> window_means(np.array([10_000, 50_000, 60_000]), np.array([1.0, 0.0, 0.5])).tolist()
    [0.5, 0.25]
    """
    means = []
    for start in range(0, max(int(steps.max()) - WINDOW, 0) + 1, STRIDE):
        inside = (steps > start) & (steps <= start + WINDOW)
        if inside.any():
            means.append(float(returns[inside].mean()))
    return np.asarray(means)


def collapse(means: np.ndarray) -> tuple[float, float, bool]:
    """``(best window, worst window after it, collapsed)``: collapsed when the worst after the
    best is below half the best.

    >>> collapse(np.array([0.2, 0.9, 0.5, 0.4]))
    (0.9, 0.4, True)
    """
    best = int(means.argmax())
    worst_after = float(means[best:].min())
    return float(means[best]), worst_after, bool(worst_after < means[best] / 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", help="an experiment folder (tlac experiment run --out)")
    args = parser.parse_args()
    exp = read_experiment(args.folder)
    runs = exp.finished()
    for data in runs:
        episodes = data.episodes
        means = window_means(episodes["timestep"].to_numpy(), episodes["return"].to_numpy())
        best, worst, collapsed = collapse(means)
        print(
            f"{data.run.name}: best window {best:.3f}, worst after it {worst:.3f}, "
            f"last {means[-1]:.3f}{'  COLLAPSED' if collapsed else ''}"
        )
    print(f"{len(runs)} finished runs")


if __name__ == "__main__":
    main()
