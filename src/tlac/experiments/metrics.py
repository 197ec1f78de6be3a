"""Metrics of the paper's evaluation, as pure functions over arrays.

Training returns come from ``episodes.csv``: one ``(timestep, return)`` per finished training
episode, ``timestep`` being the total environment steps when it ended (teacher actions
included: the paper's "mean training reward", section 4.1).

* Jumpstart, total reward (area under the curve), time to threshold and final (asymptotic)
  performance follow Taylor & Stone, "Transfer Learning for Reinforcement Learning Domains: A
  Survey", JMLR 10, 2009, section 2.1.
* The interquartile mean and its stratified-bootstrap confidence interval follow Agarwal et
  al., "Deep Reinforcement Learning at the Edge of the Statistical Precipice", NeurIPS 2021
  (the ``rliable`` package): resample runs with replacement independently within each task,
  recompute the statistic, take percentiles of the resampled statistics.

>>> t, r = np.array([100, 250, 400]), np.array([0.0, 1.0, 0.5])
>>> initial_performance(t, r, window=300)
0.5
>>> float(iqm([1, 2, 3, 4, 100, 200, 300, 400]))
76.75
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd

ArrayLike = Any
Episodes = tuple[ArrayLike, ArrayLike]
"""``(timesteps, returns)`` of one run's finished training episodes."""


