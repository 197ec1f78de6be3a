"""The report's tables as pure functions: an :class:`~tlac.experiments.rundata.Experiment` (and
the per-run summary computed from it) in, a pandas DataFrame of plain numbers out. Nothing
here reads or writes a file, draws or formats text; :mod:`tlac.experiments.markdown` turns the
frames into Markdown and :mod:`tlac.experiments.report` writes them.

Conventions shared by the frames: a missing value is NaN; a step that is never reached within
the budget is ``inf`` (so that "never" and "no data" stay distinguishable); a mean over seeds
comes with its population standard deviation and the number of seeds that had a value, in
columns ``<metric>_mean``, ``<metric>_std``, ``<metric>_n``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from tlac.experiments import metrics as M
from tlac.experiments.config import NO_TEACHERS, ExperimentConfig
from tlac.experiments.rundata import Experiment, RunData

ALGORITHM_NAMES = {
    "tlac": "TL-AC",
    "a2c": "A2C",
    "ppo": "PPO",
    "dqn-tlql": "DQN-TLQL",
    "ac-teach": "AC-Teach",
}
SELECTOR_NAMES = {"random": "random selection", "ucb1": "UCB1 per episode"}
RUN_STATUSES = ("finished", "failed", "partial", "missing")
MIN_SEEDS = 5
"""Cells with fewer finished seeds than this get a warning in the report."""
SCORES = ("final_return", "student_final_return")
"""The two per-run scores the report compares algorithms on: the final training return and
the student alone (no teacher) at the end."""


# ------------------------------------------------------------------------------- labels


def algorithm_label(config: ExperimentConfig, key: str) -> str:
    """How the report names an algorithm entry: its config ``label`` as written, else the
    algorithm's usual name (with the TL-AC selector when it is not the learned one)."""
    entry = config.algorithm(key)
    if entry.key != entry.name and "__" not in entry.key:  # a label from the config
        return entry.key
    name = ALGORITHM_NAMES.get(entry.name, entry.name)
    if entry.selector != "learned":
        name += f" ({SELECTOR_NAMES.get(entry.selector, entry.selector)})"
    return name


def set_label(config: ExperimentConfig, set_key: str) -> str:
    """How the report names a teacher set (the no-advice key included)."""
    if set_key == NO_TEACHERS:
        return "none (no advice)"
    return config.teacher_set(set_key).label


# ------------------------------------------------------------------------------- helpers


