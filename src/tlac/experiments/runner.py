"""Run an experiment's grid: in parallel processes on this machine, or as Ray tasks on a cluster.

Both runners share one contract:

* ``DIR/experiment.yaml`` is a copy of the experiment file; ``DIR/runs/<name>/`` is one run
  folder each (``docs/architecture.md``); ``DIR/teachers.json`` holds each teacher's own return.
* A run is finished once its ``result.json`` exists: ``tlac.run.train_run`` writes it last and
  atomically. Rerunning the same command skips finished runs and redoes every other one from
  scratch (an interrupted folder is cleared first), so a grid is resumable and loss-free.
  Finished run folders are never opened for writing again. Runs packed into
  ``DIR/runs.tar.xz`` (``tlac results pack``) count as they are there: finished ones are
  skipped, the others are redone into a new folder, which then wins over the archive's copy.
* A run that raises writes ``error.txt`` (the traceback) into its folder, is reported, and does
  not stop the others; it is redone on the next invocation.

Local: a :class:`~concurrent.futures.ProcessPoolExecutor` of ``workers`` spawned processes, each
with ``torch.set_num_threads(1)``; workers die with the driver (``PR_SET_PDEATHSIG``), and a lock
on ``DIR/.lock`` keeps two drivers off one folder. Ray: one ``@ray.remote`` task per run; each
task trains into a temporary folder on its node and returns the packed folder, which the driver
writes into ``DIR`` (so ``DIR`` need not be on a shared filesystem; see ``docs/experiments.md``).
"""

from __future__ import annotations

import contextlib
import fnmatch
import io
import json
import os
import re
import shutil
import signal
import sys
import tarfile
import tempfile
import time
import traceback
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml

from tlac.domains import DOMAIN_NAME
from tlac.errors import ConfigError
from tlac.experiments.archive import RunStore
from tlac.experiments.config import ExperimentConfig, domain_file
from tlac.experiments.grid import ERROR_FILE, RUNS_DIR, GridRun, expand_grid, run_dir
from tlac.run import (
    OLD_RUN_DEFAULTS,
    RESULT_FILE,
    RunSpec,
    atomic_write_text,
    folder_lock,
    resolve_run,
)

EXPERIMENT_FILE = "experiment.yaml"
TEACHERS_FILE = "teachers.json"
DOMAIN_FILE = "domain.json"
"""``{"domain": <the domain field, resolved>, "name": <its Domain's name>}``, written when a
grid whose domain is a module or file is trained: the runs are named after the Domain's
name, and reports and listings read it here rather than import the domain."""
LOCK_FILE = ".lock"


@dataclass
class GridSummary:
    """What one invocation of a runner did."""

    total: int = 0
    skipped: int = 0
    """Runs already finished before this invocation (left untouched)."""
    finished: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    """Run name -> one-line error."""
    interrupted: bool = False

    @property
    def ok(self) -> bool:
        return not self.failed and not self.interrupted

    def lines(self) -> list[str]:
        out = [
            f"{self.total} runs: {self.skipped} already finished, "
            f"{len(self.finished)} finished now, "
            f"{len(self.failed)} failed" + (" (interrupted)" if self.interrupted else "")
        ]
        out += [f"FAILED {name}: {err}" for name, err in self.failed.items()]
        return out


# --------------------------------------------------------------------------- preparing DIR


SPEC_FIELDS = (
    "env",
    "algo",
    "seed",
    "steps",
    "selector",
    "overrides",
    "eval_every",
    "eval_episodes",
    "log_interval",
    "keep_best",
    "deploy",
)
"""RunSpec fields that must agree between a finished run's ``config.yaml`` and the grid."""


