"""The report's figures in two steps: pure functions that compute what a figure shows from an
:class:`~tlac.experiments.rundata.Experiment` (curves with their bands, profiles, usage
frequencies), and functions that lay that data out on a new matplotlib ``Figure`` with the
``(ax, data) -> ax`` plots of :mod:`tlac.experiments.plots`. Nothing here saves a file: the
caller (:mod:`tlac.experiments.report`) does.

Figures are built with :class:`matplotlib.figure.Figure`, not pyplot, so that no global
figure state or interactive backend is involved.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from tlac.experiments import metrics as M
from tlac.experiments.plots import (
    legend_outside,
    plot_curves,
    plot_interval_estimates,
    plot_profiles,
    plot_usage,
)
from tlac.experiments.rundata import Experiment, RunData
from tlac.experiments.tables import (
    SCORES,
    algorithm_label,
    best_teacher_return,
    compared_algos,
    curve_grid,
    episodes,
    set_label,
    teacher_references,
)

SMOOTHING_BINS = 5
"""Training curves in the figures: each seed's binned curve (``curve_points`` bins over the
budget) is smoothed by a trailing mean over this many bins before the seeds are averaged."""
PROFILE_TAUS = np.linspace(0.0, 1.2, 61)
"""The normalised-score thresholds of the performance profiles."""

Band = tuple[np.ndarray, np.ndarray, np.ndarray]
"""``(mean, low, high)`` of a curve over seeds, each on the figure's step grid."""


@dataclass
class CurvePanel:
    """One panel of learning curves: a teacher set's curves by legend label, the style index
    of each label, and the set's teachers' own returns as reference lines."""

    title: str
    curves: dict[str, Band]
    styles: dict[str, int]
    references: dict[str, float]


@dataclass
class UsagePanel:
    """Teacher usage of one (algorithm, teacher set) cell, pooled over its seeds."""

    algo: str
    teacher_set: str
    title: str
    frequency: pd.DataFrame
    regions: list[str]
    choices: list[str]
    seeds: int


# --------------------------------------------------------------------------- data (pure)


def style_indices(exp: Experiment) -> dict[str, int]:
    """A fixed line style per algorithm entry (its position in the config), so that an
    algorithm looks the same in every figure."""
    return {k: i for i, k in enumerate(exp.algo_order())}


def curve_band(exp: Experiment, runs: list[RunData]) -> Band:
    """Each seed's binned training curve smoothed over ``SMOOTHING_BINS`` bins, then the mean
    over seeds with its 95% bootstrap interval."""
    grid = curve_grid(exp.config)
    curves = [M.moving_average(M.binned_curve(*episodes(d), grid), SMOOTHING_BINS) for d in runs]
    return M.bootstrap_mean_ci(np.array(curves))


def training_panels(
    exp: Experiment, algos: Sequence[str], with_baseline: bool = True
) -> list[CurvePanel]:
    """One panel per teacher set where one of ``algos`` finished a run: each algorithm's
    training curve band and, with ``with_baseline``, the no-advice baseline's."""
    c, styles = exp.config, style_indices(exp)
    sets = [s for s in exp.set_keys() if any(exp.finished(s, a) for a in algos)]
    base_runs = exp.baseline_runs() if with_baseline else []
    panels = []
    for s in sets:
        curves, panel_styles = {}, {}
        for a in algos:
            runs = exp.finished(s, a)
            if runs:
                label = f"{algorithm_label(c, a)} (n={len(runs)})"
                curves[label], panel_styles[label] = curve_band(exp, runs), styles[a]
        if base_runs:
            label = f"{algorithm_label(c, c.baseline)} (no advice, n={len(base_runs)})"
            curves[label] = curve_band(exp, base_runs)
            panel_styles[label] = styles.get(c.baseline, 0)
        panels.append(CurvePanel(set_label(c, s), curves, panel_styles, teacher_references(exp, s)))
    return panels


