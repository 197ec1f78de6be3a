"""Reading an experiment folder back: its config, every run of its grid and the teachers' own
returns, as one :class:`Experiment`. This is the only reading the report does; the tables
(:mod:`tlac.experiments.tables`) and figures (:mod:`tlac.experiments.figures`) work on the
object it returns and touch no file. Runs are read through a
:class:`~tlac.experiments.archive.RunStore`: from their folders, or from ``DIR/runs.tar.xz``
once the study is packed (the same bytes, so the same report).
"""

from __future__ import annotations

import dataclasses
import io
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from tlac.algorithms import NO_ADVICE, get_algorithm
from tlac.errors import ConfigError, read_yaml_file
from tlac.experiments.archive import RunFiles, RunStore
from tlac.experiments.config import NO_TEACHERS, ExperimentConfig, parse_config
from tlac.experiments.grid import ERROR_FILE, GridRun, expand_grid
from tlac.experiments.runner import (
    EXPERIMENT_FILE,
    TEACHERS_FILE,
    read_teachers,
    with_recorded_domain,
)
from tlac.run import RESULT_FILE, load_run_config

EPISODES_FILE = "episodes.csv"
EVAL_FILE = "eval.csv"
USAGE_FILE = "teacher_usage.csv"
EPISODES_COLUMNS = ["timestep", "return", "length"]
EVAL_COLUMNS = ["timestep", "mean_return", "std_return", "episodes"]
USAGE_COLUMNS = ["timestep", "region", "choice", "count", "fraction"]


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


@dataclass
class Experiment:
    """An experiment folder read back: the config, every declared run (finished or not) in
    grid order, and the teachers' own returns (``teachers.json``; empty when absent).

    The methods are plain queries over these; nothing here reads a file."""

    config: ExperimentConfig
    runs: list[RunData]
    teachers: dict[str, Any]

    def finished(self, set_key: str | None = None, algo: str | None = None) -> list[RunData]:
        """The finished runs, optionally of one teacher set and/or one algorithm entry."""
        return [
            d
            for d in self.runs
            if d.status == "finished"
            and (set_key is None or d.run.teacher_set == set_key)
            and (algo is None or d.run.algo == algo)
        ]

    def cells(self) -> list[tuple[str, str]]:
        """The (teacher set, algorithm) pairs that the grid declares, in grid order."""
        return list(dict.fromkeys((d.run.teacher_set, d.run.algo) for d in self.runs))

    def set_keys(self) -> list[str]:
        """The config's teacher sets, in config order (the no-advice key is not one)."""
        return [ts.key for ts in self.config.teacher_sets]

    def algo_order(self) -> list[str]:
        """Every algorithm entry's key, in config order."""
        return [a.key for a in self.config.algorithms]

    def advice_algos(self) -> list[str]:
        """The keys of the algorithm entries that take teachers, in config order."""
        return [a.key for a in self.config.algorithms if not a.no_advice]

    def baseline_runs(self) -> list[RunData]:
        """The finished runs of the no-advice baseline (none when the grid has no baseline)."""
        base = self.config.baseline
        return self.finished(NO_TEACHERS, base) if base else []


def _read_csv(
    data: bytes | None, where: str, columns: list[str], required: bool = False
) -> pd.DataFrame:
    """The CSV ``data`` (an empty frame when absent or unreadable); with ``required`` (a
    finished run's files) an unreadable or malformed file is a ConfigError naming ``where``."""
    df = _try_read_csv(data, columns)
    if required and df is None:
        raise ConfigError(
            f"{where!r} is damaged (expected a CSV with columns {', '.join(columns)}); "
            "delete its run folder and rerun the grid to redo it"
        )
    return pd.DataFrame(columns=columns) if df is None else df


def _try_read_csv(data: bytes | None, columns: list[str]) -> pd.DataFrame | None:
    if data is None:
        return None
    try:
        df = pd.read_csv(io.BytesIO(data))
    except (UnicodeDecodeError, pd.errors.EmptyDataError, pd.errors.ParserError):
        return None
    missing = [c for c in columns if c not in df.columns]
    if missing:
        return None
    try:
        df[columns[0]] = pd.to_numeric(df[columns[0]])
    except (ValueError, TypeError):
        return None
    return df