def spec_mismatch(spec: RunSpec, config_yaml: bytes | None) -> str | None:
    """How a finished run's ``config.yaml`` (its bytes) differs from ``spec``
    (``"steps=1000 (now 2000)"``), or ``None`` when it was made with the same settings (or
    has no readable config)."""
    if config_yaml is None:
        return None
    try:
        done = yaml.safe_load(config_yaml) or {}
    except yaml.YAMLError:
        return None
    wanted = {k: getattr(spec, k) for k in SPEC_FIELDS}
    wanted["teacher_kinds"] = list(spec.teachers or [])
    if spec.preset is not None:
        wanted["preset"] = spec.preset
    for key, value in wanted.items():
        if key not in done and key in OLD_RUN_DEFAULTS:
            done[key] = OLD_RUN_DEFAULTS[key]
        if (
            key in done
            and done[key] != value
            and not (key == "env" and _same_file(done[key], value))
        ):
            return f"{key}={done[key]!r} (now {value!r})"
    return None


def _same_file(done: Any, now: str) -> bool:
    """Whether two domain files (``path/my_domain.py:DOMAIN``) have the same file name and
    attribute: the run's name pins the Domain's own name, and the folder may have moved (a
    project cloned elsewhere records another absolute path)."""
    a, b = domain_file(done) if isinstance(done, str) else None, domain_file(now)
    return a is not None and b is not None and (Path(a[0]).name, a[1]) == (Path(b[0]).name, b[1])


def prepare_out_dir(
    config: ExperimentConfig, out_dir: str | Path, store: RunStore | None = None
) -> Path:
    """Create ``DIR`` and write the experiment to ``DIR/experiment.yaml``.

    A folder can be reused by a changed experiment file (more seeds, another teacher set...) as
    long as every run that is already finished there was made with the settings the new grid
    asks of it; otherwise this raises :class:`ConfigError` naming the run and the setting, so
    that results of two different grids never mix. ``store`` reads the runs (default: a new
    :class:`RunStore` of ``out_dir``, which also sees the runs packed in ``runs.tar.xz``)."""
    out = Path(out_dir)
    (out / RUNS_DIR).mkdir(parents=True, exist_ok=True)
    store = store or RunStore(out)
    for r in expand_grid(config):
        if store.status(r.name) != "finished":
            continue
        why = spec_mismatch(r.spec, store.read(r.name, "config.yaml"))
        if why is not None:
            raise ConfigError(
                f"{store.where(r.name)}: finished with {why} asked by {config.source}; use "
                f"another --out, or delete that run folder to redo it"
            )
    atomic_write_text(out / EXPERIMENT_FILE, yaml.safe_dump(config.raw_in(out), sort_keys=False))
    if ":" in config.domain and config.domain_name is not None:
        record = {"domain": config.domain, "name": config.domain_name}
        atomic_write_text(out / DOMAIN_FILE, json.dumps(record, indent=2) + "\n")
    return out


def with_recorded_domain(config: ExperimentConfig, out_dir: str | Path) -> ExperimentConfig:
    """``config`` with the Domain's name that ``DIR/domain.json`` recorded when the grid was
    trained, for a domain named by module or file (which reports and listings do not import);
    ``config`` unchanged where nothing was recorded for its domain. A record that is not
    ``{"domain": ..., "name": ...}`` is a ConfigError naming the file."""
    path = Path(out_dir) / DOMAIN_FILE
    if ":" not in config.domain or not path.is_file():
        return config
    expected = 'expected {"domain": "<file.py:ATTR>", "name": "<letters, digits and . _ ->"}'
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{str(path)!r}: not readable ({exc}); {expected}") from None
    if not (
        isinstance(data, dict)
        and isinstance(data.get("domain"), str)
        and isinstance(data.get("name"), str)
        and re.fullmatch(DOMAIN_NAME, data["name"])
    ):
        raise ConfigError(f"{str(path)!r}: {expected}, got {str(data)[:60]!r}")
    if data["domain"] != config.domain and not _same_file(data["domain"], config.domain):
        return config
    return replace(config, domain_name=data["name"])


