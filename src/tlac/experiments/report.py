"""``tlac report DIR``: tables and figures of an experiment folder.

Two stages, as in rl-baselines3-zoo: :func:`summarize` reads every run folder of the grid into
one table of per-run metrics (written to ``DIR/summary.csv``); :func:`write_report` aggregates
it into ``DIR/report.md`` and ``DIR/figures/*.png``:

* jumpstart per teacher set x algorithm (paper, Tables 1-3), optionally beside the paper's;
* final training performance, mean +- std over seeds; the student alone (no teacher) at the end;
  area under the curve and time to threshold (Taylor & Stone 2009);
* interquartile mean with 95% stratified-bootstrap confidence intervals (Agarwal et al. 2021);
* learning curves per teacher set with std bands and each teacher's own return (Figures 3-9),
  the student-alone curves, teacher usage per region (Figures 10, 12) and the high-level
  ablation (Figure 11).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from tlac.errors import ConfigError, read_yaml_file
from tlac.experiments import metrics as M
from tlac.experiments.config import NO_TEACHERS, ExperimentConfig, parse_config
from tlac.experiments.grid import ERROR_FILE, GridRun, expand_grid, run_dir, run_status
from tlac.experiments.runner import EXPERIMENT_FILE, TEACHERS_FILE
from tlac.run import RESULT_FILE

REPORT_FILE = "report.md"
SUMMARY_FILE = "summary.csv"
FIGURES_DIR = "figures"


@dataclass
class RunData:
    """One run folder of the grid, read back."""

    run: GridRun
    status: str
    episodes: pd.DataFrame
    evals: pd.DataFrame
    usage: pd.DataFrame
    result: dict[str, Any] | None
    error: str | None


def _read_csv(path: Path, columns: list[str], required: bool = False) -> pd.DataFrame:
    """The CSV at ``path`` (an empty frame when absent or unreadable); with ``required`` (a
    finished run's files) an unreadable or malformed file is a ConfigError naming it."""
    df = _try_read_csv(path, columns)
    if required and df is None:
        raise ConfigError(
            f"{str(path)!r} is damaged (expected a CSV with columns {', '.join(columns)}); "
            "delete its run folder and rerun the grid to redo it"
        )
    return pd.DataFrame(columns=columns) if df is None else df


def _try_read_csv(path: Path, columns: list[str]) -> pd.DataFrame | None:
    try:
        df = pd.read_csv(path)
    except (OSError, UnicodeDecodeError, pd.errors.EmptyDataError, pd.errors.ParserError):
        return None
    missing = [c for c in columns if c not in df.columns]
    if missing:
        return None
    try:
        df[columns[0]] = pd.to_numeric(df[columns[0]])
    except (ValueError, TypeError):
        return None
    return df


def load_experiment(out_dir: str | Path) -> tuple[ExperimentConfig, list[RunData], dict[str, Any]]:
    """The experiment's config, every run of its grid (finished or not) and the teachers' own
    returns (``DIR/teachers.json``, empty if absent)."""
    out = Path(out_dir)
    cfg_path = out / EXPERIMENT_FILE
    if not cfg_path.exists():
        raise ConfigError(f"{out}: not an experiment folder ({EXPERIMENT_FILE} is missing)")
    config = parse_config(read_yaml_file(cfg_path, "experiment file"), str(cfg_path))
    runs = []
    for r in expand_grid(config):
        folder = run_dir(out, r)
        status = run_status(folder)
        result = json.loads((folder / RESULT_FILE).read_text()) if status == "finished" else None
        error = None
        if status == "failed":
            lines = (folder / ERROR_FILE).read_text().strip().splitlines()
            error = lines[-1] if lines else "unknown error"
        runs.append(
            RunData(
                run=r,
                status=status,
                episodes=_read_csv(
                    folder / "episodes.csv",
                    ["timestep", "return", "length"],
                    required=status == "finished",
                ),
                evals=_read_csv(
                    folder / "eval.csv", ["timestep", "mean_return", "std_return", "episodes"]
                ),
                usage=_read_csv(
                    folder / "teacher_usage.csv",
                    ["timestep", "region", "choice", "count", "fraction"],
                ),
                result=result,
                error=error,
            )
        )
    teachers_path = out / TEACHERS_FILE
    teachers = json.loads(teachers_path.read_text()) if teachers_path.exists() else {}
    return config, runs, teachers


def final_window(config: ExperimentConfig) -> int:
    """Steps of the final-performance window: the setting, or the last 10% of the budget."""
    return config.metrics.final_window or max(1, config.steps // 10)


def summarize(config: ExperimentConfig, runs: list[RunData]) -> pd.DataFrame:
    """One row of metrics per finished run: initial and final training performance, normalised
    area under the training curve, the student alone at the end, steps and wall time."""
    grid = M.step_grid(config.steps, config.metrics.curve_points)
    rows = []
    for d in runs:
        if d.status != "finished":
            continue
        t, r = d.episodes["timestep"].to_numpy(float), d.episodes["return"].to_numpy(float)
        curve = M.binned_curve(t, r, grid)
        res = d.result or {}
        rows.append(
            {
                "run": d.run.name,
                "teacher_set": d.run.teacher_set,
                "algo": d.run.algo,
                "seed": d.run.seed,
                "episodes": len(t),
                "initial_return": M.initial_performance(t, r, config.metrics.jumpstart_window),
                "final_return": M.final_performance(t, r, config.steps, final_window(config)),
                "auc_mean_return": M.area_under_curve(grid, curve, normalize=True),
                "student_final_return": _float(res.get("final_eval_mean")),
                "steps": res.get("steps"),
                "wall_time_s": res.get("wall_time_s"),
            }
        )
    return pd.DataFrame(rows)


def _float(v: Any) -> float:
    return float("nan") if v is None else float(v)


def fmt(x: Any) -> str:
    """A number for a table: 3 significant-ish digits, ``n/a`` for missing."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "n/a"
    x = float(x)
    if abs(x) >= 100:
        return f"{x:.1f}"
    if abs(x) >= 1:
        return f"{x:.2f}"
    return f"{x:.3f}"


def fmt_mean_std(values: pd.Series) -> str:
    v = values.dropna().to_numpy(float)
    if len(v) == 0:
        return "n/a"
    return f"{fmt(v.mean())} ± {fmt(v.std())} (n={len(v)})"


def _markdown_table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def load_paper_results() -> dict[str, Any]:
    """The paper's jumpstarts (Tables 1-3) and its teachers' returns, ``paper_results.yaml``."""
    text = (resources.files("tlac.experiments") / "paper_results.yaml").read_text()
    return yaml.safe_load(text)


ALGORITHM_NAMES = {
    "tlac": "TL-AC",
    "a2c": "A2C",
    "ppo": "PPO",
    "dqn-tlql": "DQN-TLQL",
    "ac-teach": "AC-Teach",
}
SELECTOR_NAMES = {"random": "random selection", "ucb1": "UCB1 per episode"}
SMOOTHING_BINS = 5
"""Training curves in the figures: each seed's binned curve (``curve_points`` bins over the
budget) is smoothed by a trailing mean over this many bins before the seeds are averaged."""
MIN_SEEDS = 5
"""Cells with fewer finished seeds than this get a warning in the report."""


def algorithm_label(config: ExperimentConfig, key: str) -> str:
    """How a figure names an algorithm entry: its config ``label`` as written, else the
    algorithm's usual name (with the TL-AC selector when it is not the learned one)."""
    entry = config.algorithm(key)
    if entry.key != entry.name and "__" not in entry.key:  # a label from the config
        return entry.key
    name = ALGORITHM_NAMES.get(entry.name, entry.name)
    if entry.selector != "learned":
        name += f" ({SELECTOR_NAMES.get(entry.selector, entry.selector)})"
    return name


def _label(config: ExperimentConfig, set_key: str) -> str:
    if set_key == NO_TEACHERS:
        return "none (no advice)"
    return config.teacher_set(set_key).label


class _Report:
    def __init__(self, out: Path, paper: bool):
        self.out = out
        self.paper = paper
        self.config, self.runs, self.teachers = load_experiment(out)
        self.summary = summarize(self.config, self.runs)
        self.grid = M.step_grid(self.config.steps, self.config.metrics.curve_points)
        self.fig_dir = out / FIGURES_DIR
        self.fig_dir.mkdir(exist_ok=True)
        self.advice_algos = [a.key for a in self.config.algorithms if not a.no_advice]
        self.algo_order = [a.key for a in self.config.algorithms]
        self.styles = {k: i for i, k in enumerate(self.algo_order)}
        self.sections: list[str] = []
        self.figures: list[str] = []

    # ---------------------------------------------------------------- helpers
    def finished(self, set_key: str | None = None, algo: str | None = None) -> list[RunData]:
        return [
            d
            for d in self.runs
            if d.status == "finished"
            and (set_key is None or d.run.teacher_set == set_key)
            and (algo is None or d.run.algo == algo)
        ]

    def cells(self) -> list[tuple[str, str]]:
        """(teacher set, algorithm) pairs that the grid declares, in grid order."""
        seen: list[tuple[str, str]] = []
        for d in self.runs:
            cell = (d.run.teacher_set, d.run.algo)
            if cell not in seen:
                seen.append(cell)
        return seen

    def set_keys(self) -> list[str]:
        return [ts.key for ts in self.config.teacher_sets]

    def episodes(self, d: RunData) -> tuple[np.ndarray, np.ndarray]:
        return d.episodes["timestep"].to_numpy(float), d.episodes["return"].to_numpy(float)

    def mean_curve(self, runs: list[RunData]) -> tuple[np.ndarray, np.ndarray]:
        curves = [M.binned_curve(*self.episodes(d), self.grid) for d in runs]
        return M.mean_std(np.array(curves))

    def curve_band(self, runs: list[RunData]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For the figures: each seed's binned curve smoothed over SMOOTHING_BINS bins, then
        the mean over seeds with its 95% bootstrap interval."""
        curves = [
            M.moving_average(M.binned_curve(*self.episodes(d), self.grid), SMOOTHING_BINS)
            for d in runs
        ]
        return M.bootstrap_mean_ci(np.array(curves))

    def save(self, fig: Any, name: str, caption: str) -> None:
        import matplotlib.pyplot as plt

        fig.tight_layout()
        fig.savefig(self.fig_dir / name, dpi=110)
        plt.close(fig)
        self.figures.append(name)
        self.sections.append(f"![{caption}]({FIGURES_DIR}/{name})\n\n*{caption}*")

    # ---------------------------------------------------------------- sections
    def status_section(self) -> None:
        counts = pd.Series([d.status for d in self.runs]).value_counts()
        parts = [f"{counts.get(s, 0)} {s}" for s in ("finished", "failed", "partial", "missing")]
        c = self.config
        text = [
            f"# Experiment report: {c.name}",
            "",
            c.description or "",
            "",
            f"Domain `{c.domain}`, {c.steps:,} environment steps per run, seeds "
            f"{', '.join(map(str, c.seeds))}; baseline for the jumpstart: `{c.baseline}`. "
            f"Runs: {len(self.runs)} declared, " + ", ".join(parts) + ".",
            "",
            f"Training return = return of finished training episodes, teacher actions included "
            f"(the paper's training reward). Initial window (jumpstart): the first "
            f"{c.metrics.jumpstart_window:,} steps; final window: the last {final_window(c):,} steps. "
            f"Student alone = the low-level policy without any teacher "
            f"({c.eval.episodes} episodes per evaluation).",
        ]
        few = sorted(
            {
                f"{_label(c, s)} / {algorithm_label(c, a)} (n={len(self.finished(s, a))})"
                for s, a in self.cells()
                if len(self.finished(s, a)) < MIN_SEEDS
            }
        )
        if few:
            text += [
                "",
                f"**Warning: {len(few)} cell(s) have fewer than {MIN_SEEDS} finished seeds**; "
                "their means, bands and intervals are not reliable: " + "; ".join(few) + ".",
            ]
        failed = [d for d in self.runs if d.status == "failed"]
        if failed:
            text += ["", "Failed runs:", ""] + [f"- `{d.run.name}`: {d.error}" for d in failed]
        self.sections.append("\n".join(text))

    def teachers_section(self) -> None:
        """Each teacher alone, as measured for this grid (``teachers.json``), beside the
        paper's value for the same teacher where it states one (with ``--paper``)."""
        if not self.teachers:
            return
        paper = (
            load_paper_results().get("teachers", {}).get(self.config.domain, {})
            if self.paper
            else {}
        )
        header = ["teacher", "mean return", "std", "episodes"] + (["paper"] if self.paper else [])
        rows = []
        for name, info in self.teachers.items():
            if "mean" not in info:
                continue
            row = [
                f"`{name}`",
                fmt(info["mean"]),
                fmt(info.get("std")),
                str(info.get("episodes", "")),
            ]
            if self.paper:
                p = paper.get(name)
                row.append(
                    "not stated"
                    if p is None
                    else fmt(p["mean"])
                    + (f" ± {fmt(p['std'])}" if "std" in p else "")
                    + (f" ({p['note']})" if "note" in p else "")
                )
            rows.append(row)
        note = "Each teacher alone (no learner), measured once per grid."
        if self.paper:
            note += " Paper: its appendix A (A.1.1, A.2.1, A.3.1)."
        self.sections.append("## Teachers\n\n" + note + "\n\n" + _markdown_table(header, rows))

    def jumpstart_section(self) -> None:
        c = self.config
        if c.baseline is None:
            self.sections.append(
                "## Jumpstart\n\nNo no-advice baseline in the grid: jumpstart not computed."
            )
            return
        base = [self.episodes(d) for d in self.finished(NO_TEACHERS, c.baseline)]
        paper_rows: dict[str, Any] = {}
        if self.paper:
            paper_rows = load_paper_results()["domains"].get(c.domain, {}).get("rows", {})
        header = ["teacher set"] + [f"`{a}`" for a in self.advice_algos]
        rows = []
        records = []
        for s in self.set_keys():
            row = [_label(c, s)]
            for a in self.advice_algos:
                runs = self.finished(s, a)
                if (s, a) not in self.cells():
                    row.append("")
                    continue
                js = M.jumpstart([self.episodes(d) for d in runs], base, c.metrics.jumpstart_window)
                cell = fmt(js)
                # the paper's cells are plain algorithms (learned high level, no custom label)
                paper_value = (
                    paper_rows.get(s, {}).get(a) if a == self.config.algorithm(a).name else None
                )
                if self.paper and paper_value is not None:
                    cell += f" (paper {fmt(paper_value)})"
                row.append(cell)
                records.append({"teacher_set": s, "algo": a, "jumpstart": js, "paper": paper_value})
            rows.append(row)
        pd.DataFrame(records).to_csv(self.out / "jumpstart.csv", index=False)
        note = (
            f"Mean training return over the first {c.metrics.jumpstart_window:,} steps minus that of "
            f"the no-advice baseline `{c.baseline}` (Taylor & Stone 2009), each averaged over seeds "
            f"(paper, Tables 1-3)."
        )
        if self.paper:
            source = load_paper_results()["source"]
            note += f" In brackets: the paper's value for the same cell ({source}); its initial window is not stated."
        self.sections.append("## Jumpstart\n\n" + note + "\n\n" + _markdown_table(header, rows))

    def performance_section(self) -> None:
        c = self.config
        header = [
            "teacher set",
            "algorithm",
            "final training return",
            "student alone (final)",
            "gap: training - student",
            "student matches best teacher at",
            "mean return over training (AUC / steps)",
        ]
        if c.metrics.threshold is not None:
            header.append(f"steps to reach {fmt(c.metrics.threshold)}")
        rows = []
        for s, a in self.cells():
            part = (
                self.summary[(self.summary.teacher_set == s) & (self.summary.algo == a)]
                if len(self.summary)
                else self.summary
            )
            if len(part) == 0:
                rows.append(
                    [_label(c, s), f"`{a}`", "no finished run", "", "", "", ""]
                    + ([""] if c.metrics.threshold is not None else [])
                )
                continue
            row = [
                _label(c, s),
                f"`{a}`",
                fmt_mean_std(part.final_return),
                fmt_mean_std(part.student_final_return),
                fmt_mean_std(part.final_return - part.student_final_return),
                self._steps_to_match(s, a),
                fmt_mean_std(part.auc_mean_return),
            ]
            if c.metrics.threshold is not None:
                mean, _ = self.mean_curve(self.finished(s, a))
                ttt = M.time_to_threshold(self.grid, mean, c.metrics.threshold)
                row.append("never" if math.isnan(ttt) else f"{ttt:,.0f}")
            rows.append(row)
        self.sections.append(
            "## Performance\n\nMean ± standard deviation over seeds. Final training return: the last "
            f"{final_window(c):,} steps. Student alone: the last evaluation without teachers. "
            "Gap: final training return minus the student alone, per seed. Student matches best "
            "teacher: the first evaluation where the seed-mean student alone reaches the best "
            "single teacher's measured return. "
            "Time to threshold: first grid step where the seed-mean training curve reaches it.\n\n"
            + _markdown_table(header, rows)
        )

    def _steps_to_match(self, set_key: str, algo: str) -> str:
        """Steps until the student alone (seed-mean evaluation curve) first reaches the best
        single teacher's measured return; 'never' within the budget, '' without data."""
        refs = self._references(set_key)
        runs = [d for d in self.finished(set_key, algo) if len(d.evals)]
        if not refs or not runs:
            return ""
        merged = pd.concat([d.evals for d in runs]).groupby("timestep")["mean_return"].mean()
        step = M.first_step_reaching(merged.index, merged.to_numpy(), max(refs.values()))
        return "never" if math.isnan(step) else f"{step:,.0f}"

    def iqm_section(self) -> None:
        """IQM per algorithm over all its runs. Teacher sets have different ceilings, so
        beside the raw IQM each run's score is divided by the best teacher's own return in its
        set (where one was measured and is positive), and the figure shows that normalised
        IQM when every run has it."""
        if len(self.summary) == 0:
            return
        import matplotlib.pyplot as plt

        from tlac.experiments.plots import plot_interval_estimates

        c = self.config
        summary = self.summary.copy()
        best = summary.teacher_set.map(self._best_teacher)
        best = best.where(best > 0)
        cols = ("final_return", "student_final_return")
        for col in cols:
            summary[f"{col}_norm"] = summary[col] / best
        header = [
            "algorithm",
            "IQM final training return [95% CI]",
            "IQM student alone [95% CI]",
            "the same / best teacher's return [95% CI]",
            "runs",
        ]
        rows, labels, est = [], [], {k: [] for k in cols + tuple(f"{k}_norm" for k in cols)}
        for a in self.algo_order:
            part = summary[summary.algo == a]
            if len(part) == 0:
                continue
            labels.append(a)
            cells = []
            for col in est:
                tasks = [g[col].dropna().to_numpy(float) for _, g in part.groupby("teacher_set")]
                p, lo, hi = M.stratified_bootstrap_ci(
                    tasks, M.iqm, c.metrics.bootstrap_reps, 0.95, c.metrics.bootstrap_seed
                )
                est[col].append((p, lo, hi))
                cells.append(f"{fmt(p)} [{fmt(lo)}, {fmt(hi)}]")
            normalised = f"training {cells[2]}; student {cells[3]}"
            rows.append([algorithm_label(c, a), cells[0], cells[1], normalised, str(len(part))])
        self.sections.append(
            "## Interquartile mean\n\nIQM over all runs of an algorithm (every teacher set and seed), "
            f"with a 95% stratified-bootstrap confidence interval ({c.metrics.bootstrap_reps} resamples, "
            f"random state {c.metrics.bootstrap_seed}; runs resampled within each teacher set), as in "
            "Agarwal et al. 2021. Teacher sets have different ceilings, so the raw IQM mixes "
            "them; the normalised column divides each run's score by the best teacher's own "
            "return in its set first (runs without advice have no teacher: left out there)."
            "\n\n" + _markdown_table(header, rows)
        )
        use_norm = all(np.isfinite(p) for p, _, _ in est["final_return_norm"])
        suffix = "_norm" if use_norm else ""
        unit = " / best teacher's return" if use_norm else " (per episode)"
        fig, axes = plt.subplots(1, 2, figsize=(9, 0.6 * len(labels) + 1.6), sharey=True)
        for ax, (col, xlabel) in zip(
            axes,
            [
                ("final_return", "IQM final training return"),
                ("student_final_return", "IQM student-alone return"),
            ],
            strict=True,
        ):
            values = est[col + suffix]
            p, lo, hi = zip(*values, strict=True) if values else ((), (), ())
            plot_interval_estimates(
                ax,
                [algorithm_label(c, a) for a in labels],
                p,
                lo,
                hi,
                xlabel=xlabel + unit,
                styles=[self.styles[a] for a in labels],
            )
        caption = "IQM with 95% stratified-bootstrap confidence intervals" + (
            ", each run's score divided by its teacher set's best teacher" if use_norm else ""
        )
        self.save(fig, "iqm.png", caption)

    def _best_teacher(self, set_key: str) -> float:
        """The best own return among a teacher set's teachers (NaN if not measured)."""
        refs = self._references(set_key)
        return max(refs.values()) if refs else float("nan")

    def comparison_section(self) -> None:
        """Probability of improvement between the advice algorithms and performance profiles
        of their scores normalised by each teacher set's best teacher (Agarwal et al. 2021):
        both compare within a teacher set, so sets with different ceilings are not pooled."""
        import matplotlib.pyplot as plt

        from tlac.experiments.plots import legend_outside, plot_profiles

        c, summary = self.config, self.summary
        algos = [a for a in self.advice_algos if len(summary) and (summary.algo == a).any()]
        if not algos or len(summary) == 0:
            return
        cols = (("final_return", "training return"), ("student_final_return", "student alone"))
        text = ["## Comparisons within teacher sets"]
        if len(algos) > 1:
            rows = []
            for i, x in enumerate(algos):
                for y in algos[i + 1 :]:
                    sets = sorted(
                        set(summary[summary.algo == x].teacher_set)
                        & set(summary[summary.algo == y].teacher_set)
                    )
                    cells = []
                    for col, _ in cols:
                        xs = [
                            summary[(summary.algo == x) & (summary.teacher_set == s)][col].dropna()
                            for s in sets
                        ]
                        ys = [
                            summary[(summary.algo == y) & (summary.teacher_set == s)][col].dropna()
                            for s in sets
                        ]
                        cells.append(fmt(M.probability_of_improvement(xs, ys)))
                    rows.append(
                        [algorithm_label(c, x), algorithm_label(c, y), str(len(sets)), *cells]
                    )
            text += [
                "Probability of improvement P(X > Y) (rliable): per teacher set, the share of "
                "(run of X, run of Y) pairs where X scores higher, ties half; then the mean over "
                "the teacher sets both ran. 0.5: no difference.",
                _markdown_table(
                    [
                        "X",
                        "Y",
                        "teacher sets",
                        "P(X > Y), final training return",
                        "P(X > Y), student alone",
                    ],
                    rows,
                ),
            ]
        self.sections.append("\n\n".join(text) if len(text) > 1 else text[0])
        taus = np.linspace(0.0, 1.2, 61)
        fig, axes = plt.subplots(1, 2, figsize=(10.4, 4.0), squeeze=False)
        drawn = False
        for ax, (col, what) in zip(axes.flat, cols, strict=True):
            profiles, styles = {}, {}
            for a in algos:
                part = summary[summary.algo == a]
                best = part.teacher_set.map(self._best_teacher)
                scores = (part[col] / best).replace([np.inf, -np.inf], np.nan).dropna()
                if len(scores):
                    label = f"{algorithm_label(c, a)} (n={len(scores)})"
                    profiles[label] = M.performance_profile(scores.to_numpy(float), taus)
                    styles[label] = self.styles.get(a, 0)
            plot_profiles(
                ax, taus, profiles, xlabel=f"{what} / best teacher's return", styles=styles
            )
            legend_outside(ax)
            drawn = drawn or bool(profiles)
        if drawn:
            self.save(
                fig,
                "profiles.png",
                "Performance profiles: the share of runs whose final score, divided by the best "
                "teacher's own return in their teacher set, exceeds tau (rliable)",
            )
        else:
            plt.close(fig)

    def _references(self, set_key: str) -> dict[str, float]:
        refs = {}
        if set_key == NO_TEACHERS:
            return refs
        for kind in dict.fromkeys(self.config.teacher_set(set_key).teachers):
            info = self.teachers.get(kind, {})
            if "mean" in info:
                refs[f"teacher {kind}"] = float(info["mean"])
        return refs

    def curves_figure(
        self, algos: list[str], name: str, caption: str, with_baseline: bool = True
    ) -> None:
        import matplotlib.pyplot as plt

        from tlac.experiments.plots import legend_outside, plot_curves

        sets = [s for s in self.set_keys() if any(self.finished(s, a) for a in algos)]
        if not sets:
            return
        c = self.config
        base_runs = self.finished(NO_TEACHERS, c.baseline) if (with_baseline and c.baseline) else []
        ncols = min(len(sets), 2)
        nrows = math.ceil(len(sets) / ncols)
        fig, axes = plt.subplots(nrows, ncols, figsize=(5.2 * ncols, 4.3 * nrows), squeeze=False)
        for ax, s in zip(axes.flat, sets, strict=False):
            curves, styles = {}, {}
            for a in algos:
                runs = self.finished(s, a)
                if runs:
                    label = f"{algorithm_label(c, a)} (n={len(runs)})"
                    curves[label], styles[label] = self.curve_band(runs), self.styles[a]
            if base_runs:
                label = f"{algorithm_label(c, c.baseline)} (no advice, n={len(base_runs)})"
                curves[label] = self.curve_band(base_runs)
                styles[label] = self.styles.get(c.baseline, 0)
            plot_curves(
                ax, self.grid, curves, self._references(s), title=_label(c, s), styles=styles
            )
            legend_outside(ax)
        for ax in list(axes.flat)[len(sets) :]:
            ax.set_visible(False)
        self.save(fig, name, caption)

    def student_figure(self) -> None:
        import matplotlib.pyplot as plt

        from tlac.experiments.plots import legend_outside, plot_curves

        c = self.config
        sets = [s for s in self.set_keys() if any(len(d.evals) for d in self.finished(s))]
        if not sets or c.eval.episodes == 0:
            return
        every = c.eval.every or c.steps
        grid = np.unique(np.append(np.arange(0, c.steps + 1, every, dtype=float), float(c.steps)))
        if len(grid) < 2:
            return
        ncols = min(len(sets), 2)
        nrows = math.ceil(len(sets) / ncols)
        fig, axes = plt.subplots(nrows, ncols, figsize=(5.2 * ncols, 4.3 * nrows), squeeze=False)
        base_runs = self.finished(NO_TEACHERS, c.baseline) if c.baseline else []
        for ax, s in zip(axes.flat, sets, strict=False):
            curves, styles = {}, {}
            groups = [(a, self.finished(s, a)) for a in self.advice_algos]
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
                    styles[label] = self.styles.get(a, 0)
            plot_curves(
                ax,
                grid,
                curves,
                self._references(s),
                title=_label(c, s),
                ylabel="student-alone return per episode",
                styles=styles,
            )
            legend_outside(ax)
        for ax in list(axes.flat)[len(sets) :]:
            ax.set_visible(False)
        self.save(
            fig,
            "student_alone.png",
            f"The student alone (no teacher): mean over seeds of {c.eval.episodes}-episode "
            "evaluations, with the 95% bootstrap interval of the mean (seeds resampled)",
        )

    def usage_figures(self) -> None:
        import matplotlib.pyplot as plt

        from tlac.experiments.plots import legend_outside, plot_usage

        bin_width = max(self.config.log_interval, self.config.steps / 50)
        for a in self.advice_algos:
            for s in self.set_keys():
                frames = [d.usage for d in self.finished(s, a) if len(d.usage)]
                if not frames:
                    continue
                freq = M.reuse_frequency(pd.concat(frames, ignore_index=True), bin_width)
                regions = [r for r in freq["region"].unique() if r != "all"] or ["all"]
                fig, axes = plt.subplots(
                    1, len(regions), figsize=(4.6 * len(regions), 4.0), squeeze=False
                )
                choices = list(dict.fromkeys(pd.concat(frames)["choice"]))
                for ax, region in zip(axes.flat, regions, strict=True):
                    plot_usage(
                        ax, freq[freq.region == region], title=f"region: {region}", choices=choices
                    )
                legend_outside(axes.flat[0])
                fig.suptitle(
                    f"{algorithm_label(self.config, a)}, {_label(self.config, s)}: teacher usage",
                    fontsize=10,
                )
                self.save(
                    fig,
                    f"usage__{s}__{a}.png",
                    f"Teacher reuse frequency per region over training, `{a}` with {_label(self.config, s)} "
                    f"(pooled over {len(frames)} seed(s); paper Figures 10, 12)",
                )

    def write(self) -> Path:
        self.status_section()
        self.teachers_section()
        self.jumpstart_section()
        self.performance_section()
        self.iqm_section()
        self.comparison_section()
        self.sections.append("## Learning curves")
        self.curves_figure(
            self.advice_algos,
            "curves.png",
            f"Mean training return over seeds per teacher set, each seed's curve smoothed over "
            f"{SMOOTHING_BINS} of {self.config.metrics.curve_points} bins "
            f"({SMOOTHING_BINS / self.config.metrics.curve_points:.0%} of the budget); bands: "
            "95% bootstrap interval of the mean (seeds resampled; the paper's Figures 3-9 show "
            "+-1 std); horizontal lines: each teacher's own return",
        )
        self.student_figure()
        tlac_variants = [a.key for a in self.config.algorithms if a.name == "tlac"]
        if len({self.config.algorithm(k).selector for k in tlac_variants}) > 1:
            self.sections.append("## Ablation of the high level")
            self.curves_figure(
                tlac_variants,
                "ablation.png",
                "TL-AC's learned high level against random selection and UCB1 per episode "
                "(paper, Figure 11)",
                with_baseline=False,
            )
        self.sections.append("## Teacher usage")
        self.usage_figures()
        if len(self.summary):
            self.summary.to_csv(self.out / SUMMARY_FILE, index=False)
        path = self.out / REPORT_FILE
        path.write_text("\n\n".join(self.sections) + "\n")
        return path


def write_report(out_dir: str | Path, paper: bool = False) -> Path:
    """Write ``DIR/report.md``, ``DIR/summary.csv``, ``DIR/jumpstart.csv`` and
    ``DIR/figures/*.png`` for the experiment in ``out_dir``; returns the report's path."""
    import matplotlib

    matplotlib.use("Agg")
    return _Report(Path(out_dir), paper).write()
