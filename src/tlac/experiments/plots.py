"""Plain matplotlib plots of the report. Each function draws on the ``Axes`` it is given and
returns it (rliable's convention), so callers compose figures freely.

Lines differ by line style and marker as well as colour, so that the figures stay readable
when printed in black and white; standard-deviation bands are light and unhatched.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.axes import Axes

LINESTYLES = ("-", "--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1, 1, 1)))
MARKERS = ("o", "s", "^", "D", "v", "x", "P", "*")
COLORS = ("#1b9e77", "#d95f02", "#7570b3", "#000000", "#e7298a", "#66a61e", "#a6761d", "#666666")


def style(i: int) -> dict[str, object]:
    """Colour, line style and marker of the ``i``-th line (cycled)."""
    return {
        "color": COLORS[i % len(COLORS)],
        "linestyle": LINESTYLES[i % len(LINESTYLES)],
        "marker": MARKERS[i % len(MARKERS)],
    }


def plot_curves(
    ax: Axes,
    grid: np.ndarray,
    curves: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    references: Mapping[str, float] | None = None,
    title: str = "",
    xlabel: str = "environment steps",
    ylabel: str = "mean training return per episode",
    styles: Mapping[str, int] | None = None,
) -> Axes:
    """Learning curves: for each label ``(mean, low, high)``: the mean over seeds and a band
    (the report uses a 95% bootstrap interval of the mean; the paper's Figures 3-9 show +-1
    std), and optional horizontal reference lines (each teacher's own return). The legend is
    the caller's (:func:`legend_outside`)."""
    grid = np.asarray(grid, dtype=np.float64)
    n_markers = 8
    for i, (label, (mean, low, high)) in enumerate(curves.items()):
        st = style(styles[label] if styles and label in styles else i)
        mean = np.asarray(mean, dtype=np.float64)
        every = max(1, len(grid) // n_markers)
        ax.plot(grid, mean, label=label, linewidth=1.6, markevery=every, markersize=4, **st)
        ax.fill_between(grid, low, high, color=st["color"], alpha=0.15, linewidth=0)
    for j, (name, value) in enumerate((references or {}).items()):
        if value is None or not np.isfinite(value):
            continue
        ax.axhline(
            value, color="0.45", linewidth=0.9, linestyle=LINESTYLES[(j + 1) % len(LINESTYLES)]
        )
        ax.annotate(
            f"{name} {value:.3g}",
            xy=(1.0, value),
            xycoords=("axes fraction", "data"),
            xytext=(-2, 2),
            textcoords="offset points",
            ha="right",
            va="bottom",
            fontsize=7,
            color="0.3",
        )
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 3))
    ax.grid(True, color="0.9", linewidth=0.6)
    return ax


def legend_outside(ax: Axes) -> Axes:
    """The legend below the axes, never over the data."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(
            handles,
            labels,
            fontsize=7,
            loc="upper center",
            bbox_to_anchor=(0.5, -0.2),
            ncol=2,
            frameon=False,
        )
    return ax


def plot_profiles(
    ax: Axes,
    taus: np.ndarray,
    profiles: Mapping[str, np.ndarray],
    xlabel: str = "normalised score tau",
    title: str = "",
    styles: Mapping[str, int] | None = None,
) -> Axes:
    """Performance profiles (rliable): per label, the share of runs scoring above tau."""
    for i, (label, profile) in enumerate(profiles.items()):
        st = style(styles[label] if styles and label in styles else i)
        ax.plot(taus, profile, label=label, linewidth=1.6, markevery=max(1, len(taus) // 8), **st)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fraction of runs with score > tau")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(title, fontsize=10)
    ax.grid(True, color="0.9", linewidth=0.6)
    return ax


def plot_usage(
    ax: Axes, usage: pd.DataFrame, title: str = "", choices: Sequence[str] | None = None
) -> Axes:
    """Reuse frequency of each choice (a teacher, or ``agent``) over training in one region
    (paper, Figures 10 and 12). ``usage`` has columns ``step, choice, fraction``."""
    names = list(choices) if choices is not None else sorted(usage["choice"].unique())
    for i, name in enumerate(names):
        part = usage[usage["choice"] == name].sort_values("step")
        if part.empty:
            continue
        every = max(1, len(part) // 8)
        ax.plot(
            part["step"],
            part["fraction"],
            label=name,
            linewidth=1.4,
            markevery=every,
            markersize=4,
            **style(i),
        )
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("environment steps")
    ax.set_ylabel("fraction of selections")
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 3))
    ax.grid(True, color="0.9", linewidth=0.6)
    return ax


def plot_interval_estimates(
    ax: Axes,
    labels: Sequence[str],
    points: Sequence[float],
    lows: Sequence[float],
    highs: Sequence[float],
    xlabel: str = "IQM of final return",
    title: str = "",
    styles: Sequence[int] | None = None,
) -> Axes:
    """Point estimates with confidence intervals, one row per label (rliable's interval plot):
    a thick bar spans the interval, a black tick marks the estimate."""
    y = np.arange(len(labels))
    for i, (p, lo, hi) in enumerate(zip(points, lows, highs, strict=True)):
        st = style(styles[i] if styles is not None else i)
        ax.barh(
            i,
            hi - lo,
            left=lo,
            height=0.5,
            color=st["color"],
            alpha=0.45,
            edgecolor="black",
            linewidth=0.6,
        )
        ax.plot([p, p], [i - 0.3, i + 0.3], color="black", linewidth=2)
    ax.set_yticks(y, list(labels))
    ax.set_xlabel(xlabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, axis="x", color="0.9", linewidth=0.6)
    return ax