@contextlib.contextmanager
def _grid_session(
    config: Any, out: Path, only: str | None = None
) -> Iterator[tuple[list[GridRun], GridSummary]]:
    """What every backend does first, holding the folder's lock throughout: create DIR,
    check or write its experiment file, measure the teachers once, and plan the unfinished
    runs (those matching ``only``, see :func:`select_runs`). Yields (runs to do, a summary
    counting the finished ones as skipped). Every run's settings are checked before anything
    is written."""
    check_grid_settings(config)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {str(out)!r} is a file; expected a folder for the grid")
    is_grid = (out / EXPERIMENT_FILE).exists() or (out / RUNS_DIR).is_dir()
    if out.is_dir() and any(out.iterdir()) and not is_grid:
        raise ConfigError(
            f"--out {str(out)!r} is not empty and holds no {EXPERIMENT_FILE} or {RUNS_DIR}/: "
            "not a grid folder; give a new or an existing grid folder"
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create the grid folder {str(out)!r}: {exc.strerror}") from None
    with dir_lock(out):
        store = RunStore(out)
        prepare_out_dir(config, out, store)
        evaluate_teachers(config, out)
        todo, skipped = _plan(config, store, only)
        yield todo, GridSummary(total=len(todo) + skipped, skipped=skipped)


def check_grid_settings(config: ExperimentConfig) -> None:
    """Every run's spec and hyperparameters are valid (:func:`tlac.run.resolve_run`, what
    ``train_run`` does first), so that a typo in one algorithm's overrides stops the grid
    before any run starts."""
    for r in expand_grid(config):
        try:
            resolve_run(r.spec)
        except ConfigError as exc:
            raise ConfigError(f"{config.source}: run {r.name}: {exc}") from None


@contextlib.contextmanager
def _stderr_silenced() -> Iterator[None]:
    """Send this process's file descriptor 2 (C++ libraries' logs too) to /dev/null."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


@contextlib.contextmanager
def dir_lock(out: Path) -> Iterator[None]:
    """An exclusive lock on ``DIR/.lock`` for the driver's lifetime (released even on SIGKILL;
    ``filelock`` works on Linux, macOS and Windows)."""
    with folder_lock(out / LOCK_FILE, f"{out}: another 'tlac experiment run' is using this folder"):
        yield


def read_teachers(path: Path) -> dict[str, Any]:
    """``DIR/teachers.json`` (empty when absent): a JSON object of teacher name -> ``{mean,
    std, episodes}`` or ``{error}``; anything else is one ConfigError naming the file."""
    if not path.exists():
        return {}
    expected = "expected a JSON object of teacher name -> {mean, std, episodes}"
    try:
        data = json.loads(path.read_bytes())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{str(path)!r}: not readable JSON ({exc}); {expected}") from None
    if not isinstance(data, dict) or not all(isinstance(v, dict) for v in data.values()):
        raise ConfigError(f"{str(path)!r}: {expected}, got {str(data)[:60]!r}")
    for name, info in data.items():
        for key in ("mean", "std"):
            value = info.get(key)
            if value is not None and (
                isinstance(value, bool) or not isinstance(value, int | float)
            ):
                raise ConfigError(f"{str(path)!r}: {name}.{key} must be a number, got {value!r}")
    return data


def evaluate_teachers(config: ExperimentConfig, out: Path) -> dict[str, Any]:
    """Each teacher's own return (``teacher_eval_episodes`` episodes, acting alone), written to
    ``DIR/teachers.json``: the reference lines of the learning-curve plots (paper, Figures 3-9).
    Kinds already measured are kept; a teacher that cannot be built is recorded with its error."""
    path = out / TEACHERS_FILE
    data = read_teachers(path)
    kinds = sorted({t for ts in config.teacher_sets for t in ts.teachers})
    todo = [k for k in kinds if k not in data or "error" in data[k]]
    if not todo or config.teacher_eval_episodes == 0:
        return data
    from tlac.domains import get_domain
    from tlac.evaluation import evaluate_policy

    domain = get_domain(config.domain)
    for kind in todo:
        env = domain.make_env()
        try:
            teacher = domain.make_teacher(kind, env, 0)
            returns = evaluate_policy(
                teacher.predict, domain, config.teacher_eval_episodes, seed=20_000
            )
            data[kind] = {
                "mean": float(returns.mean()),
                "std": float(returns.std()),
                "episodes": len(returns),
            }
        except Exception as exc:  # reference lines are optional: record and go on
            data[kind] = {"error": f"{type(exc).__name__}: {exc}"}
        finally:
            env.close()
    atomic_write_text(path, json.dumps(data, indent=2))
    return data


# --------------------------------------------------------------------------- worker side


def _init_worker(algorithms: dict[str, str], die_with_parent: bool = True) -> None:
    """Process initialiser: one torch thread per worker, the driver's algorithm registry
    (so that algorithms registered at run time by a plugin or a test exist here too), and
    death with the driver (Linux ``PR_SET_PDEATHSIG``) so that no orphan writes into ``DIR``."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import torch

    torch.set_num_threads(1)
    from tlac import algorithms as registry

    registry.ALGORITHMS.update(algorithms)
    if die_with_parent and sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            import ctypes

            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
            if os.getppid() == 1:  # the driver is already gone
                os._exit(1)


