"""One training run -> one run folder. Used by ``tlac train`` and by the experiment runners.

The folder layout is documented in ``docs/architecture.md``. A run counts as finished only
once ``result.json`` exists; it is written last, atomically (temporary file + rename).

>>> spec = RunSpec(env="doorkey", teachers=["optimal", "random"], steps=2000)
>>> spec.resolved_preset()
'doorkey'
"""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import json
import os
import shutil
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
import yaml
from filelock import FileLock, Timeout

from tlac.algorithms import NO_ADVICE, get_algorithm
from tlac.algorithms.common import check_seed, safe_torch_load
from tlac.argtypes import DEPLOY_MODES
from tlac.domains import (
    Domain,
    ParsedTeacher,
    get_domain,
    is_gym_domain,
    make_teachers,
    make_vec_env,
    parse_teachers,
)
from tlac.errors import ConfigError, StorageError, UnknownNameError, read_yaml_file
from tlac.evaluation import evaluate_student
from tlac.presets import SCHEDULE_HORIZON, load_preset, settle_variant_values, stretch_schedules
from tlac.recording import MONITOR_FILE, Recorder, platform_record
from tlac.selectors import SELECTOR_NAMES
from tlac.teachers.files import check_teacher_files

RESULT_FILE = "result.json"
CHECKPOINT = "checkpoint.pt"
CHECKPOINT_EVERY = 50_000
"""Steps between the checkpoints of a run (TL-AC, DQN-TLQL and AC-Teach save their training
state in them: exact resume)."""
LOCK_FILE = ".run.lock"
BEST_MODEL = "model-best"
"""keep_best: the model of the best evaluation so far, while the run trains."""
LAST_MODEL = "model-last"
"""keep_best: the last weights, where the best evaluation's model became ``model``."""
RUN_FILES = (
    "episodes.csv",
    MONITOR_FILE,
    "teacher_usage.csv",
    "progress.csv",
    "eval.csv",
    "tb",
    CHECKPOINT,
    "checkpoint.zip",
    "model.pt",
    "model.zip",
    "model-best.pt",
    "model-best.zip",
    "model-last.pt",
    "model-last.zip",
    "config.yaml",
    "advice.csv",  # a person's answers (tlac teach, tlac.human)
    "human_episodes.csv",
    RESULT_FILE,
)


@dataclass
class RunSpec:
    """Everything that defines one run. Written, resolved, to ``config.yaml``."""

    env: str = "doorkey"
    """Domain name (``tlac envs`` lists them)."""
    algo: str = "tlac"
    """Algorithm: tlac, ppo, a2c, dqn-tlql, ac-teach."""
    teachers: list[str] | None = None
    """Teacher names of the domain; ``None`` = the domain's default set; ignored by ppo/a2c."""
    seed: int = 0
    steps: int = 50_000
    """Total environment steps (over all parallel environments)."""
    selector: str = "learned"
    """TL-AC's high level: learned (the paper), random, or ucb1 (per episode; Figure 11)."""
    preset: str | None = None
    """Hyperparameter preset file; ``None`` = the domain's preset for this algorithm."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """Hyperparameters that replace the preset's."""
    eval_every: int | None = None
    """Evaluate the student alone every this many steps (``None``: only at the end)."""
    eval_episodes: int = 10
    """Episodes per evaluation of the student alone (0 disables evaluation)."""
    log_interval: int = 2000
    """Steps per teacher-usage / progress logging window."""
    keep_best: bool = False
    """With ``eval_every``: deploy the student of the best periodic evaluation rather than the
    last weights, as SB3's ``EvalCallback`` keeps a best model. ``model`` is then that student
    (the last weights stay in ``model-last``), and ``final_eval_mean`` is its return on
    ``eval_episodes`` fresh episodes (other seeds than the evaluations that chose it: the best
    of several noisy evaluations overstates the student). Training itself is unchanged."""
    deploy: str = "greedy"
    """How the student is deployed and scored: ``greedy`` (``predict(deterministic=True)``),
    ``sampled`` (``predict``'s default, as SB3's) or ``choose``: every evaluation scores both
    and counts the higher (the greedy one on a tie), and the run's mode is the one its last
    evaluation (with ``keep_best``: its best) chose, scored again on fresh episodes.
    ``result.json``'s ``deploy_mode`` names it, and ``tlac eval`` acts in it. Sampled actions
    are drawn apart from the model's generators: training is unchanged."""
    tensorboard: bool = False

    def resolved_preset(self) -> str:
        if self.preset is not None:
            return self.preset
        domain = get_domain(self.env)
        if self.algo not in domain.presets:
            raise UnknownNameError(f"algorithm for {self.env}", self.algo, list(domain.presets))
        return domain.presets[self.algo]

    def validate(self) -> Domain:
        """Check every field; returns the domain. Raises :class:`ConfigError` naming the field.
        The teachers' names are parsed by :func:`resolve_run`."""
        domain = get_domain(self.env)
        get_algorithm(self.algo)
        if not isinstance(self.steps, int) or isinstance(self.steps, bool) or self.steps <= 0:
            raise ConfigError(f"steps must be a positive integer, got {self.steps!r}")
        check_seed(self.seed)
        if self.selector not in SELECTOR_NAMES:
            raise UnknownNameError("selector", self.selector, SELECTOR_NAMES)
        if self.selector != "learned" and self.algo != "tlac":
            raise ConfigError(
                f"--selector {self.selector} replaces TL-AC's high level; {self.algo} has none "
                "(use it with --algo tlac)"
            )
        if self.eval_every is not None and not _is_int(self.eval_every, 1):
            raise ConfigError(
                f"eval_every must be a positive number of steps, got {self.eval_every!r}"
            )
        if not _is_int(self.eval_episodes, 0):
            raise ConfigError(f"eval_episodes must be an integer >= 0, got {self.eval_episodes!r}")
        if not _is_int(self.log_interval, 1):
            raise ConfigError(f"log_interval must be a positive integer, got {self.log_interval!r}")
        if self.teachers is not None and (
            not isinstance(self.teachers, list | tuple)
            or not all(isinstance(t, str) for t in self.teachers)
        ):
            raise ConfigError(f"teachers must be a list of teacher names, got {self.teachers!r}")
        if not isinstance(self.overrides, dict):
            raise ConfigError(f"overrides must be a mapping of settings, got {self.overrides!r}")
        if not isinstance(self.keep_best, bool):
            raise ConfigError(f"keep_best must be true or false, got {self.keep_best!r}")
        if self.deploy not in DEPLOY_MODES:
            raise UnknownNameError("deploy", self.deploy, list(DEPLOY_MODES))
        if self.deploy == "choose" and self.eval_episodes == 0:
            raise ConfigError(
                "deploy choose chooses on the evaluations' episodes: give eval_episodes > 0"
            )
        samples = getattr(get_algorithm(self.algo), "samples_actions", True)
        if self.deploy != "greedy" and not samples:
            raise ConfigError(
                f"deploy {self.deploy}: {self.algo}'s student acts greedily only; use greedy"
            )
        if self.keep_best and (self.eval_every is None or self.eval_episodes == 0):
            raise ConfigError(
                "keep_best chooses among periodic evaluations: give eval_every (--eval-every) "
                "and eval_episodes > 0"
            )
        if is_gym_domain(domain) and self.algo not in NO_ADVICE and not self.teachers:
            raise ConfigError(
                f"{self.env!r} is a Gymnasium id, with no teachers of its own: give --teachers "
                "path/to/file.py:NAME (a function of one observation, an object with predict or "
                "an SB3 model), path/to/agent.zip (an SB3 / rl-zoo agent, with --trust-pickle) "
                "or random, comma-separated"
            )
        return domain


