"""Markdown of the report: the frames of :mod:`tlac.experiments.tables` in, text out. Pure:
the number formatting, the table syntax and each section's wording live here, and nothing
reads or writes a file.

>>> print(markdown_table(["a", "b"], [["1", "2"]]))
| a | b |
|---|---|
| 1 | 2 |
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import pandas as pd

from tlac.experiments.config import ExperimentConfig
from tlac.experiments.tables import MIN_SEEDS, algorithm_label, final_window, set_label


def fmt(x: Any) -> str:
    """A number for a table: 3 significant-ish digits, ``n/a`` for missing.

    >>> fmt(0.12345), fmt(3.14159), fmt(1234.5), fmt(None), fmt(float("nan"))
    ('0.123', '3.14', '1234.5', 'n/a', 'n/a')
    """
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "n/a"
    x = float(x)
    if abs(x) >= 100:
        return f"{x:.1f}"
    if abs(x) >= 1:
        return f"{x:.2f}"
    return f"{x:.3f}"


def fmt_mean_std(values: pd.Series) -> str:
    """``mean ± std (n=N)`` of the non-missing values; ``n/a`` when there is none."""
    v = values.dropna().to_numpy(float)
    if len(v) == 0:
        return "n/a"
    return fmt_stats(v.mean(), v.std(), len(v))


def fmt_stats(mean: float, std: float, n: int) -> str:
    """``mean ± std (n=N)`` from the three numbers; ``n/a`` when ``n`` is 0.

    >>> fmt_stats(0.75, 0.15, 2), fmt_stats(float("nan"), float("nan"), 0)
    ('0.750 ± 0.150 (n=2)', 'n/a')
    """
    if n == 0:
        return "n/a"
    return f"{fmt(mean)} ± {fmt(std)} (n={n})"


def fmt_step(step: float) -> str:
    """A step count: ``''`` when unknown (NaN), ``never`` when infinite, else with commas.

    >>> fmt_step(12500.0), fmt_step(float("inf")), fmt_step(float("nan"))
    ('12,500', 'never', '')
    """
    if math.isnan(step):
        return ""
    return "never" if math.isinf(step) else f"{step:,.0f}"


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A GitHub-flavoured Markdown table of already formatted cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def figure(path: str, caption: str) -> str:
    """An image with its caption below it in italics."""
    return f"![{caption}]({path})\n\n*{caption}*"


def document(sections: Sequence[str]) -> str:
    """The whole report: the sections separated by blank lines, ending with a newline."""
    return "\n\n".join(sections) + "\n"


# ------------------------------------------------------------------------------- sections


def status_section(
    config: ExperimentConfig, counts: pd.Series, seeds: pd.DataFrame, failed: pd.DataFrame
) -> str:
    """The title, what was run and how many runs are in each status, the definitions of the
    windows, a warning naming the cells with fewer than ``MIN_SEEDS`` finished seeds, and the
    failed runs with their errors (``counts``: :func:`~tlac.experiments.tables.status_counts`,
    ``seeds``: :func:`~tlac.experiments.tables.seed_counts`, ``failed``:
    :func:`~tlac.experiments.tables.failed_runs`)."""
    c = config
    parts = [f"{n} {s}" for s, n in counts.items()]
    text = [
        f"# Experiment report: {c.name}",
        "",
        c.description or "",
        "",
        f"Domain `{c.domain}`, {c.steps:,} environment steps per run, seeds "
        f"{', '.join(map(str, c.seeds))}; baseline for the jumpstart: `{c.baseline}`. "
        f"Runs: {int(counts.sum())} declared, " + ", ".join(parts) + ".",
        "",
        f"Training return = return of finished training episodes, teacher actions included "
        f"(the paper's training reward). Initial window (jumpstart): the first "
        f"{c.metrics.jumpstart_window:,} steps; final window: the last {final_window(c):,} steps. "
        f"Student alone = the low-level policy without any teacher"
        f"{MODE_WORDS.get(c.eval.deploy, '')} ({c.eval.episodes} episodes per evaluation).",
    ]
    thin = seeds[seeds.finished < MIN_SEEDS]
    few = sorted(
        {
            f"{set_label(c, s)} / {algorithm_label(c, a)} (n={n})"
            for s, a, n in zip(thin.teacher_set, thin.algo, thin.finished, strict=True)
        }
    )
    if few:
        text += [
            "",
            f"**Warning: {len(few)} cell(s) have fewer than {MIN_SEEDS} finished seeds**; "
            "their means, bands and intervals are not reliable: " + "; ".join(few) + ".",
        ]
    if len(failed):
        text += ["", "Failed runs:", ""]
        text += [f"- `{run}`: {error}" for run, error in zip(failed.run, failed.error, strict=True)]
    return "\n".join(text)


def _paper_teacher(p: dict[str, Any] | None) -> str:
    if p is None:
        return "not stated"
    text = fmt(p["mean"])
    if "std" in p:
        text += f" ± {fmt(p['std'])}"
    if "note" in p:
        text += f" ({p['note']})"
    return text


def teachers_section(table: pd.DataFrame) -> str:
    """Each teacher alone (:func:`~tlac.experiments.tables.teachers_table`), with the paper's
    column when the table has one."""
    paper = "paper" in table
    header = ["teacher", "mean return", "std", "episodes"] + (["paper"] if paper else [])
    rows = []
    for r in table.to_dict("records"):
        row = [f"`{r['teacher']}`", fmt(r["mean"]), fmt(r["std"]), str(r["episodes"])]
        if paper:
            row.append(_paper_teacher(r["paper"]))
        rows.append(row)
    note = "Each teacher alone (no learner), measured once per grid."
    if paper:
        note += " Paper: its appendix A (A.1.1, A.2.1, A.3.1)."
    return "## Teachers\n\n" + note + "\n\n" + markdown_table(header, rows)


def jumpstart_section(
    config: ExperimentConfig, table: pd.DataFrame | None, paper_source: str | None = None
) -> str:
    """Jumpstart per teacher set (rows) and advice algorithm (columns) from
    :func:`~tlac.experiments.tables.jumpstart_table` (None: the grid has no baseline); with
    ``paper_source``, the paper's value for the same cell in brackets."""
    c = config
    if table is None:
        return "## Jumpstart\n\nNo no-advice baseline in the grid: jumpstart not computed."
    advice = [a.key for a in c.algorithms if not a.no_advice]
    cells = {}
    if len(table):
        cells = {
            (s, a): (js, p)
            for s, a, js, p in zip(
                table.teacher_set, table.algo, table.jumpstart, table.paper, strict=True
            )
        }
    header = ["teacher set"] + [f"`{a}`" for a in advice]
    rows = []
    for ts in c.teacher_sets:
        row = [set_label(c, ts.key)]
        for a in advice:
            if (ts.key, a) not in cells:
                row.append("")
                continue
            js, paper_value = cells[(ts.key, a)]
            cell = fmt(js)
            if paper_source is not None and not pd.isna(paper_value):
                cell += f" (paper {fmt(paper_value)})"
            row.append(cell)
        rows.append(row)
    note = (
        f"Mean training return over the first {c.metrics.jumpstart_window:,} steps minus that of "
        f"the no-advice baseline `{c.baseline}` (Taylor & Stone 2009), each averaged over seeds "
        f"(paper, Tables 1-3)."
    )
    if paper_source is not None:
        note += (
            f" In brackets: the paper's value for the same cell ({paper_source}); "
            "its initial window is not stated."
        )
    return "## Jumpstart\n\n" + note + "\n\n" + markdown_table(header, rows)