def final_window(config: ExperimentConfig) -> int:
    """Steps of the final-performance window: the setting, or the last 10% of the budget."""
    return config.metrics.final_window or max(1, config.steps // 10)


def tlac_variants(config: ExperimentConfig) -> list[str]:
    """The keys of the TL-AC entries (every high-level selector), in config order."""
    return [a.key for a in config.algorithms if a.name == "tlac"]


def curve_grid(config: ExperimentConfig) -> np.ndarray:
    """The common step grid that every training curve is binned onto."""
    return M.step_grid(config.steps, config.metrics.curve_points)


def episodes(d: RunData) -> tuple[np.ndarray, np.ndarray]:
    """A run's finished training episodes as ``(timesteps, returns)``."""
    return d.episodes["timestep"].to_numpy(float), d.episodes["return"].to_numpy(float)


def mean_std_n(values: pd.Series) -> tuple[float, float, int]:
    """Mean, population standard deviation and count of the non-missing values (NaN, NaN, 0
    when there is none).

    >>> mean_std_n(pd.Series([0.9, 0.6, float("nan")]))
    (0.75, 0.15000000000000002, 2)
    """
    v = values.dropna().to_numpy(float)
    if len(v) == 0:
        return float("nan"), float("nan"), 0
    return float(v.mean()), float(v.std()), len(v)


def teacher_references(exp: Experiment, set_key: str) -> dict[str, float]:
    """Each teacher of a set with its own measured return (``teachers.json``), labelled
    ``teacher <kind>``, in the set's order; empty for the no-advice runs."""
    if set_key == NO_TEACHERS:
        return {}
    refs = {}
    for kind in dict.fromkeys(exp.config.teacher_set(set_key).teachers):
        info = exp.teachers.get(kind, {})
        if "mean" in info:
            refs[f"teacher {kind}"] = float(info["mean"])
    return refs


def best_teacher_return(exp: Experiment, set_key: str) -> float:
    """The best own return among a teacher set's teachers (NaN if none was measured)."""
    refs = teacher_references(exp, set_key)
    return max(refs.values()) if refs else float("nan")


def _never(step: float) -> float:
    """A first-reaching step with NaN (never reached) turned into ``inf``."""
    return math.inf if math.isnan(step) else step


# ------------------------------------------------------------------------------- tables


def summarize(config: ExperimentConfig, runs: list[RunData]) -> pd.DataFrame:
    """One row of metrics per finished run: initial and final training performance, normalised
    area under the training curve, the student alone at the end, steps and wall time
    (``summary.csv``)."""
    grid = curve_grid(config)
    rows = []
    for d in runs:
        if d.status != "finished":
            continue
        t, r = episodes(d)
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


def status_counts(exp: Experiment) -> pd.Series:
    """How many declared runs are in each status, indexed by :data:`RUN_STATUSES`."""
    counts = pd.Series([d.status for d in exp.runs]).value_counts()
    return pd.Series([int(counts.get(s, 0)) for s in RUN_STATUSES], index=list(RUN_STATUSES))


def seed_counts(exp: Experiment) -> pd.DataFrame:
    """Finished runs per declared (teacher set, algorithm) cell, in grid order: columns
    ``teacher_set, algo, finished``."""
    rows = [
        {"teacher_set": s, "algo": a, "finished": len(exp.finished(s, a))} for s, a in exp.cells()
    ]
    return pd.DataFrame(rows, columns=["teacher_set", "algo", "finished"])


def failed_runs(exp: Experiment) -> pd.DataFrame:
    """The failed runs with the last line of their error: columns ``run, error``."""
    rows = [{"run": d.run.name, "error": d.error} for d in exp.runs if d.status == "failed"]
    return pd.DataFrame(rows, columns=["run", "error"])


def teachers_table(
    teachers: Mapping[str, Any], paper: Mapping[str, Any] | None = None
) -> pd.DataFrame:
    """Each teacher alone as measured for the grid (``teachers.json``), in file order, and
    with ``paper`` (the paper's values for the domain) a ``paper`` column holding the paper's
    entry for the same teacher (a dict with ``mean`` and optional ``std`` and ``note``; None
    where the paper states none). Teachers without a measured mean are left out. ``episodes``
    keeps the value as written (``""`` when absent).

    >>> table = teachers_table({"a": {"mean": 0.5, "episodes": 10}, "b": {}}, {"a": {"mean": 0.7}})
    >>> table.to_dict("records")
    [{'teacher': 'a', 'mean': 0.5, 'std': nan, 'episodes': 10, 'paper': {'mean': 0.7}}]
    """
    rows = []
    for name, info in teachers.items():
        if "mean" not in info:
            continue
        row = {
            "teacher": name,
            "mean": _float(info["mean"]),
            "std": _float(info.get("std")),
            "episodes": info.get("episodes", ""),
        }
        if paper is not None:
            row["paper"] = paper.get(name)
        rows.append(row)
    columns = ["teacher", "mean", "std", "episodes"] + (["paper"] if paper is not None else [])
    frame = pd.DataFrame(rows, columns=columns)
    for col in ("episodes", "paper"):
        if col in frame:  # as written: no int -> float conversion, None stays None
            frame[col] = pd.Series([r.get(col) for r in rows], dtype=object)
    return frame


def jumpstart_table(exp: Experiment, paper_rows: Mapping[str, Any] | None = None) -> pd.DataFrame:
    """Jumpstart (Taylor & Stone 2009; paper, Tables 1-3) of every declared (teacher set, advice
    algorithm) cell against the no-advice baseline, in teacher-set then algorithm order:
    columns ``teacher_set, algo, jumpstart, paper`` (``jumpstart.csv``). ``paper`` is the
    paper's value for the same cell from ``paper_rows`` (teacher set -> algorithm -> value),
    only for plain algorithm entries (learned high level, no custom label)."""
    c = exp.config
    base = [episodes(d) for d in exp.baseline_runs()]
    paper_rows = paper_rows or {}
    cells = exp.cells()
    records = []
    for s in exp.set_keys():
        for a in exp.advice_algos():
            if (s, a) not in cells:
                continue
            runs = [episodes(d) for d in exp.finished(s, a)]
            js = M.jumpstart(runs, base, c.metrics.jumpstart_window)
            paper_value = paper_rows.get(s, {}).get(a) if a == c.algorithm(a).name else None
            records.append({"teacher_set": s, "algo": a, "jumpstart": js, "paper": paper_value})
    return pd.DataFrame(records)


def performance_table(exp: Experiment, summary: pd.DataFrame) -> pd.DataFrame:
    """Per declared cell: the seed count of ``summary`` (``runs``), mean/std/n over seeds of the
    final training return, the student alone, their per-seed gap and the mean return over
    training (AUC / steps); ``student_matches_at``, the first evaluation step where the
    seed-mean student alone reaches the set's best teacher (NaN without teacher returns or
    evaluations); and ``steps_to_threshold``, the first grid step where the seed-mean training
    curve reaches ``metrics.threshold`` (NaN when no threshold is set)."""
    c = exp.config
    grid = curve_grid(c)
    rows = []
    for s, a in exp.cells():
        part = (
            summary[(summary.teacher_set == s) & (summary.algo == a)] if len(summary) else summary
        )
        row: dict[str, Any] = {"teacher_set": s, "algo": a, "runs": len(part)}
        metrics = {
            "final_return": part.get("final_return"),
            "student_final_return": part.get("student_final_return"),
            "gap": None if len(part) == 0 else part.final_return - part.student_final_return,
            "auc_mean_return": part.get("auc_mean_return"),
        }
        for name, values in metrics.items():
            m, sd, n = mean_std_n(values) if len(part) else (float("nan"), float("nan"), 0)
            row |= {f"{name}_mean": m, f"{name}_std": sd, f"{name}_n": n}
        row["student_matches_at"] = _steps_to_match(exp, s, a) if len(part) else float("nan")
        row["steps_to_threshold"] = float("nan")
        if c.metrics.threshold is not None and len(part):
            curves = [M.binned_curve(*episodes(d), grid) for d in exp.finished(s, a)]
            mean, _ = M.mean_std(np.array(curves))
            row["steps_to_threshold"] = _never(M.time_to_threshold(grid, mean, c.metrics.threshold))
        rows.append(row)
    return pd.DataFrame(rows)


def _steps_to_match(exp: Experiment, set_key: str, algo: str) -> float:
    """Steps until the student alone (seed-mean evaluation curve) first reaches the best
    single teacher's measured return; inf if never within the budget, NaN without data."""
    refs = teacher_references(exp, set_key)
    runs = [d for d in exp.finished(set_key, algo) if len(d.evals)]
    if not refs or not runs:
        return float("nan")
    merged = pd.concat([d.evals for d in runs]).groupby("timestep")["mean_return"].mean()
    return _never(M.first_step_reaching(merged.index, merged.to_numpy(), max(refs.values())))


def normalised_scores(exp: Experiment, summary: pd.DataFrame) -> pd.DataFrame:
    """``summary`` with ``<score>_norm`` columns: each run's score divided by the best teacher's
    own return in its teacher set (NaN where that return is unknown or not positive, e.g. the
    runs without advice)."""
    out = summary.copy()
    best = out.teacher_set.map(lambda s: best_teacher_return(exp, s))
    best = best.where(best > 0)
    for col in SCORES:
        out[f"{col}_norm"] = out[col] / best
    return out


def iqm_table(exp: Experiment, summary: pd.DataFrame) -> pd.DataFrame:
    """Interquartile mean per algorithm over all its runs with a 95% stratified-bootstrap
    confidence interval (Agarwal et al. 2021; runs resampled within each teacher set), for
    each score raw and normalised by the best teacher (:func:`normalised_scores`): columns
    ``algo, runs`` then ``<score>, <score>_low, <score>_high`` per score, in algorithm order;
    algorithms without a run are left out."""
    c = exp.config
    scores = normalised_scores(exp, summary)
    cols = SCORES + tuple(f"{k}_norm" for k in SCORES)
    rows = []
    for a in exp.algo_order():
        part = scores[scores.algo == a]
        if len(part) == 0:
            continue
        row: dict[str, Any] = {"algo": a, "runs": len(part)}
        for col in cols:
            tasks = [g[col].dropna().to_numpy(float) for _, g in part.groupby("teacher_set")]
            p, lo, hi = M.stratified_bootstrap_ci(
                tasks, M.iqm, c.metrics.bootstrap_reps, 0.95, c.metrics.bootstrap_seed
            )
            row |= {col: p, f"{col}_low": lo, f"{col}_high": hi}
        rows.append(row)
    return pd.DataFrame(rows)


def compared_algos(exp: Experiment, summary: pd.DataFrame) -> list[str]:
    """The advice algorithms with at least one finished run, in config order."""
    if len(summary) == 0:
        return []
    return [a for a in exp.advice_algos() if (summary.algo == a).any()]


def improvement_table(exp: Experiment, summary: pd.DataFrame) -> pd.DataFrame:
    """Probability of improvement P(X > Y) (rliable) for every pair of compared algorithms, X
    before Y in config order, over the teacher sets both ran: columns ``x, y, teacher_sets``
    and one per score of :data:`SCORES`."""
    algos = compared_algos(exp, summary)
    rows = []
    for i, x in enumerate(algos):
        for y in algos[i + 1 :]:
            sets = sorted(
                set(summary[summary.algo == x].teacher_set)
                & set(summary[summary.algo == y].teacher_set)
            )
            row: dict[str, Any] = {"x": x, "y": y, "teacher_sets": len(sets)}
            for col in SCORES:
                xs = [
                    summary[(summary.algo == x) & (summary.teacher_set == s)][col].dropna()
                    for s in sets
                ]
                ys = [
                    summary[(summary.algo == y) & (summary.teacher_set == s)][col].dropna()
                    for s in sets
                ]
                row[col] = M.probability_of_improvement(xs, ys)
            rows.append(row)
    return pd.DataFrame(rows, columns=["x", "y", "teacher_sets", *SCORES])