def _is_int(value: Any, minimum: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= minimum


@dataclass(frozen=True)
class ResolvedRun:
    """One run with every setting worked out (:func:`resolve_run`), handed down to the model
    and the run folder's writers, which work none out again."""

    spec: RunSpec
    """The run as given."""
    domain: Domain
    teachers: tuple[ParsedTeacher, ...]
    """The teachers as named (the domain's default set where none were given; none for the
    algorithms without advice), parsed once."""
    preset: str
    """The preset's name (``spec.preset``, or the domain's preset for the algorithm)."""
    hyperparameters: dict[str, Any]
    """The preset's settings with the overrides, ``n_envs`` first (1 unless set): what the
    algorithm is given and config.yaml records."""
    settings: Any
    """The algorithm's validated settings, built once (``check_hyperparameters``'s: TL-AC's
    TLACConfig, ...), or None where it returns none."""
    trust_pickle: bool = False
    """Open the SB3 agents named as teachers (``--trust-pickle``; tlac.teachers.files)."""

    @property
    def teacher_kinds(self) -> list[str]:
        """The teachers as named (config.yaml's ``teacher_kinds``)."""
        return [t.spec for t in self.teachers]

    @property
    def n_envs(self) -> int:
        return int(self.hyperparameters["n_envs"])


def resolve_run(spec: RunSpec, trust_pickle: bool = False) -> ResolvedRun:
    """The one place where what a user gave (``tlac train``, the Python API, an experiment's
    run, a resumed run's config.yaml) becomes a run: every field checked, the teachers
    parsed, the preset chosen and applied with the overrides, the algorithm's settings built
    and validated. Raises :class:`ConfigError` naming what is wrong, before anything is built
    or written; ``trust_pickle``: see :class:`ResolvedRun`."""
    domain = spec.validate()
    named = domain.default_teachers if spec.teachers is None else spec.teachers
    kinds = [] if spec.algo in NO_ADVICE else list(named)
    teachers = tuple(parse_teachers(domain, kinds))
    check_teacher_files(kinds, trust_pickle)
    hp = hyperparameters(spec)
    check = getattr(get_algorithm(spec.algo), "check_hyperparameters", None)
    settings = None if check is None else check(hp)  # optional (docs/architecture.md)
    check_in_process(hp)
    # n_envs first, as config.yaml always had it; the model is told it too (it checks the
    # VecEnv against it), so that its settings record the environments it ran with
    hp = {"n_envs": int(hp.get("n_envs", 1)), **{k: v for k, v in hp.items() if k != "n_envs"}}
    return ResolvedRun(
        spec, domain, teachers, spec.resolved_preset(), hp, settings, bool(trust_pickle)
    )


def check_in_process(hp: dict[str, Any]) -> None:
    """A run folder's environments stay in this process (its checkpoints keep what re-creates
    their episodes in progress, for an exact resume): ``vec_env: subproc`` is refused with
    that reason."""
    if hp.get("vec_env", "dummy") != "dummy":
        raise ConfigError(
            "vec_env=subproc is for the Python API (TLAC(..., vec_env='subproc')): a run of "
            "tlac train keeps its environments in process, so that its checkpoints can resume "
            "exactly"
        )


def hyperparameters(spec: RunSpec) -> dict[str, Any]:
    """The preset's settings for ``spec.algo`` with ``spec.overrides`` applied (an override
    ``schedule_horizon`` stretches the linear schedules: :func:`tlac.presets.stretch_schedules`)."""
    hp = load_preset(spec.resolved_preset(), spec.algo)
    if "preset" in spec.overrides:
        raise ConfigError(
            "the preset is chosen with --preset (or an algorithm's 'preset' in an experiment "
            "file), not with --set preset=..."
        )
    if "selector" in spec.overrides:
        raise ConfigError(
            "the high level is chosen with --selector (or an algorithm's 'selector' in an "
            "experiment file), not with --set selector=..."
        )
    hp.update(spec.overrides)
    if SCHEDULE_HORIZON in hp:  # a run shorter than the paper's, on the paper's schedules
        hp = stretch_schedules(hp, spec.steps, hp.pop(SCHEDULE_HORIZON))
    if spec.algo == "tlac":
        hp["selector"] = spec.selector
        hp = settle_variant_values(hp)  # config.yaml records the value that runs
    return hp


def atomic_write_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _clear_run_folder(out: Path) -> None:
    for name in RUN_FILES:
        p = out / name
        if p.is_dir():
            shutil.rmtree(p)
        elif p.exists():
            p.unlink()


def check_out_folder(out: Path, run: ResolvedRun, replace: bool) -> None:
    """Refuse to write a run into ``out`` when that would destroy something: a finished run,
    another run's files, or anything else (unless ``replace``). An unfinished run of the same
    settings is accepted (it continues or is redone). Raises ConfigError naming the folder and
    the way out."""
    _check_usable_path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {str(out)!r} is a file; expected a folder for the run")
    if replace and out.exists() and not _is_run_folder(out):
        raise ConfigError(
            f"--out {str(out)!r} holds files that are not a run's; --force replaces a run "
            "folder only: give another folder"
        )
    if replace or not out.exists() or all(p.name == LOCK_FILE for p in out.iterdir()):
        return
    if (out / RESULT_FILE).exists():
        raise ConfigError(
            f"--out {str(out)!r} holds a finished run; "
            "give another folder, or --force to replace it"
        )
    if not _same_settings(out, run):
        raise ConfigError(
            f"--out {str(out)!r} is not empty and is not an unfinished run of these settings; "
            "give another folder, or --force to replace its run files"
        )


def _check_usable_path(out: Path) -> None:
    """ConfigError when the file system refuses the path itself (a name longer than it allows,
    a component that is a file): said before anything is written."""
    try:
        out.exists()
    except OSError as exc:
        limit = ""
        if exc.errno == errno.ENAMETOOLONG:
            with contextlib.suppress(OSError, ValueError):
                limit = f" (at most {os.pathconf('/', 'PC_NAME_MAX')} bytes a name)"
        raise ConfigError(f"--out {str(out)!r} cannot be used: {exc.strerror}{limit}") from None


def _is_run_folder(out: Path) -> bool:
    """Whether ``out`` holds a run (a run's config.yaml) or only files a run writes: what
    ``--force`` may replace."""
    config = out / "config.yaml"
    if config.is_file():
        try:
            data = yaml.safe_load(config.read_text())
        except (OSError, UnicodeDecodeError, yaml.YAMLError):
            return False
        return isinstance(data, dict) and {"env", "algo"} <= set(data)
    return all(
        p.name in RUN_FILES or p.name == LOCK_FILE or ".tmp" in p.name for p in out.iterdir()
    )


@contextlib.contextmanager
def folder_lock(lock_file: Path, busy: str) -> Iterator[None]:
    """Hold an exclusive lock on ``lock_file`` (``filelock``: Linux, macOS and Windows;
    released even when the process is killed); a lock held elsewhere is ConfigError(busy)."""
    lock = FileLock(str(lock_file))
    try:
        lock.acquire(timeout=0)
    except Timeout:
        raise ConfigError(busy) from None
    except OSError as exc:  # a read-only folder, or one this user may not write
        raise StorageError(f"cannot write {str(lock_file.parent)!r}: {exc.strerror}") from None
    try:
        yield
    finally:
        lock.release()


OLD_RUN_DEFAULTS = {"deploy": "greedy", "keep_best": False}
"""RunSpec fields added after runs were made, with the value those runs had: a ``config.yaml``
without the field was written for it."""


def _same_settings(out: Path, run: ResolvedRun) -> bool:
    """Whether ``out/config.yaml`` was written for exactly ``run``."""
    try:
        saved = yaml.safe_load((out / "config.yaml").read_text()) or {}
    except (OSError, yaml.YAMLError):
        return False
    resolved = ("teachers", "preset")  # config.yaml has them resolved
    return (
        isinstance(saved, dict)
        and saved.get("teacher_kinds") == run.teacher_kinds
        and saved.get("preset") == run.preset
        and all(
            saved.get(k, OLD_RUN_DEFAULTS.get(k)) == v
            for k, v in dataclasses.asdict(run.spec).items()
            if k not in resolved
        )
    )


def _checkpoint_run_state(out: Path) -> dict[str, Any] | None:
    """What the run's writers need to continue from ``out/checkpoint.pt`` (saved in the same
    file as the model and its training state); None without such a checkpoint."""
    return _read_checkpoint(out)[0]


def _read_checkpoint(out: Path) -> tuple[dict[str, Any] | None, str | None]:
    """:func:`_checkpoint_run_state`, and the environment the checkpoint's model was trained
    on (a domain's name, as TL-AC records it; None where unknown)."""
    if not (out / CHECKPOINT).exists():
        return None, None
    state = safe_torch_load(out / CHECKPOINT, "checkpoint")
    if not isinstance(state, dict):
        return None, None
    run_state, trained_on = state.get("run"), state.get("env_name")
    return (
        run_state if isinstance(run_state, dict) and "training" in state else None,
        trained_on if isinstance(trained_on, str) else None,
    )


def _names_domain(env: Any, name: str) -> bool:
    """Whether the ``env`` of a config.yaml is the domain ``name`` (by that name, or a
    ``module:attribute`` / ``file.py:attribute`` whose Domain is named so)."""
    if env == name:
        return True
    try:
        named = isinstance(env, str) and (":" in env or env in gym.registry)
        return named and get_domain(env).name == name
    except ConfigError:
        return False


def _resumable(out: Path, run: ResolvedRun) -> dict[str, Any] | None:
    """The run state of an unfinished run of ``run`` whose checkpoint holds its training
    state, else None."""
    if (out / RESULT_FILE).exists() or not _same_settings(out, run):
        return None
    return _checkpoint_run_state(out)


def train_run(
    spec: RunSpec | ResolvedRun,
    out_dir: str | Path,
    progress_bar: bool = False,
    on_eval: Any = None,
    replace: bool = True,
    checkpoint_every: int | None = CHECKPOINT_EVERY,
    fresh: bool = False,
    trust_pickle: bool = False,
    on_model: Any = None,
) -> dict[str, Any]:
    """Train one run described by ``spec`` and write its run folder; returns ``result.json``'s
    content. Every setting is checked before anything is written (:func:`resolve_run`; a
    :class:`ResolvedRun` is used as it is). An unfinished run of the same settings at
    ``out_dir`` (no ``result.json``) continues from its last checkpoint when it has one with
    the training state (TL-AC, DQN-TLQL, AC-Teach), else is redone from scratch; with
    ``replace=False`` (``tlac train`` without ``--force``) a finished run or a folder holding
    anything else is refused (:func:`check_out_folder`). The folder is locked while the run
    writes it. ``on_eval(timestep, student_alone_mean, training_return)`` is called after
    every evaluation of the student alone (``training_return``: mean of the recent training
    episodes, teachers included, or ``None`` before the first episode ends). ``fresh``: never
    continue from a checkpoint (``tlac train --force``). ``trust_pickle``: open the SB3
    agents named as teachers (``--trust-pickle``; tlac.teachers.files; a ResolvedRun carries
    its own). ``on_model(model, out)``: called with the model once it is built or loaded from
    the checkpoint, before it learns (tlac teach hands it to the person's page)."""
    run = spec if isinstance(spec, ResolvedRun) else resolve_run(spec, trust_pickle)
    if not str(out_dir).strip():
        raise ConfigError("--out '' names no folder; expected the run folder's path")
    out = Path(out_dir)
    check_out_folder(out, run, replace)
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot write the run folder {str(out)!r}: {exc.strerror}") from None
    try:
        with (
            storage_errors(out, run.spec.algo),
            folder_lock(out / LOCK_FILE, f"--out {str(out)!r} is in use by another tlac process"),
        ):
            meta = None if fresh else _resumable(out, run)
            return _train_locked(
                run,
                out,
                progress_bar=progress_bar,
                on_eval=on_eval,
                checkpoint_every=checkpoint_every,
                meta=meta,
                on_model=on_model,
            )
    except ConfigError:  # refused when the model was built (its memory): leave no folder
        if created and not (out / CHECKPOINT).exists():
            shutil.rmtree(out, ignore_errors=True)
        raise


def resume_run(
    run_dir: str | Path,
    progress_bar: bool = False,
    on_eval: Any = None,
    checkpoint_every: int | None = CHECKPOINT_EVERY,
    trust_pickle: bool = False,
    on_model: Any = None,
) -> dict[str, Any]:
    """Continue the unfinished run in ``run_dir`` from its last checkpoint (``tlac train
    --resume``). With TL-AC, DQN-TLQL and AC-Teach the continuation is exact: the run files end
    byte-identical to an uninterrupted run's (the rows written after the checkpoint are dropped
    and redone)."""
    out = Path(run_dir)
    config = load_run_config(out)
    if (out / RESULT_FILE).exists():
        raise ConfigError(f"{str(out)!r} is a finished run; nothing to resume")
    meta, trained_on = _read_checkpoint(out)
    if meta is None:
        raise ConfigError(
            f"{str(out)!r} has no checkpoint to resume from "
            "(TL-AC, DQN-TLQL and AC-Teach runs write one every --checkpoint-every steps)"
        )
    if trained_on is not None and not _names_domain(config["env"], trained_on):
        raise ConfigError(
            f"{str(out / 'config.yaml')!r}: env is {config['env']!r}, and the run's checkpoint "
            f"was trained on {trained_on!r}; --resume continues a run on its own environment: "
            f"put env: {trained_on} back, or start a new run (tlac train --env ...)"
        )
    fields = {f.name for f in dataclasses.fields(RunSpec)}
    spec = RunSpec(**{k: v for k, v in config.items() if k in fields})
    spec.teachers = config.get("teacher_kinds", spec.teachers)
    try:  # the model comes from the checkpoint: its settings are checked all the same
        run = resolve_run(spec, trust_pickle)
    except ConfigError as exc:  # config.yaml edited by hand: say which file
        raise ConfigError(f"{str(out / 'config.yaml')!r}: {exc}") from None
    with (
        storage_errors(out, spec.algo),
        folder_lock(out / LOCK_FILE, f"{str(out)!r} is in use by another tlac process"),
    ):
        return _train_locked(
            run,
            out,
            progress_bar=progress_bar,
            on_eval=on_eval,
            checkpoint_every=checkpoint_every,
            meta=meta,
            on_model=on_model,
        )


@contextlib.contextmanager
def storage_errors(out: Path, algo: str) -> Iterator[None]:
    """A run's failures to write (a full disk, a file size limit, a folder turned read-only)
    as one StorageError naming the file and how the run continues."""
    try:
        yield
    except StorageError as exc:  # a model or checkpoint that could not be saved
        raise StorageError(f"{exc}; {_how_to_continue(out, algo)}") from None
    except OSError as exc:
        if exc.errno not in STORAGE_ERRNOS:
            raise
        raise storage_error(out, exc, algo) from None


STORAGE_ERRNOS = frozenset(
    {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EACCES, errno.EPERM}
)
"""The OSErrors that mean a folder cannot be written (disk full, a file size limit, a
read-only file system, no permission)."""


def storage_error(out: Path, exc: OSError, algo: str) -> StorageError:
    """A run folder that could not be written as one :class:`StorageError` naming the file,
    the reason and how the run continues."""
    where = exc.filename or out
    return StorageError(
        f"cannot write {str(where)!r}: {exc.strerror}; {_how_to_continue(out, algo)}"
    )


def _how_to_continue(out: Path, algo: str) -> str:
    try:
        checkpoint = (out / CHECKPOINT).exists()
    except OSError:  # a folder this process may no longer read
        checkpoint = False
    then = (
        f"tlac train --resume {out} continues from its last checkpoint"
        if getattr(get_algorithm(algo), "exact_resume", False) and checkpoint
        else "the same tlac train command starts it again"
    )
    return f"the run stopped unfinished: once the folder can be written, {then}"


def _keep_rows_until(path: Path, last_step: int) -> None:
    """Drop the rows of a run CSV whose timestep (first column) is after ``last_step``, and a
    torn last row (the run was killed while writing it: it has no line end), which the rows
    written next would otherwise continue. A row that does not start with a timestep is a
    ConfigError naming the file and line."""
    if not path.exists():
        return
    data = path.read_bytes()
    lines = data[: data.rfind(b"\n") + 1].splitlines(keepends=True)  # bytes: \r\n stays
    if not lines:  # not even its header: its writer starts it again
        path.unlink()
        return
    kept = lines[:1]
    for number, line in enumerate(lines[1:], start=2):
        try:
            step = float(line.split(b",", 1)[0])
        except ValueError:
            raise ConfigError(
                f"{str(path)!r} line {number} is not a row of this run ({line[:40]!r}; "
                "expected a timestep first): restore the file, or rerun with --force"
            ) from None
        if step <= last_step:
            kept.append(line)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(b"".join(kept))
    os.replace(tmp, path)


def _keep_rows_of_checkpoint(out: Path, num_timesteps: int) -> None:
    """A resumed run's records as they were at its checkpoint, taken at ``num_timesteps``
    (a rollout's end): the rows at that step or before, but ``advice.csv``'s before it only
    (its ``step`` is the run's step before the transition the answer acted in: an answer at
    ``num_timesteps`` was asked in the rollout after the checkpoint, and is asked again)."""
    for name in (
        "episodes.csv",
        "eval.csv",
        "progress.csv",
        "teacher_usage.csv",
        "human_episodes.csv",
    ):
        _keep_rows_until(out / name, num_timesteps)
    _keep_rows_until(out / "advice.csv", num_timesteps - 1)
    _keep_monitor_rows(out / MONITOR_FILE, out / "episodes.csv")


def _keep_monitor_rows(monitor: Path, episodes: Path) -> None:
    """Keep as many episode rows in ``monitor.csv`` (two header lines) as ``episodes.csv``
    (one header line) has: the two files hold the same episodes, in the same order."""
    if not monitor.exists() or not episodes.exists():
        return
    n_episodes = len(episodes.read_bytes().splitlines()) - 1
    lines = monitor.read_bytes().splitlines(keepends=True)
    tmp = monitor.with_name(monitor.name + ".tmp")
    tmp.write_bytes(b"".join(lines[: 2 + n_episodes]))
    os.replace(tmp, monitor)


def _train_locked(
    run: ResolvedRun,
    out: Path,
    progress_bar: bool,
    on_eval: Any,
    checkpoint_every: int | None = None,
    meta: dict[str, Any] | None = None,
    on_model: Any = None,
) -> dict[str, Any]:
    """The run itself, the folder locked; ``meta``: the run state of the checkpoint to
    continue from (None: from scratch)."""
    spec, domain, hp = run.spec, run.domain, run.hyperparameters
    resume = meta is not None
    if meta is not None:
        _keep_rows_of_checkpoint(out, int(meta["num_timesteps"]))
    else:
        meta = {}
        _clear_run_folder(out)

    # small networks: one thread is fastest, and parallel runs must not oversubscribe cores
    torch.set_num_threads(1)
    torch.manual_seed(spec.seed)
    np.random.seed(spec.seed)
    probe_env = domain.make_env()
    teachers = make_teachers(domain, list(run.teachers), probe_env, spec.seed, run.trust_pickle)
    venv = make_vec_env(domain, run.n_envs, spec.seed, out / "episodes.csv")
    recorder = Recorder(
        out,
        [t.name for t in teachers] + ["agent"],
        domain.region_names,
        domain.region_of,
        log_interval=spec.log_interval,
        tensorboard=spec.tensorboard,
    )
    if not resume:  # a resumed run keeps the config.yaml it was started with
        config = {
            **dataclasses.asdict(spec),
            "teachers": [t.name for t in teachers],
            "teacher_kinds": run.teacher_kinds,
            "preset": run.preset,
            "hyperparameters": hp,
        }
        (out / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))

    algo_cls = get_algorithm(spec.algo)
    # the algorithms whose checkpoints hold the training state (save(training_state=True))
    exact = bool(getattr(algo_cls, "exact_resume", False))
    eval_rows: list[tuple[int, float, float, int]] = []
    eval_file = out / "eval.csv"
    if resume:
        model = algo_cls.load(out / CHECKPOINT, env=venv, teachers=teachers, resume=True)
        model.recorder = recorder
        recorder.load_window_state(meta["recorder"])
        eval_rows = [tuple(r) for r in meta["eval_rows"]]  # type: ignore[misc]
    else:
        model = _new_model(run, algo_cls, venv, teachers, recorder)
        eval_file.write_text(",".join(eval_columns(spec.deploy)) + "\n")
        settings = getattr(model, "config", None)
        if dataclasses.is_dataclass(settings):  # every setting as resolved, defaults included
            config["settings"] = dataclasses.asdict(settings)
            (out / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))

    # keep_best: [mean, timestep, mode] of the best evaluation so far; its model is BEST_MODEL
    best: list[Any] | None = meta.get("best_eval")
    if best is not None and len(best) == 2:  # a checkpoint made before runs chose a mode
        best = [*best, spec.deploy]

    def evaluate(timestep: int) -> None:
        nonlocal best
        if spec.eval_episodes <= 0:
            return
        scores = scores_by_mode(model, domain, spec.deploy, spec.eval_episodes, 10_000 + spec.seed)
        row = eval_row(timestep, scores)
        eval_rows.append(row)
        with eval_file.open("a") as f:
            f.write(",".join(str(v) for v in row) + "\n")
        recorder.record_metrics(timestep, eval_metrics(row, spec.deploy))  # the headline figure
        if spec.keep_best and (best is None or row[1] >= best[0]):  # ties: the later one
            model.save(out / BEST_MODEL)
            best = [row[1], timestep, row_mode(row, spec.deploy)]
        if on_eval is not None:
            train_return = venv.mean_recent_return() if venv.episode_returns else None
            on_eval(timestep, row[1], train_return)

    next_eval = meta.get("next_eval", spec.eval_every if spec.eval_every else None)
    next_checkpoint = meta.get("next_checkpoint", checkpoint_every if exact else None)

    def save_checkpoint(timestep: int) -> None:
        """The model with its training state and what the run folder's writers need to
        continue, in ONE file written atomically: a crash at any moment leaves the previous
        checkpoint whole (the writers flush every row, so the CSVs are at least that far)."""
        if not exact:
            model.save(out / "checkpoint")
            return
        run_state = {
            "num_timesteps": timestep,
            "eval_rows": [list(r) for r in eval_rows],
            "next_eval": next_eval,
            "next_checkpoint": next_checkpoint,
            "recorder": recorder.window_state(),
            "best_eval": best,
        }
        model.save(out / "checkpoint", training_state=True, run_state=run_state)

    def callback(algo: Any) -> bool:
        nonlocal next_eval, next_checkpoint
        due = False
        if next_eval is not None and algo.num_timesteps >= next_eval:
            evaluate(algo.num_timesteps)
            next_eval = (algo.num_timesteps // spec.eval_every + 1) * spec.eval_every
            due = True
        if next_checkpoint is not None and algo.num_timesteps >= next_checkpoint:
            next_checkpoint = (algo.num_timesteps // checkpoint_every + 1) * checkpoint_every
            due = True
        if due:
            save_checkpoint(algo.num_timesteps)
        return True

    if on_model is not None:
        on_model(model, out)
    start = time.time()
    if spec.eval_every and not resume:
        evaluate(0)
    if model.num_timesteps < spec.steps:  # a run stopped after its last checkpoint has none left
        model.learn(spec.steps - model.num_timesteps, callback=callback, progress_bar=progress_bar)
    wall = time.time() - start
    recorder.close(model.num_timesteps)
    model.save(out / (LAST_MODEL if spec.keep_best else "model"))
    if not eval_rows or eval_rows[-1][0] != model.num_timesteps:
        evaluate(model.num_timesteps)
    last_row = eval_rows[-1] if eval_rows else None
    deployed = _deploy(spec, out, domain, best, last_row, model.num_timesteps)
    result = {
        "finished": True,
        "steps": int(model.num_timesteps),
        "wall_time_s": round(wall, 3),
        "steps_per_s": round(model.num_timesteps / max(wall, 1e-9), 2),
        "episodes": int(venv.episodes_done),
        # None (JSON null) when no episode finished, rather than a non-standard NaN
        "final_train_return_mean": None if not venv.episode_returns else venv.mean_recent_return(),
        "final_eval_mean": eval_rows[-1][1] if eval_rows else None,
        "final_eval_std": eval_rows[-1][2] if eval_rows else None,
        "deploy_mode": row_mode(eval_rows[-1], spec.deploy) if eval_rows else spec.deploy,
        "platform": platform_record(),
    }
    ledger = getattr(model, "advice", None)
    if ledger is not None and getattr(model, "teacher_names", None):  # TL-AC's answers
        result["advice"] = ledger.summary(list(model.teacher_names))
    kept = getattr(model, "deployed", None)
    if kept is not None:  # the kept student: the step whose student predict deploys
        result["student_kept_from_step"] = int(kept.num_timesteps)
    if deployed is not None:  # keep_best or choose: the deployed student, scored afresh
        result.update(deployed, last_eval_mean=eval_rows[-1][1], last_eval_std=eval_rows[-1][2])
    venv.close()
    probe_env.close()
    atomic_write_text(out / RESULT_FILE, json.dumps(result, indent=2))
    # only now: until result.json exists, a rerun continues from the checkpoint
    for name in (CHECKPOINT, "checkpoint.zip", *_model_files(out, BEST_MODEL)):
        (out / name).unlink(missing_ok=True)
    return result


def _new_model(
    run: ResolvedRun, algo_cls: Any, venv: Any, teachers: list[Any], recorder: Any
) -> Any:
    """The run's model, from its settings as :func:`resolve_run` built them where the
    algorithm takes them (``from_config``), else from its hyperparameters."""
    seed = run.spec.seed
    if run.settings is not None and hasattr(algo_cls, "from_config"):
        return algo_cls.from_config(run.settings, venv, teachers, seed, recorder)
    hp = run.hyperparameters
    return algo_cls(env=venv, teachers=teachers, seed=seed, recorder=recorder, **hp)


def _model_files(out: Path, stem: str) -> list[str]:
    """The names of ``out``'s model files called ``stem`` (.pt: tlac's, .zip: SB3's)."""
    return [stem + ext for ext in (".pt", ".zip") if (out / (stem + ext)).exists()]


def scores_by_mode(
    model: Any, domain: Domain, deploy: str, episodes: int, seed: int
) -> dict[str, np.ndarray]:
    """The student's returns on the same ``episodes`` episodes in each mode ``deploy`` names
    (:data:`~tlac.argtypes.DEPLOY_MODES`: ``choose`` scores greedy, then sampled)."""
    modes = ("greedy", "sampled") if deploy == "choose" else (deploy,)
    return {
        mode: evaluate_student(model, domain, episodes, seed, deterministic=mode == "greedy")
        for mode in modes
    }


def eval_columns(deploy: str) -> list[str]:
    """``eval.csv``'s header: under ``choose`` each row also names the mode it counts and
    both modes' means."""
    base = ["timestep", "mean_return", "std_return", "episodes"]
    return base + (["mode", "greedy_mean", "sampled_mean"] if deploy == "choose" else [])


def eval_row(timestep: int, scores: dict[str, np.ndarray]) -> tuple[Any, ...]:
    """One evaluation's ``eval.csv`` row from its returns per mode (:func:`scores_by_mode`):
    the higher-scoring mode's mean, std and episodes (the first mode, greedy, on a tie), and
    with two modes that mode's name and each mode's mean.

    >>> eval_row(8, {"greedy": np.array([1.0, 3.0]), "sampled": np.array([2.0, 2.0])})
    (8, 2.0, 1.0, 2, 'greedy', 2.0, 2.0)
    >>> eval_row(8, {"sampled": np.array([4.0])})
    (8, 4.0, 0.0, 1)
    """
    means = {mode: float(returns.mean()) for mode, returns in scores.items()}
    mode = max(means, key=means.__getitem__)  # max keeps the first of equal scores
    returns = scores[mode]
    row: tuple[Any, ...] = (timestep, means[mode], float(returns.std()), len(returns))
    if len(scores) > 1:
        row += (mode, means["greedy"], means["sampled"])
    return row


def eval_metrics(row: Sequence[Any], deploy: str) -> dict[str, float]:
    """An evaluation's scalars for ``progress.csv`` and TensorBoard: the student alone as
    counted (``eval.csv``'s mean and std), and where the run does not deploy the greedy student
    the mode's own name: under ``choose`` each mode's mean and ``eval/deploys_sampled`` (1 where
    the sampled student counted).

    >>> eval_metrics((8, 2.0, 1.0, 2), "greedy")
    {'eval/student_alone_mean': 2.0, 'eval/student_alone_std': 1.0}
    >>> eval_metrics((8, 3.0, 0.0, 2, "sampled", 2.0, 3.0), "choose")["eval/deploys_sampled"]
    1.0
    """
    metrics = {"eval/student_alone_mean": float(row[1]), "eval/student_alone_std": float(row[2])}
    if deploy == "choose":
        metrics["eval/greedy_mean"] = float(row[5])
        metrics["eval/sampled_mean"] = float(row[6])
        metrics["eval/deploys_sampled"] = float(row_mode(row, deploy) == "sampled")
    elif deploy == "sampled":
        metrics["eval/sampled_mean"] = float(row[1])
    return metrics


def row_mode(row: Sequence[Any], deploy: str) -> str:
    """The mode an ``eval.csv`` row counts: named in the row under ``choose``, else ``deploy``."""
    return str(row[4]) if deploy == "choose" else deploy


def _deploy(
    spec: RunSpec,
    out: Path,
    domain: Domain,
    best: list[Any] | None,
    last_row: Sequence[Any] | None,
    last_step: int,
) -> dict[str, Any] | None:
    """The deployed student, where a choice made on the evaluations' episodes names it:
    ``keep_best`` copies the best evaluation's model to the run's ``model`` (the last weights
    are in ``model-last``, removed when they are the best); ``choose`` takes the mode that
    evaluation counted. The student is then measured in that mode on ``eval_episodes`` fresh
    episodes (seeds ``30_000 + seed``, none of the evaluations' ``10_000 + seed``): the best
    of several noisy scores overstates the one chosen. Every step can be repeated: a run
    stopped here continues from its checkpoint and comes back to the same files. Returns the
    result's fields, or None when nothing was chosen."""
    if spec.keep_best and best is not None:
        selection, step, mode = best
        for name in _model_files(out, BEST_MODEL):
            suffix = Path(name).suffix
            tmp = out / f"model.tmp{suffix}"
            shutil.copyfile(out / name, tmp)
            os.replace(tmp, out / ("model" + suffix))
        if step == last_step:
            for name in _model_files(out, LAST_MODEL):
                (out / name).unlink()
    elif spec.deploy == "choose" and last_row is not None:
        selection, step, mode = last_row[1], None, row_mode(last_row, spec.deploy)
    else:
        return None
    model = load_run_model(out, spec.algo, trust_pickle=True)  # the file this process wrote
    returns = evaluate_student(
        model, domain, spec.eval_episodes, 30_000 + spec.seed, deterministic=mode == "greedy"
    )
    fields: dict[str, Any] = {
        "final_eval_mean": float(returns.mean()),
        "final_eval_std": float(returns.std()),
        "deploy_mode": mode,
        "deployed_selection_mean": float(selection),
    }
    if step is not None:
        fields["deployed_from_step"] = int(step)
    kept = getattr(model, "deployed", None)  # the deployed model's own kept student
    if kept is not None:
        fields["student_kept_from_step"] = int(kept.num_timesteps)
    return fields


def load_run_model(run: Path, algo: str, trust_pickle: bool = False) -> Any:
    """The model of the run folder ``run``: tlac's ``model.pt`` (plain data and tensors, read
    with ``weights_only=True``) or the SB3 baselines' ``model.zip``, whose pickles can run code
    when loaded: opened only with ``trust_pickle`` (``tlac eval --trust-pickle``)."""
    return get_algorithm(algo).load(run / "model", trust_pickle=trust_pickle)


def load_run_config(run_dir: str | Path) -> dict[str, Any]:
    """The resolved config of a run folder; :class:`ConfigError` if it is not one."""
    path = Path(run_dir)
    if not path.is_dir():
        raise ConfigError(f"run folder {str(path)!r} does not exist")
    cfg = path / "config.yaml"
    if not cfg.exists():
        raise ConfigError(f"{str(path)!r} is not a run folder: config.yaml is missing")
    data = read_yaml_file(cfg, "run config")
    if not isinstance(data, dict) or not {"env", "algo"} <= set(data):
        raise ConfigError(f"{str(cfg)!r} is not a run's config.yaml (no env / algo)")
    try:  # what every command reads of it (tlac train --resume checks the rest)
        for key in ("env", "algo"):
            if not isinstance(data[key], str):
                raise ConfigError(f"{key} must be a name, got {data[key]!r}")
        check_seed(data.get("seed", 0))
    except ConfigError as exc:  # config.yaml edited by hand: say which file
        raise ConfigError(f"{str(cfg)!r}: {exc}") from None
    return data