def _one_line(exc: BaseException) -> str:
    text = f"{type(exc).__name__}: {exc}".strip()
    return text.splitlines()[0] if text else type(exc).__name__


def execute_run(name: str, spec_dict: dict[str, Any], folder: str) -> dict[str, Any]:
    """Train one run into ``folder`` (worker side). Never raises an ``Exception``: a failure
    writes ``error.txt`` and is returned as ``{"status": "failed", "error": ...}``."""
    from tlac.run import train_run

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    (out / ERROR_FILE).unlink(missing_ok=True)
    start = time.time()
    try:
        result = train_run(RunSpec(**spec_dict), out)
    except Exception as exc:
        atomic_write_text(out / ERROR_FILE, traceback.format_exc())
        return {
            "name": name,
            "status": "failed",
            "error": _one_line(exc),
            "wall": time.time() - start,
        }
    return {"name": name, "status": "finished", "result": result, "wall": time.time() - start}


def execute_run_packed(
    name: str, spec_dict: dict[str, Any], algorithms: dict[str, str]
) -> dict[str, Any]:
    """Ray task: train into a temporary folder on this node and return it packed (tar.gz
    bytes, ``result.json`` excluded and returned as a dict) for the driver to write."""
    _init_worker(algorithms, die_with_parent=False)  # Ray manages its own worker processes
    with tempfile.TemporaryDirectory(prefix="tlac-run-") as tmp:
        folder = Path(tmp) / name
        outcome = execute_run(name, spec_dict, str(folder))
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:gz") as tar:
            for p in sorted(folder.rglob("*")):
                if p.is_file() and p.name != RESULT_FILE:
                    tar.add(p, arcname=str(p.relative_to(folder)))
        outcome["archive"] = buf.getvalue()
    return outcome


def unpack_run(outcome: dict[str, Any], folder: Path) -> None:
    """Driver side of :func:`execute_run_packed`: replace ``folder`` with the packed files, then
    write ``result.json`` last and atomically (finished runs only)."""
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    with tarfile.open(fileobj=io.BytesIO(outcome["archive"]), mode="r:gz") as tar:
        tar.extractall(folder, filter="data")
    if outcome["status"] == "finished":
        atomic_write_text(folder / RESULT_FILE, json.dumps(outcome["result"], indent=2))


# --------------------------------------------------------------------------- live display


def latest_step(folder: Path) -> int:
    """Environment steps a running run has reached: the last ``episodes.csv`` row's timestep
    (0 if none yet). Reads only the file's tail."""
    path = folder / "episodes.csv"
    try:
        with path.open("rb") as fh:
            fh.seek(0, os.SEEK_END)
            fh.seek(max(0, fh.tell() - 256))
            last = fh.read().decode(errors="replace").strip().splitlines()[-1]
        return int(float(last.split(",")[0]))
    except (OSError, ValueError, IndexError):  # no file, header only, or a torn last line
        return 0