PERFORMANCE_METRICS = ("final_return", "student_final_return", "gap")


def _stats(r: dict[str, Any], name: str) -> str:
    return fmt_stats(r[f"{name}_mean"], r[f"{name}_std"], r[f"{name}_n"])


def performance_section(config: ExperimentConfig, table: pd.DataFrame) -> str:
    """Final performance per declared cell (:func:`~tlac.experiments.tables.performance_table`)."""
    c = config
    threshold = c.metrics.threshold is not None
    header = [
        "teacher set",
        "algorithm",
        "final training return",
        "student alone (final)",
        "gap: training - student",
        "student matches best teacher at",
        "mean return over training (AUC / steps)",
    ]
    if threshold:
        header.append(f"steps to reach {fmt(c.metrics.threshold)}")
    rows = []
    for r in table.to_dict("records"):
        row = [set_label(c, r["teacher_set"]), f"`{r['algo']}`"]
        if r["runs"] == 0:
            rows.append(row + ["no finished run", "", "", "", ""] + ([""] if threshold else []))
            continue
        row += [_stats(r, m) for m in PERFORMANCE_METRICS]
        row += [fmt_step(r["student_matches_at"]), _stats(r, "auc_mean_return")]
        if threshold:
            row.append(fmt_step(r["steps_to_threshold"]))
        rows.append(row)
    return (
        "## Performance\n\nMean ± standard deviation over seeds. Final training return: the last "
        f"{final_window(c):,} steps. Student alone: the last evaluation without teachers. "
        "Gap: final training return minus the student alone, per seed. Student matches best "
        "teacher: the first evaluation where the seed-mean student alone reaches the best "
        "single teacher's measured return. "
        "Time to threshold: first grid step where the seed-mean training curve reaches it.\n\n"
        + markdown_table(header, rows)
    )


