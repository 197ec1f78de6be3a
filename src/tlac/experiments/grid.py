"""Grid expansion: an :class:`ExperimentConfig` -> the list of runs it declares.

A run is named CleanRL-style, ``<domain>__<teacherset>__<algo>[__<selector>]__seed<k>``, and
lives in ``DIR/runs/<name>/`` (the run-folder format of ``docs/architecture.md``). The
no-advice baselines (``a2c``, ``ppo``) run once per seed under the teacher set ``none``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from tlac.errors import ConfigError
from tlac.experiments.config import NO_TEACHERS, ExperimentConfig
from tlac.run import RESULT_FILE, RunSpec

RUNS_DIR = "runs"
ERROR_FILE = "error.txt"


@dataclass(frozen=True)
class GridRun:
    """One cell x seed of the grid."""

    name: str
    """Folder name under ``DIR/runs``."""
    teacher_set: str
    """Teacher-set key (``none`` for the no-advice baselines)."""
    algo: str
    """Algorithm key of the experiment (``tlac``, ``tlac__ucb1``, a label...)."""
    seed: int
    spec: RunSpec


def run_name(domain_name: str, teacher_set: str, algo_key: str, seed: int) -> str:
    """The run's folder name. ``domain_name`` is the Domain's own name (for a domain given as
    ``module:attribute`` or ``file.py:attribute``: a path must never become part of a folder
    name), :attr:`ExperimentConfig.domain_name`."""
    return f"{domain_name}__{teacher_set}__{algo_key}__seed{seed}"


def expand_grid(config: ExperimentConfig) -> list[GridRun]:
    """Every run of the experiment, in a stable order (teacher set, algorithm, seed). A
    ConfigError when the runs' names are not known: a domain file or module that was not
    imported, whose name neither ``DIR/domain.json`` nor the file's source gives."""
    if config.domain_name is None:
        raise ConfigError(
            f"{config.source}: the runs are named after the Domain's name of {config.domain}, "
            "recorded when the grid is trained ('tlac experiment run'), and this command does "
            "not import the domain to read it"
        )
    runs: list[GridRun] = []
    set_order = [NO_TEACHERS] + [ts.key for ts in config.teacher_sets]
    for set_key in set_order:
        for algo in config.algorithms:
            if algo.no_advice != (set_key == NO_TEACHERS):
                continue
            if algo.teacher_sets is not None and set_key not in algo.teacher_sets:
                continue
            teachers = [] if algo.no_advice else list(config.teacher_set(set_key).teachers)
            for seed in algo.seeds if algo.seeds is not None else config.seeds:
                spec = RunSpec(
                    env=config.domain,
                    algo=algo.name,
                    teachers=teachers,
                    seed=seed,
                    steps=config.steps,
                    selector=algo.selector,
                    preset=algo.preset,
                    overrides=dict(algo.overrides),
                    eval_every=config.eval.every,
                    eval_episodes=config.eval.episodes,
                    keep_best=config.eval.keep_best,
                    deploy=config.eval.deploy,
                    log_interval=config.log_interval,
                )
                runs.append(
                    GridRun(
                        run_name(config.domain_name, set_key, algo.key, seed),
                        set_key,
                        algo.key,
                        seed,
                        spec,
                    )
                )
    return runs


def run_dir(out_dir: str | Path, run: GridRun | str) -> Path:
    return Path(out_dir) / RUNS_DIR / (run if isinstance(run, str) else run.name)


def run_status(folder: Path) -> str:
    """``finished`` (``result.json`` present and readable), ``failed`` (``error.txt``), ``partial``
    (a folder without either: interrupted) or ``missing``."""
    result = folder / RESULT_FILE
    text = None
    if result.exists():
        try:
            text = result.read_bytes()
        except OSError:
            text = b""  # present but unreadable: not finished
    return status_of(text, (folder / ERROR_FILE).exists(), folder.exists())


def status_of(result: bytes | None, has_error: bool, present: bool) -> str:
    """A run's status from what its folder holds: the bytes of its ``result.json`` (``None``
    when absent), whether it has an ``error.txt`` and whether the run exists at all; the one
    rule behind :func:`run_status` and the runs packed in ``runs.tar.xz``."""
    if result is not None:
        try:
            json.loads(result)
            return "finished"
        except ValueError:
            return "partial"
    if has_error:
        return "failed"
    return "partial" if present else "missing"