def _fmt_time(seconds: float | None) -> str:
    if seconds is None or seconds != seconds or seconds == float("inf"):
        return "--:--:--"
    s = int(seconds)
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


class Display:
    """Runs done / running / failed and an estimate of the time left.

    The estimate is steps-based: ``(steps left) / (steps done per second so far)``, counting a
    running run's progress from its ``episodes.csv`` when its folder is visible (local runner),
    else only finished runs. On a terminal it redraws one live panel (``rich``); elsewhere it
    prints one line per finished or failed run.
    """

    def __init__(
        self, todo: list[GridRun], skipped: int, out: Path, workers: int, live: bool | None = None
    ):
        from rich.console import Console

        self.todo = {r.name: r for r in todo}
        self.total_runs = len(todo) + skipped
        self.skipped = skipped
        self.out = out
        self.workers = workers
        self.console = Console(stderr=True, soft_wrap=True)
        self.live_mode = self.console.is_terminal if live is None else live
        self.running: set[str] = set()
        self.done: set[str] = set()
        self.failed: set[str] = set()
        self.start = time.time()
        self._live: Any = None
        self.total_steps = sum(r.spec.steps for r in todo)

    def __enter__(self) -> Display:
        if self.live_mode:
            from rich.live import Live

            self._live = Live(
                self._render(), console=self.console, refresh_per_second=2, transient=False
            )
            self._live.__enter__()
        else:
            self.console.print(
                f"{self.total_runs} runs: {self.skipped} already finished, {len(self.todo)} to run "
                f"with {self.workers} worker(s) -> {self.out}"
            )
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._live is not None:
            self._live.update(self._render())
            self._live.__exit__(*exc)

    def steps_done(self, peek_running: bool) -> int:
        steps = sum(self.todo[n].spec.steps for n in self.done | self.failed)
        if peek_running:
            steps += sum(
                min(latest_step(run_dir(self.out, n)), self.todo[n].spec.steps)
                for n in self.running
            )
        return steps

    def eta(self, peek_running: bool = True) -> float | None:
        done = self.steps_done(peek_running)
        elapsed = time.time() - self.start
        if done <= 0 or elapsed <= 0:
            return None
        return (self.total_steps - done) / (done / elapsed)

    def _render(self) -> Any:
        from rich.text import Text

        done = len(self.done) + self.skipped
        text = Text()
        text.append(f"runs {done}/{self.total_runs} done", style="bold green")
        text.append(f" | {len(self.running)} running | ")
        text.append(f"{len(self.failed)} failed", style="bold red" if self.failed else "")
        text.append(
            f" | elapsed {_fmt_time(time.time() - self.start)} "
            f"| time left ~{_fmt_time(self.eta(self.peek))}"
        )
        for name in sorted(self.running):
            step = latest_step(run_dir(self.out, name)) if self.peek else 0
            text.append(
                f"\n  running {name}"
                + (f"  step {step:,}/{self.todo[name].spec.steps:,}" if self.peek else "")
            )
        return text

    peek = True

    def refresh(self) -> None:
        if self._live is not None:
            self._live.update(self._render())

    def started(self, name: str) -> None:
        self.running.add(name)
        self.refresh()

    def finished(self, name: str, wall: float) -> None:
        self.running.discard(name)
        self.done.add(name)
        if not self.live_mode:
            self.console.print(
                f"[{len(self.done) + self.skipped}/{self.total_runs}] "
                f"finished {name} in {wall:.1f}s "
                f"(time left ~{_fmt_time(self.eta(self.peek))})"
            )
        self.refresh()

    def failed_run(self, name: str, error: str) -> None:
        self.running.discard(name)
        self.failed.add(name)
        self.console.print(f"FAILED {name}: {error}")
        self.refresh()


# --------------------------------------------------------------------------- runners