def _interval(r: dict[str, Any], col: str) -> str:
    return f"{fmt(r[col])} [{fmt(r[col + '_low'])}, {fmt(r[col + '_high'])}]"


def iqm_section(config: ExperimentConfig, table: pd.DataFrame) -> str:
    """IQM per algorithm with its interval (:func:`~tlac.experiments.tables.iqm_table`)."""
    c = config
    header = [
        "algorithm",
        "IQM final training return [95% CI]",
        "IQM student alone [95% CI]",
        "the same / best teacher's return [95% CI]",
        "runs",
    ]
    rows = []
    for r in table.to_dict("records"):
        normalised = (
            f"training {_interval(r, 'final_return_norm')}; "
            f"student {_interval(r, 'student_final_return_norm')}"
        )
        rows.append(
            [
                algorithm_label(c, r["algo"]),
                _interval(r, "final_return"),
                _interval(r, "student_final_return"),
                normalised,
                str(r["runs"]),
            ]
        )
    return (
        "## Interquartile mean\n\nIQM over all runs of an algorithm (every teacher set and seed), "
        "with a 95% stratified-bootstrap confidence interval "
        f"({c.metrics.bootstrap_reps} resamples, "
        f"random state {c.metrics.bootstrap_seed}; runs resampled within each teacher set), as in "
        "Agarwal et al. 2021. Teacher sets have different ceilings, so the raw IQM mixes "
        "them; the normalised column divides each run's score by the best teacher's own "
        "return in its set first (runs without advice have no teacher: left out there)."
        "\n\n" + markdown_table(header, rows)
    )


def comparisons_section(config: ExperimentConfig, table: pd.DataFrame) -> str:
    """Probability of improvement between pairs of algorithms
    (:func:`~tlac.experiments.tables.improvement_table`); the heading alone when the table
    is empty (a single algorithm to compare)."""
    c = config
    title = "## Comparisons within teacher sets"
    if len(table) == 0:
        return title
    rows = [
        [
            algorithm_label(c, r["x"]),
            algorithm_label(c, r["y"]),
            str(r["teacher_sets"]),
            fmt(r["final_return"]),
            fmt(r["student_final_return"]),
        ]
        for r in table.to_dict("records")
    ]
    header = [
        "X",
        "Y",
        "teacher sets",
        "P(X > Y), final training return",
        "P(X > Y), student alone",
    ]
    text = (
        "Probability of improvement P(X > Y) (rliable): per teacher set, the share of "
        "(run of X, run of Y) pairs where X scores higher, ties half; then the mean over "
        "the teacher sets both ran. 0.5: no difference."
    )
    return "\n\n".join([title, text, markdown_table(header, rows)])


# ------------------------------------------------------------------------------- captions


def iqm_caption(normalised: bool) -> str:
    """Caption of the IQM figure; ``normalised`` when it shows scores / best teacher."""
    return "IQM with 95% stratified-bootstrap confidence intervals" + (
        ", each run's score divided by its teacher set's best teacher" if normalised else ""
    )


PROFILES_CAPTION = (
    "Performance profiles: the share of runs whose final score, divided by the best "
    "teacher's own return in their teacher set, exceeds tau (rliable)"
)
ABLATION_CAPTION = (
    "TL-AC's learned high level against random selection and UCB1 per episode (paper, Figure 11)"
)


def curves_caption(smoothing_bins: int, curve_points: int) -> str:
    """Caption of the training curves: how they were smoothed and what the bands are."""
    return (
        f"Mean training return over seeds per teacher set, each seed's curve smoothed over "
        f"{smoothing_bins} of {curve_points} bins "
        f"({smoothing_bins / curve_points:.0%} of the budget); bands: "
        "95% bootstrap interval of the mean (seeds resampled; the paper's Figures 3-9 show "
        "+-1 std); horizontal lines: each teacher's own return"
    )


MODE_WORDS = {
    "sampled": ", sampled",
    "choose": ", greedy or sampled, whichever scores higher at each evaluation",
}
"""How the student alone acts in a report's figures and tables (``eval.deploy``; greedy, the
default, goes unsaid)."""


def student_caption(episodes: int) -> str:
    """Caption of the student-alone curves (``episodes`` per evaluation)."""
    return (
        f"The student alone (no teacher): mean over seeds of {episodes}-episode "
        "evaluations, with the 95% bootstrap interval of the mean (seeds resampled)"
    )


def usage_caption(config: ExperimentConfig, algo: str, set_key: str, seeds: int) -> str:
    """Caption of one (algorithm, teacher set) cell's teacher-usage figure."""
    return (
        f"Teacher reuse frequency per region over training, `{algo}` with "
        f"{set_label(config, set_key)} (pooled over {seeds} seed(s); paper Figures 10, 12)"
    )
