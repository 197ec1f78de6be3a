"""``tlac report DIR``: tables and figures of an experiment folder.

This module only orchestrates; the work is done by pure pieces it calls in order:

1. :func:`~tlac.experiments.rundata.read_experiment` reads the config, every run folder of the
   grid and the teachers' own returns (the only reading);
2. :mod:`~tlac.experiments.tables` computes the tables as DataFrames (the per-run summary,
   jumpstart per teacher set x algorithm as in the paper's Tables 1-3, final performance,
   IQM with stratified-bootstrap intervals, probability of improvement);
3. :mod:`~tlac.experiments.markdown` renders them as the sections of ``report.md``;
4. :mod:`~tlac.experiments.figures` lays out the figures (learning curves as in the paper's
   Figures 3-9, the student alone, IQM, performance profiles, the high-level ablation of
   Figure 11 and teacher usage per region of Figures 10 and 12) from the same data.

:func:`write_report` then writes every file; their names are defined here and nowhere else.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from tlac.errors import StorageError
from tlac.experiments import markdown as md
from tlac.experiments import tables as T
from tlac.experiments.markdown import fmt, fmt_mean_std
from tlac.experiments.rundata import (
    Experiment,
    RunData,
    load_experiment,
    read_experiment,
    read_run_folder,
)
from tlac.experiments.runner import EXPERIMENT_FILE
from tlac.experiments.tables import algorithm_label, final_window, summarize

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "FIGURES_DIR",
    "JUMPSTART_FILE",
    "REPORT_FILE",
    "SUMMARY_FILE",
    "RunData",
    "algorithm_label",
    "final_window",
    "fmt",
    "fmt_mean_std",
    "load_experiment",
    "load_paper_results",
    "summarize",
    "write_report",
]

REPORT_FILE = "report.md"
SUMMARY_FILE = "summary.csv"
JUMPSTART_FILE = "jumpstart.csv"
FIGURES_DIR = "figures"
CURVES_FIGURE = "curves.png"
STUDENT_FIGURE = "student_alone.png"
IQM_FIGURE = "iqm.png"
PROFILES_FIGURE = "profiles.png"
ABLATION_FIGURE = "ablation.png"
FIGURE_DPI = 110


def usage_figure_name(set_key: str, algo: str) -> str:
    """The file name of one (teacher set, algorithm) cell's teacher-usage figure."""
    return f"usage__{set_key}__{algo}.png"


def load_paper_results() -> dict[str, Any]:
    """The paper's jumpstarts (Tables 1-3) and its teachers' returns, ``paper_results.yaml``."""
    text = (resources.files("tlac.experiments") / "paper_results.yaml").read_text()
    return yaml.safe_load(text)


class _FigureWriter:
    """Saves figures into ``DIR/figures`` and returns the Markdown that shows each one."""

    def __init__(self, out: Path):
        self.dir = out / FIGURES_DIR
        self.dir.mkdir(exist_ok=True)

    def __call__(self, fig: Figure, name: str, caption: str) -> str:
        fig.tight_layout()
        fig.savefig(self.dir / name, dpi=FIGURE_DPI)
        return md.figure(f"{FIGURES_DIR}/{name}", caption)


def write_report(out_dir: str | Path, paper: bool = False) -> Path:
    """Write ``DIR/report.md``, ``DIR/summary.csv``, ``DIR/jumpstart.csv`` (when the grid has a
    no-advice baseline) and ``DIR/figures/*.png`` for the experiment in ``out_dir``, or for
    the one run of a run folder that ``tlac train`` wrote (its ``config.yaml``); with
    ``paper``, the paper's values beside ours. Returns the report's path."""
    import matplotlib

    matplotlib.use("Agg")
    out = Path(out_dir)
    one_run = not (out / EXPERIMENT_FILE).exists() and (out / "config.yaml").is_file()
    exp = read_run_folder(out) if one_run else read_experiment(out)
    try:
        return _write_report(out, exp, paper)
    except OSError as exc:  # a read-only folder, a full disk, report.md a folder
        raise StorageError(
            f"cannot write the report into {str(out)!r}: {exc.filename or out}: {exc.strerror}"
        ) from None


def _write_report(out: Path, exp: Experiment, paper: bool) -> Path:
    """:func:`write_report` once the experiment is read: every file it writes."""
    from tlac.experiments import figures as F

    c = exp.config
    paper_data = load_paper_results() if paper else None
    save = _FigureWriter(out)

    # the tables
    summary = summarize(c, exp.runs)
    jumpstart = None
    if c.baseline is not None:
        rows = paper_data["domains"].get(c.domain, {}).get("rows", {}) if paper_data else None
        jumpstart = T.jumpstart_table(exp, rows)
    teachers = None
    if exp.teachers:
        paper_teachers = paper_data.get("teachers", {}).get(c.domain, {}) if paper_data else None
        teachers = T.teachers_table(exp.teachers, paper_teachers)

    # report.md, section by section, each figure after the section it belongs to
    sections = [md.status_section(c, T.status_counts(exp), T.seed_counts(exp), T.failed_runs(exp))]
    if teachers is not None:
        sections.append(md.teachers_section(teachers))
    source = paper_data["source"] if paper_data else None
    sections.append(md.jumpstart_section(c, jumpstart, source))
    sections.append(md.performance_section(c, T.performance_table(exp, summary)))
    if len(summary):
        iqm = T.iqm_table(exp, summary)
        sections.append(md.iqm_section(c, iqm))
        caption = md.iqm_caption(F.iqm_uses_normalised(iqm))
        sections.append(save(F.iqm_figure(exp, iqm), IQM_FIGURE, caption))
    if T.compared_algos(exp, summary):
        sections.append(md.comparisons_section(c, T.improvement_table(exp, summary)))
        profiles = F.profile_panels(exp, summary)
        if any(curves for curves, _ in profiles.values()):
            fig = F.profiles_figure(profiles)
            sections.append(save(fig, PROFILES_FIGURE, md.PROFILES_CAPTION))

    sections.append("## Learning curves")
    grid = T.curve_grid(c)
    panels = F.training_panels(exp, exp.advice_algos())
    if panels:
        caption = md.curves_caption(F.SMOOTHING_BINS, c.metrics.curve_points)
        sections.append(save(F.curves_figure(panels, grid), CURVES_FIGURE, caption))
    eval_grid = F.student_grid(exp)
    if eval_grid is not None:
        ylabel = "student-alone return per episode"
        fig = F.curves_figure(F.student_panels(exp, eval_grid), eval_grid, ylabel)
        sections.append(save(fig, STUDENT_FIGURE, md.student_caption(c.eval.episodes)))
    variants = T.tlac_variants(c)
    if len({c.algorithm(k).selector for k in variants}) > 1:
        sections.append("## Ablation of the high level")
        panels = F.training_panels(exp, variants, with_baseline=False)
        if panels:
            fig = F.curves_figure(panels, grid)
            sections.append(save(fig, ABLATION_FIGURE, md.ABLATION_CAPTION))
    sections.append("## Teacher usage")
    for u in F.usage_panels(exp):
        caption = md.usage_caption(c, u.algo, u.teacher_set, u.seeds)
        sections.append(save(F.usage_figure(u), usage_figure_name(u.teacher_set, u.algo), caption))

    # the files
    if jumpstart is not None:
        jumpstart.to_csv(out / JUMPSTART_FILE, index=False)
    if len(summary):
        summary.to_csv(out / SUMMARY_FILE, index=False)
    path = out / REPORT_FILE
    path.write_text(md.document(sections))
    return path