def _episodes(timesteps: ArrayLike, returns: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(timesteps, dtype=np.float64).reshape(-1)
    r = np.asarray(returns, dtype=np.float64).reshape(-1)
    if t.shape != r.shape:
        raise ValueError(f"timesteps and returns differ in length: {t.shape} vs {r.shape}")
    return t, r


def window_mean(timesteps: ArrayLike, returns: ArrayLike, start: float, end: float) -> float:
    """Mean return of the episodes that ended in the step window ``(start, end]``; NaN if none."""
    t, r = _episodes(timesteps, returns)
    mask = (t > start) & (t <= end)
    return float(r[mask].mean()) if mask.any() else float("nan")


def initial_performance(timesteps: ArrayLike, returns: ArrayLike, window: float = 10_000) -> float:
    """Mean training return over the first ``window`` steps (episodes ending at or before it)."""
    return window_mean(timesteps, returns, -np.inf, window)


def final_performance(
    timesteps: ArrayLike, returns: ArrayLike, total_steps: float, window: float
) -> float:
    """Mean training return over the last ``window`` steps of a ``total_steps`` run
    (Taylor & Stone's asymptotic performance, measured at the end of the budget)."""
    return window_mean(timesteps, returns, total_steps - window, np.inf)


def jumpstart(
    runs: Sequence[Episodes], baseline_runs: Sequence[Episodes], window: float = 10_000
) -> float:
    """Jumpstart (Taylor & Stone 2009): initial performance with advice minus initial performance
    of the no-advice baseline, each averaged over its runs (seeds) first. The initial
    performance of a run is its mean training return over the first ``window`` steps
    (:func:`initial_performance`); runs without a finished episode in the window are skipped.
    NaN when either side has no such run."""
    ours = [initial_performance(t, r, window) for t, r in runs]
    base = [initial_performance(t, r, window) for t, r in baseline_runs]
    ours = [v for v in ours if not np.isnan(v)]
    base = [v for v in base if not np.isnan(v)]
    if not ours or not base:
        return float("nan")
    return float(np.mean(ours) - np.mean(base))


def step_grid(total_steps: float, points: int = 100) -> np.ndarray:
    """``points`` equally spaced steps ending at ``total_steps``: ``total/points, ..., total``."""
    if points < 1:
        raise ValueError(f"points must be >= 1, got {points}")
    return np.linspace(total_steps / points, total_steps, points)


def binned_curve(timesteps: ArrayLike, returns: ArrayLike, grid: ArrayLike) -> np.ndarray:
    """A run's training curve on a common step grid.

    The value at ``grid[i]`` is the mean return of the episodes that ended in
    ``(grid[i-1], grid[i]]`` (``grid[-1]`` taken as minus infinity). A bin with no finished
    episode repeats the previous bin's value; bins before the first episode are NaN. This puts
    runs whose episodes end at different steps on one grid, so that seeds can be averaged.
    """
    t, r = _episodes(timesteps, returns)
    g = np.asarray(grid, dtype=np.float64)
    if np.any(np.diff(g) <= 0):
        raise ValueError("grid must be strictly increasing")
    # bin index of each episode: first grid point >= t; episodes after the grid are dropped
    idx = np.searchsorted(g, t, side="left")
    keep = idx < len(g)
    sums = np.bincount(idx[keep], weights=r[keep], minlength=len(g))
    counts = np.bincount(idx[keep], minlength=len(g))
    out = np.full(len(g), np.nan)
    last = np.nan
    for i in range(len(g)):
        if counts[i] > 0:
            last = sums[i] / counts[i]
        out[i] = last
    return out


def interpolated_curve(timesteps: ArrayLike, values: ArrayLike, grid: ArrayLike) -> np.ndarray:
    """Linear interpolation of a measured curve (e.g. ``eval.csv``'s student-alone returns) onto
    ``grid``; NaN outside the measured step range."""
    t, v = _episodes(timesteps, values)
    g = np.asarray(grid, dtype=np.float64)
    if len(t) == 0:
        return np.full(len(g), np.nan)
    order = np.argsort(t, kind="stable")
    t, v = t[order], v[order]
    out = np.interp(g, t, v)
    out[(g < t[0]) | (g > t[-1])] = np.nan
    return out


def mean_std(curves: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Mean and (population, ddof=0) standard deviation over runs of curves ``(runs, points)``,
    ignoring NaN (a point where no run has a value is NaN)."""
    c = np.asarray(curves, dtype=np.float64)
    if c.ndim == 1:
        c = c[None]
    n = np.sum(~np.isnan(c), axis=0)
    total = np.nansum(c, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n > 0, total / np.maximum(n, 1), np.nan)
        sq = np.nansum((c - mean) ** 2, axis=0)
        std = np.where(n > 0, np.sqrt(sq / np.maximum(n, 1)), np.nan)
    return mean, std


def area_under_curve(grid: ArrayLike, curve: ArrayLike, normalize: bool = False) -> float:
    """Area under a curve by the trapezoidal rule (Taylor & Stone's "total reward"), over the
    points where it is defined. ``normalize=True`` divides by the step span, giving the mean
    return over training (comparable across budgets)."""
    g, c = _episodes(grid, curve)
    ok = ~np.isnan(c)
    g, c = g[ok], c[ok]
    if len(g) < 2:
        return float("nan")
    area = float(np.sum((c[1:] + c[:-1]) * np.diff(g)) / 2.0)
    return area / float(g[-1] - g[0]) if normalize else area


def time_to_threshold(grid: ArrayLike, curve: ArrayLike, threshold: float) -> float:
    """First step of ``grid`` at which ``curve`` reaches ``threshold`` (>=); NaN if never."""
    g, c = _episodes(grid, curve)
    hit = np.flatnonzero(c >= threshold)  # NaN compares False
    return float(g[hit[0]]) if len(hit) else float("nan")


def iqm(scores: ArrayLike) -> float:
    """Interquartile mean (Agarwal et al. 2021): the mean of the middle 50% of all scores.

    Like ``scipy.stats.trim_mean(x, 0.25)``: sort, drop ``floor(0.25 * n)`` scores from each end,
    average the rest. NaN scores are ignored.
    """
    x = np.sort(np.asarray(scores, dtype=np.float64).reshape(-1))
    x = x[~np.isnan(x)]
    if len(x) == 0:
        return float("nan")
    cut = int(0.25 * len(x))
    return float(x[cut : len(x) - cut].mean())


def stratified_bootstrap_ci(
    scores: ArrayLike | Sequence[ArrayLike],
    statistic: Callable[[np.ndarray], float] = iqm,
    reps: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
) -> tuple[float, float, float]:
    """Point estimate and percentile confidence interval of ``statistic`` by the stratified
    bootstrap (Agarwal et al. 2021; ``rliable``'s ``StratifiedBootstrap``).

    ``scores`` is a ``(runs, tasks)`` array, or one 1-D array of run scores per task (tasks may
    have different numbers of runs). Each replicate resamples, within every task separately,
    as many runs as it has with replacement, then applies ``statistic`` to all resampled
    scores together. The interval is the ``(1 - confidence) / 2`` and ``(1 + confidence) / 2``
    percentiles of the ``reps`` replicates. ``seed`` fixes the random state, so a report is
    reproducible. Returns ``(statistic(scores), low, high)``.
    """
    if not isinstance(scores, np.ndarray) and all(np.ndim(s) == 0 for s in scores):
        scores = np.asarray(scores, dtype=np.float64)  # a flat list: one task
    if isinstance(scores, np.ndarray) and scores.ndim == 2:
        tasks = [scores[:, j] for j in range(scores.shape[1])]
    elif isinstance(scores, np.ndarray) and scores.ndim == 1:
        tasks = [scores]
    else:
        tasks = [np.asarray(s, dtype=np.float64).reshape(-1) for s in scores]
    tasks = [np.asarray(t, dtype=np.float64) for t in tasks if len(t) > 0]
    if not tasks:
        return float("nan"), float("nan"), float("nan")
    point = statistic(np.concatenate(tasks))
    rng = np.random.default_rng(seed)
    stats = np.empty(reps)
    for k in range(reps):
        sample = [t[rng.integers(0, len(t), size=len(t))] for t in tasks]
        stats[k] = statistic(np.concatenate(sample))
    alpha = (1.0 - confidence) / 2.0
    low, high = np.nanpercentile(stats, [100 * alpha, 100 * (1 - alpha)])
    return float(point), float(low), float(high)


def reuse_frequency(usage: pd.DataFrame, bin_width: float) -> pd.DataFrame:
    """Teacher reuse frequency over training, per region (paper, Figures 10 and 12).

    ``usage`` has ``teacher_usage.csv``'s columns ``timestep, region, choice, count`` (rows of
    one run or of several seeds concatenated). Windows are pooled into bins of ``bin_width``
    steps (a window ending at ``t`` falls into the bin ending at ``ceil(t / bin_width) *
    bin_width``); within each bin and region the result is each choice's share of all
    selections: ``fraction = count / sum of counts``. Returns columns
    ``step, region, choice, count, fraction`` sorted by region, step, choice.
    """
    if usage.empty:
        return pd.DataFrame(columns=["step", "region", "choice", "count", "fraction"])
    df = usage[["timestep", "region", "choice", "count"]].copy()
    df["step"] = np.ceil(df["timestep"].astype(float) / bin_width) * bin_width
    grouped = df.groupby(["region", "step", "choice"], as_index=False)["count"].sum()
    totals = grouped.groupby(["region", "step"])["count"].transform("sum")
    grouped["fraction"] = grouped["count"] / totals.where(totals > 0)
    return grouped[["step", "region", "choice", "count", "fraction"]].sort_values(
        ["region", "step", "choice"], ignore_index=True
    )


def first_step_reaching(timesteps: ArrayLike, values: ArrayLike, target: float) -> float:
    """The first timestep whose value is >= ``target`` (NaN if none): e.g. the steps until the
    student alone first matches the best single teacher's return (issue 8).

    >>> first_step_reaching([0, 10, 20, 30], [0.1, 0.5, 0.95, 0.9], 0.9)
    20.0
    >>> import math; math.isnan(first_step_reaching([0, 10], [0.1, 0.2], 0.9))
    True
    """
    t, v = np.asarray(timesteps, dtype=float), np.asarray(values, dtype=float)
    hit = np.flatnonzero(v >= target)
    return float(t[hit[0]]) if len(hit) else float("nan")


def moving_average(curve: ArrayLike, window: int) -> np.ndarray:
    """Trailing mean over the last ``window`` points (fewer at the start), ignoring NaN; the
    report smooths each seed's binned curve with it before averaging over seeds.

    >>> moving_average([0.0, 1.0, 2.0, 3.0], 2).tolist()
    [0.0, 0.5, 1.5, 2.5]
    """
    c = np.asarray(curve, dtype=np.float64)
    out = np.full_like(c, np.nan)
    for i in range(len(c)):
        part = c[max(0, i - window + 1) : i + 1]
        if np.any(~np.isnan(part)):
            out[i] = np.nanmean(part)
    return out


def bootstrap_mean_ci(
    curves: ArrayLike, confidence: float = 0.95, reps: int = 2000, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean over seeds of curves ``(seeds, points)`` and its percentile bootstrap interval
    (seeds resampled with replacement; NaN ignored). With one seed the interval is the mean.

    >>> mean, lo, hi = bootstrap_mean_ci([[0.0, 1.0], [2.0, 3.0]])
    >>> mean.tolist(), lo.tolist(), hi.tolist()
    ([1.0, 2.0], [0.0, 1.0], [2.0, 3.0])
    """
    c = np.atleast_2d(np.asarray(curves, dtype=np.float64))
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns stay NaN
        mean = np.nanmean(c, axis=0)
        rng = np.random.default_rng(seed)
        idx = rng.integers(0, len(c), size=(reps, len(c)))
        means = np.nanmean(c[idx], axis=1)  # (reps, points)
        alpha = (1.0 - confidence) / 2.0
        lo, hi = np.nanpercentile(means, [100 * alpha, 100 * (1 - alpha)], axis=0)
    return mean, lo, hi


def probability_of_improvement(x: Sequence[ArrayLike], y: Sequence[ArrayLike]) -> float:
    """P(X > Y) of Agarwal et al. (2021; rliable): for each task, the share of run pairs
    (one of X, one of Y) where X scores higher, ties counting half (the Mann-Whitney U
    statistic over the number of pairs); then the mean over tasks.

    >>> probability_of_improvement([[3.0, 1.0]], [[2.0, 1.0]])  # (1 + 1 + 0 + 0.5) / 4
    0.625
    >>> probability_of_improvement([[1.0], [0.0]], [[0.0], [1.0]])  # task means 1 and 0
    0.5
    """
    per_task = []
    for xs, ys in zip(x, y, strict=True):
        a, b = np.asarray(xs, dtype=np.float64), np.asarray(ys, dtype=np.float64)
        if len(a) == 0 or len(b) == 0:
            continue
        greater = (a[:, None] > b[None, :]).mean()
        ties = (a[:, None] == b[None, :]).mean()
        per_task.append(greater + 0.5 * ties)
    return float(np.mean(per_task)) if per_task else float("nan")


def performance_profile(scores: ArrayLike, taus: ArrayLike) -> np.ndarray:
    """The share of runs whose (normalised) score exceeds each threshold tau (rliable's
    run-score distribution).

    >>> performance_profile([0.2, 0.5, 0.9, 1.0], [0.0, 0.5, 0.95]).tolist()
    [1.0, 0.5, 0.25]
    """
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    return np.array([(s > t).mean() for t in np.asarray(taus, dtype=np.float64)])