def read_run(store: RunStore, run: GridRun) -> RunData:
    """One run (its folder, or its copy in the archive): its status, its CSVs (empty frames
    where absent), its ``result.json`` when finished and the last line of its ``error.txt``
    when failed."""
    name = run.name
    status = store.status(name)
    result = None
    if status == "finished":
        result = json.loads(store.read(name, RESULT_FILE) or b"")
    error = None
    if status == "failed":
        text = (store.read(name, ERROR_FILE) or b"").decode(errors="replace")
        lines = text.strip().splitlines()
        error = lines[-1] if lines else "unknown error"

    def csv(file: str, columns: list[str], required: bool = False) -> pd.DataFrame:
        return _read_csv(store.read(name, file), store.where(name, file), columns, required)

    return RunData(
        run=run,
        status=status,
        episodes=csv(EPISODES_FILE, EPISODES_COLUMNS, required=status == "finished"),
        evals=csv(EVAL_FILE, EVAL_COLUMNS),
        usage=csv(USAGE_FILE, USAGE_COLUMNS),
        result=result,
        error=error,
    )


def read_experiment(out_dir: str | Path) -> Experiment:
    """Read the experiment folder ``out_dir`` (its runs from their folders or from
    ``runs.tar.xz``); a ConfigError when it is not one. A domain named by module or file is
    not imported: the runs' names come from ``DIR/domain.json``
    (:func:`~tlac.experiments.runner.with_recorded_domain`)."""
    out = Path(out_dir)
    cfg_path = out / EXPERIMENT_FILE
    if not cfg_path.exists():
        raise ConfigError(
            f"{out}: not an experiment folder ({EXPERIMENT_FILE} is missing) nor a run folder "
            "of tlac train (config.yaml)"
        )
    data = read_yaml_file(cfg_path, "experiment file")
    config = parse_config(data, str(cfg_path), import_domain=False)
    config = with_recorded_domain(config, out)
    store = RunStore(out)
    runs = [read_run(store, r) for r in expand_grid(config)]
    teachers = read_teachers(out / TEACHERS_FILE)
    return Experiment(config, runs, teachers)


class _OneRunStore(RunStore):
    """The :class:`RunStore` of one run folder (``tlac train``'s): whatever its grid name,
    the run is that folder."""

    def __init__(self, run_dir: Path):
        super().__init__(run_dir)
        self.run_dir = run_dir

    def folder(self, name: str) -> Path:
        return self.run_dir

    def packed(self) -> dict[str, RunFiles]:
        return {}


def read_run_folder(run_dir: str | Path) -> Experiment:
    """One run folder written by ``tlac train`` (its ``config.yaml``) read as an experiment of
    that one run: its domain, steps, seed, evaluations, algorithm and teachers (a teacher set
    named ``teachers``), so that ``tlac report RUN`` reports it as a grid of one."""
    out = Path(run_dir)
    run = load_run_config(out)
    try:
        get_algorithm(run["algo"])
    except ConfigError as exc:
        raise ConfigError(f"{str(out / 'config.yaml')!r}: {exc}") from None
    algo, teachers = run["algo"], run.get("teacher_kinds") or run.get("teachers") or []
    entry: dict[str, Any] = {"name": algo}
    if algo == "tlac" and run.get("selector", "learned") != "learned":
        entry["selector"] = run["selector"]
    every = run.get("eval_every")
    data = {
        "name": re.sub(r"[^A-Za-z0-9._-]+", "-", out.resolve().name).strip("-._") or "run",
        "domain": run["env"],
        "steps": run.get("steps"),
        "seeds": [run["seed"]],
        "eval": {
            "every": every,
            "episodes": run.get("eval_episodes", 10),
            "keep_best": bool(every and run.get("keep_best", False)),
            "deploy": run.get("deploy", "greedy"),
        },
        "log_interval": run.get("log_interval", 2000),
        "teacher_sets": {}
        if algo in NO_ADVICE or not teachers
        else {"teachers": {"label": ", ".join(map(str, teachers)), "teachers": list(teachers)}},
        "algorithms": [entry],
    }
    if isinstance(data["steps"], int):  # the first 10,000 steps, or all of a shorter run
        data["metrics"] = {"jumpstart_window": max(1, min(10_000, data["steps"]))}
    source = str(out / "config.yaml")
    config = parse_config(data, source, folder=Path.cwd(), import_domain=False)
    if config.domain_name is None:  # a domain file not found from here: the run is named anyway
        config = dataclasses.replace(config, domain_name=data["name"])
    runs = [read_run(_OneRunStore(out), r) for r in expand_grid(config)]
    return Experiment(config, runs, {})


def load_experiment(out_dir: str | Path) -> tuple[ExperimentConfig, list[RunData], dict[str, Any]]:
    """The experiment's config, every run of its grid (finished or not) and the teachers' own
    returns (``DIR/teachers.json``, empty if absent): :func:`read_experiment` as a tuple."""
    exp = read_experiment(out_dir)
    return exp.config, exp.runs, exp.teachers