def student_grid(exp: Experiment) -> np.ndarray | None:
    """The evaluation steps of the student-alone figure (every ``eval.every`` steps and the
    last); None when there is nothing to draw: no evaluation, or no set with one."""
    c = exp.config
    sets = [s for s in exp.set_keys() if any(len(d.evals) for d in exp.finished(s))]
    if not sets or c.eval.episodes == 0:
        return None
    every = c.eval.every or c.steps
    grid = np.unique(np.append(np.arange(0, c.steps + 1, every, dtype=float), float(c.steps)))
    return grid if len(grid) >= 2 else None


def student_panels(exp: Experiment, grid: np.ndarray) -> list[CurvePanel]:
    """One panel per teacher set with evaluations: the student alone of each advice algorithm
    and of the baseline, interpolated onto ``grid``, mean over seeds with its 95% bootstrap
    interval (not smoothed)."""
    c, styles = exp.config, style_indices(exp)
    sets = [s for s in exp.set_keys() if any(len(d.evals) for d in exp.finished(s))]
    base_runs = exp.baseline_runs()
    panels = []
    for s in sets:
        curves, panel_styles = {}, {}
        groups = [(a, exp.finished(s, a)) for a in exp.advice_algos()]
        if base_runs:
            groups.append((c.baseline, base_runs))
        for a, runs in groups:
            ev = [
                M.interpolated_curve(d.evals["timestep"], d.evals["mean_return"], grid)
                for d in runs
                if len(d.evals)
            ]
            if ev:
                label = f"{algorithm_label(c, a)} (n={len(ev)})"
                curves[label] = M.bootstrap_mean_ci(np.array(ev))
                panel_styles[label] = styles.get(a, 0)
        panels.append(CurvePanel(set_label(c, s), curves, panel_styles, teacher_references(exp, s)))
    return panels


def profile_panels(
    exp: Experiment, summary: pd.DataFrame, taus: np.ndarray = PROFILE_TAUS
) -> dict[str, tuple[dict[str, np.ndarray], dict[str, int]]]:
    """Per score of :data:`~tlac.experiments.tables.SCORES`: each compared algorithm's
    performance profile (rliable) of its runs' scores divided by the best teacher's own return
    in their set, by legend label, and the style index of each label."""
    c, styles = exp.config, style_indices(exp)
    out = {}
    for col in SCORES:
        profiles, panel_styles = {}, {}
        for a in compared_algos(exp, summary):
            part = summary[summary.algo == a]
            best = part.teacher_set.map(lambda s: best_teacher_return(exp, s))
            scores = (part[col] / best).replace([np.inf, -np.inf], np.nan).dropna()
            if len(scores):
                label = f"{algorithm_label(c, a)} (n={len(scores)})"
                profiles[label] = M.performance_profile(scores.to_numpy(float), taus)
                panel_styles[label] = styles.get(a, 0)
        out[col] = (profiles, panel_styles)
    return out


def usage_panels(exp: Experiment) -> list[UsagePanel]:
    """Teacher reuse frequency per region (paper, Figures 10 and 12) of every (advice
    algorithm, teacher set) cell with usage logs, seeds pooled, in bins of at least the log
    interval and at most 1/50 of the budget."""
    c = exp.config
    bin_width = max(c.log_interval, c.steps / 50)
    panels = []
    for a in exp.advice_algos():
        for s in exp.set_keys():
            frames = [d.usage for d in exp.finished(s, a) if len(d.usage)]
            if not frames:
                continue
            freq = M.reuse_frequency(pd.concat(frames, ignore_index=True), bin_width)
            regions = [r for r in freq["region"].unique() if r != "all"] or ["all"]
            choices = list(dict.fromkeys(pd.concat(frames)["choice"]))
            title = f"{algorithm_label(c, a)}, {set_label(c, s)}: teacher usage"
            panels.append(UsagePanel(a, s, title, freq, regions, choices, len(frames)))
    return panels