def select_runs(runs: list[GridRun], only: str | None) -> list[GridRun]:
    """The runs whose name matches one of the comma-separated shell patterns ``only`` (all
    runs when ``None``), e.g. ``*__tlac__*`` or ``*3noisy*,*teacher-l*``; a pattern list that
    matches nothing is a ConfigError naming a few run names."""
    if only is None:
        return runs
    patterns = [p.strip() for p in only.split(",") if p.strip()]
    chosen = [r for r in runs if any(fnmatch.fnmatchcase(r.name, p) for p in patterns)]
    if not chosen:
        examples = ", ".join(r.name for r in runs[:3])
        raise ConfigError(
            f"--only {only!r} matches none of the grid's runs (they are named like {examples})"
        )
    return chosen


def _plan(
    config: ExperimentConfig, store: RunStore, only: str | None = None
) -> tuple[list[GridRun], int]:
    runs = select_runs(expand_grid(config), only)
    todo = [r for r in runs if store.status(r.name) != "finished"]
    return todo, len(runs) - len(todo)


def _registry() -> dict[str, str]:
    from tlac import algorithms as registry

    return dict(registry.ALGORITHMS)


def run_local(
    config: ExperimentConfig,
    out_dir: str | Path,
    workers: int = 1,
    live: bool | None = None,
    on_event: Callable[[str, str], None] | None = None,
    only: str | None = None,
) -> GridSummary:
    """Run every unfinished run of ``config`` (matching ``only``, see :func:`select_runs`) in
    ``workers`` parallel processes on this machine."""
    if workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {workers}")
    out = Path(out_dir)
    with _grid_session(config, out, only) as (todo, summary):
        if not todo:
            return summary
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")

        def new_pool() -> ProcessPoolExecutor:
            return ProcessPoolExecutor(
                max_workers=min(workers, len(todo)),
                mp_context=ctx,
                initializer=_init_worker,
                initargs=(_registry(),),
            )

        pool = new_pool()
        futures: dict[Future[dict[str, Any]], GridRun] = {}
        queue = list(todo)
        try:
            with Display(todo, summary.skipped, out, workers, live=live) as display:

                def submit_more() -> None:
                    # keep exactly `workers` runs in flight, so "running" is what really runs
                    while queue and len(futures) < workers:
                        r = queue.pop(0)
                        folder = str(run_dir(out, r))
                        futures[pool.submit(execute_run, r.name, asdict(r.spec), folder)] = r
                        display.started(r.name)

                submit_more()
                while futures:
                    done, _ = wait(list(futures), timeout=1.0, return_when=FIRST_COMPLETED)
                    broken = False
                    for fut in done:
                        r = futures.pop(fut)
                        try:
                            outcome = fut.result()
                        except BrokenProcessPool as exc:  # a worker was killed (e.g. out of memory)
                            broken = True
                            outcome = {
                                "status": "failed",
                                "error": f"worker process died: {_one_line(exc)}",
                                "wall": 0.0,
                            }
                            folder = run_dir(out, r)
                            folder.mkdir(parents=True, exist_ok=True)
                            atomic_write_text(folder / ERROR_FILE, outcome["error"] + "\n")
                        _record(summary, display, r.name, outcome, on_event)
                    if broken:  # a broken pool fails every call: replace it, go on with the rest
                        pool.shutdown(wait=False, cancel_futures=True)
                        pool = new_pool()
                    submit_more()
                    display.refresh()
        except KeyboardInterrupt:
            summary.interrupted = True
        finally:
            pool.shutdown(wait=not summary.interrupted, cancel_futures=True)
    return summary


def _record(
    summary: GridSummary,
    display: Display,
    name: str,
    outcome: dict[str, Any],
    on_event: Callable[[str, str], None] | None,
) -> None:
    if outcome["status"] == "finished":
        summary.finished.append(name)
        display.finished(name, outcome.get("wall", 0.0))
    else:
        summary.failed[name] = outcome["error"]
        display.failed_run(name, outcome["error"])
    if on_event is not None:
        on_event(outcome["status"], name)


def run_ray(
    config: ExperimentConfig,
    out_dir: str | Path,
    address: str | None = None,
    workers: int | None = None,
    live: bool | None = None,
    ray_init_kwargs: dict[str, Any] | None = None,
    only: str | None = None,
) -> GridSummary:
    """Run every unfinished run of ``config`` (matching ``only``) as one Ray task each.

    ``address=None`` starts a local Ray instance with ``workers`` CPUs; otherwise
    ``ray.init(address=...)`` joins a running cluster (``auto``, or ``HEAD:6379``) and
    ``workers``, if given, caps the runs in flight. The driver writes every run folder into
    ``DIR`` itself (workers return them packed), so ``DIR`` need only exist on the driver.
    """
    try:
        import ray
    except ImportError as exc:  # pragma: no cover - ray is an optional dependency
        raise ConfigError("--backend ray needs Ray: pip install 'tlac[ray]'") from exc
    out = Path(out_dir)
    with _grid_session(config, out, only) as (todo, summary):
        if not todo:
            return summary
        kwargs: dict[str, Any] = {
            "include_dashboard": False,
            "ignore_reinit_error": True,
            "log_to_driver": False,
        }
        if address is None:
            # "local": always a new instance here, even when an earlier `ray start` left a
            # cluster file behind (Ray would otherwise try to join it and refuse num_cpus)
            kwargs["address"] = "local"
            kwargs["num_cpus"] = workers or os.cpu_count() or 1
        else:
            kwargs["address"] = address
        kwargs.update(ray_init_kwargs or {})
        started_here = not ray.is_initialized()
        try:
            with _stderr_silenced():  # Ray's core logs every retry: our error says it in one line
                ray.init(logging_level="ERROR", **kwargs)
        except Exception as exc:  # noqa: BLE001 - Ray raises several kinds, all multi-line
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            where = "a local Ray instance" if address is None else f"the Ray cluster at {address!r}"
            raise ConfigError(f"cannot start or join {where}: {first[:200]}") from None
        # max_retries: Ray retries a task only when its worker or node dies, not on exceptions
        task = ray.remote(num_cpus=1, max_retries=2)(execute_run_packed)
        in_flight = workers if workers else len(todo)
        registry = _registry()
        refs: dict[Any, GridRun] = {}
        queue = list(todo)
        try:
            with Display(todo, summary.skipped, out, in_flight, live=live) as display:
                display.peek = False  # the folders appear only when a task returns
                while queue or refs:
                    while queue and len(refs) < in_flight:
                        r = queue.pop(0)
                        refs[task.remote(r.name, asdict(r.spec), registry)] = r
                        display.started(r.name)
                    ready, _ = ray.wait(list(refs), num_returns=1, timeout=1.0)
                    for ref in ready:
                        r = refs.pop(ref)
                        try:
                            outcome = ray.get(ref)
                            unpack_run(outcome, run_dir(out, r))
                        except Exception as exc:  # task lost (node died, ...) or unpacking failed
                            outcome = {
                                "status": "failed",
                                "error": f"ray task failed: {_one_line(exc)}",
                            }
                            folder = run_dir(out, r)
                            folder.mkdir(parents=True, exist_ok=True)
                            atomic_write_text(folder / ERROR_FILE, traceback.format_exc())
                        _record(summary, display, r.name, outcome, None)
                    display.refresh()
        except KeyboardInterrupt:
            summary.interrupted = True
            for ref in refs:
                with contextlib.suppress(Exception):
                    ray.cancel(ref, force=True)
        finally:
            if started_here:
                ray.shutdown()
    return summary


def grid_status(
    config: ExperimentConfig, out_dir: str | Path, only: str | None = None
) -> list[tuple[GridRun, str]]:
    """Each run of the grid (matching ``only``) with its status (``finished``/``failed``/
    ``partial``/``missing``), from its folder or from ``runs.tar.xz``."""
    store = RunStore(out_dir)
    return [(r, store.status(r.name)) for r in select_runs(expand_grid(config), only)]