def iqm_uses_normalised(iqm: pd.DataFrame) -> bool:
    """Whether the IQM figure shows scores divided by the best teacher: only when every
    algorithm has that IQM."""
    return all(np.isfinite(p) for p in iqm.get("final_return_norm", []))


# --------------------------------------------------------------------------- drawing


def _panel_figure(n: int) -> tuple[Figure, np.ndarray]:
    ncols = min(n, 2)
    nrows = math.ceil(n / ncols)
    fig = Figure(figsize=(5.2 * ncols, 4.3 * nrows))
    return fig, fig.subplots(nrows, ncols, squeeze=False)


def curves_figure(
    panels: Sequence[CurvePanel], grid: np.ndarray, ylabel: str | None = None
) -> Figure:
    """Learning-curve panels, two per row, each with its legend below it."""
    fig, axes = _panel_figure(len(panels))
    extra = {} if ylabel is None else {"ylabel": ylabel}
    for ax, p in zip(axes.flat, panels, strict=False):
        plot_curves(ax, grid, p.curves, p.references, title=p.title, styles=p.styles, **extra)
        legend_outside(ax)
    for ax in list(axes.flat)[len(panels) :]:
        ax.set_visible(False)
    return fig


def iqm_figure(exp: Experiment, iqm: pd.DataFrame) -> Figure:
    """The IQM of each algorithm with its interval, the final training return beside the
    student alone; normalised by the best teacher when :func:`iqm_uses_normalised`."""
    use_norm = iqm_uses_normalised(iqm)
    suffix = "_norm" if use_norm else ""
    unit = " / best teacher's return" if use_norm else " (per episode)"
    algos = list(iqm.algo) if len(iqm) else []
    styles = style_indices(exp)
    fig = Figure(figsize=(9, 0.6 * len(algos) + 1.6))
    axes = fig.subplots(1, 2, sharey=True)
    xlabels = ("IQM final training return", "IQM student-alone return")
    for ax, col, xlabel in zip(axes, SCORES, xlabels, strict=True):
        key = col + suffix
        points = iqm[key].tolist() if len(iqm) else []
        lows = iqm[f"{key}_low"].tolist() if len(iqm) else []
        highs = iqm[f"{key}_high"].tolist() if len(iqm) else []
        plot_interval_estimates(
            ax,
            [algorithm_label(exp.config, a) for a in algos],
            points,
            lows,
            highs,
            xlabel=xlabel + unit,
            styles=[styles[a] for a in algos],
        )
    return fig


def profiles_figure(
    profiles: Mapping[str, tuple[dict[str, np.ndarray], dict[str, int]]],
    taus: np.ndarray = PROFILE_TAUS,
) -> Figure:
    """Performance profiles (:func:`profile_panels`), one panel per score."""
    fig = Figure(figsize=(10.4, 4.0))
    axes = fig.subplots(1, 2, squeeze=False)
    whats = {"final_return": "training return", "student_final_return": "student alone"}
    for ax, (col, (curves, styles)) in zip(axes.flat, profiles.items(), strict=True):
        plot_profiles(
            ax, taus, curves, xlabel=f"{whats[col]} / best teacher's return", styles=styles
        )
        legend_outside(ax)
    return fig


def usage_figure(panel: UsagePanel) -> Figure:
    """One (algorithm, teacher set) cell's teacher usage, one panel per region."""
    n = len(panel.regions)
    fig = Figure(figsize=(4.6 * n, 4.0))
    axes = fig.subplots(1, n, squeeze=False)
    freq = panel.frequency
    for ax, region in zip(axes.flat, panel.regions, strict=True):
        plot_usage(
            ax, freq[freq.region == region], title=f"region: {region}", choices=panel.choices
        )
    legend_outside(axes.flat[0])
    fig.suptitle(panel.title, fontsize=10)
    return fig
