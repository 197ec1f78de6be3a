"""Experiment files: the YAML schema, its validation, and the typed config it loads into.

An experiment declares one grid of runs (paper, section 4 and Appendix A): one domain x
named teacher sets x algorithms x seeds, with a step budget and a schedule for evaluating the
student alone. ``docs/experiments.md`` documents every field; a minimal file::

    domain: doorkey
    steps: 500000
    seeds: 5                      # or a list: [0, 1, 2]
    eval: {every: 10000, episodes: 10}
    baseline: a2c                 # the no-advice baseline of the jumpstart (Taylor & Stone 2009)
    teacher_sets:
      3good: [good, good, good]
      2good-1noisy: {label: "2 good + 1 noisy", teachers: [good, good, noisy]}
    algorithms:
      - name: tlac
      - name: tlac
        selector: ucb1            # ablation (Figure 11)
      - name: a2c                 # no advice: one run per seed, no teacher set

Every problem is one :class:`~tlac.errors.ConfigError` whose message names the file, the
field and what is accepted, e.g. ``configs/x.yaml: field 'algorithms[1].name': unknown
algorithm 'foo'; expected one of: tlac, ppo, a2c, dqn-tlql, ac-teach``.
"""

from __future__ import annotations

import ast
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym

from tlac.algorithms import NO_ADVICE, algorithm_names
from tlac.algorithms.common import MAX_SEED
from tlac.argtypes import DEPLOY_MODES
from tlac.domains import DOMAIN_NAME, domain_names, get_domain, gym_id_hint
from tlac.errors import ConfigError, TlacError, read_yaml_file
from tlac.presets import load_preset, preset_names
from tlac.selectors import SELECTOR_NAMES
from tlac.validation import Checks

NO_TEACHERS = "none"
"""Teacher-set key of the no-advice runs (``a2c``/``ppo``): they take no teachers."""

_SLUG = re.compile(r"^[A-Za-z0-9][A-Za-z0-9.+-]*(_[A-Za-z0-9.+-]+)*$")

TOP_KEYS = (
    "name",
    "description",
    "domain",
    "steps",
    "seeds",
    "eval",
    "log_interval",
    "teacher_eval_episodes",
    "baseline",
    "metrics",
    "teacher_sets",
    "algorithms",
)
EVAL_KEYS = ("every", "episodes", "keep_best", "deploy")
METRIC_KEYS = (
    "jumpstart_window",
    "final_window",
    "threshold",
    "curve_points",
    "bootstrap_reps",
    "bootstrap_seed",
)
TEACHER_SET_KEYS = ("label", "teachers")
ALGORITHM_KEYS = ("name", "label", "preset", "overrides", "selector", "seeds", "teacher_sets")


@dataclass(frozen=True)
class EvalSchedule:
    """Evaluation of the student alone (the low-level policy, no teacher)."""

    every: int | None = None
    """Evaluate every this many environment steps; ``None``: only at the end of the run."""
    episodes: int = 10
    """Episodes per evaluation (0 disables it)."""
    keep_best: bool = False
    """Deploy each run's student of its best evaluation, scored again on fresh episodes
    (``tlac.run.RunSpec.keep_best``); needs ``every``."""
    deploy: str = "greedy"
    """How each run's student is scored and deployed: greedy, sampled or choose
    (``tlac.run.RunSpec.deploy``)."""

    def __post_init__(self) -> None:
        check = Checks("eval", file=True)
        if self.every is not None:
            check.integer("every", self.every, 1)
        check.integer("episodes", self.episodes, 0)
        if not isinstance(self.keep_best, bool):
            raise check.error("keep_best", "true or false", self.keep_best)
        if self.keep_best and (self.every is None or self.episodes == 0):
            raise check.error(
                "keep_best", "eval.every and eval.episodes > 0 with it", self.keep_best
            )
        if self.deploy not in DEPLOY_MODES:
            raise check.error("deploy", f"one of {', '.join(DEPLOY_MODES)}", self.deploy)
        if self.deploy == "choose" and self.episodes == 0:
            raise check.error("deploy", "greedy or sampled with episodes: 0", self.deploy)


@dataclass(frozen=True)
class MetricSettings:
    """Settings of the report's metrics (``tlac.experiments.metrics``)."""

    jumpstart_window: int = 10_000
    """Jumpstart: mean training return over the first this many steps, minus the baseline's."""
    final_window: int | None = None
    """Final performance: mean training return over the last this many steps
    (``None``: the last 10% of the budget)."""
    threshold: float | None = None
    """Time to threshold: first step at which the mean training curve reaches this return."""
    curve_points: int = 100
    """Points of the common step grid that learning curves are resampled onto."""
    bootstrap_reps: int = 2000
    """Bootstrap resamples for the interquartile-mean confidence intervals."""
    bootstrap_seed: int = 0
    """Random state of the bootstrap (fixed, so that reports are reproducible)."""

    def __post_init__(self) -> None:
        check = Checks("metrics", file=True)
        check.integer("jumpstart_window", self.jumpstart_window, 1)
        if self.final_window is not None:
            check.integer("final_window", self.final_window, 1)
        if self.threshold is not None:
            check.number("threshold", self.threshold)
        check.integer("curve_points", self.curve_points, 2)
        check.integer("bootstrap_reps", self.bootstrap_reps, 1)
        check.integer("bootstrap_seed", self.bootstrap_seed, 0)


@dataclass(frozen=True)
class TeacherSet:
    """A named set of the domain's teachers (duplicates allowed: ``[good, good, good]``)."""

    key: str
    """Identifier used in run names and tables (letters, digits, ``. + - _``)."""
    teachers: tuple[str, ...]
    """The domain's teacher names, in the order the algorithms number them."""
    label: str
    """Human-readable name for tables and plot titles."""


@dataclass(frozen=True)
class AlgorithmEntry:
    """One algorithm of the grid, with its hyperparameters."""

    name: str
    """Registered algorithm name (``tlac.algorithms.algorithm_names()``)."""
    key: str
    """Identifier in run names and tables: ``label`` if given, else ``name`` plus
    ``__<selector>`` when TL-AC's high level is not the learned one."""
    preset: str | None = None
    """Preset to start from (``None``: the domain's preset for this algorithm)."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """Hyperparameters that replace the preset's (checked by the algorithm before any run)."""
    selector: str = "learned"
    """TL-AC's high level: learned, random or ucb1 (the Figure 11 ablations)."""
    seeds: tuple[int, ...] | None = None
    """Seeds of this algorithm (``None``: the experiment's); the paper ran AC-Teach on 3."""
    teacher_sets: tuple[str, ...] | None = None
    """Teacher-set keys this algorithm runs on (``None``: all)."""

    @property
    def no_advice(self) -> bool:
        return self.name in NO_ADVICE


@dataclass(frozen=True)
class ExperimentConfig:
    """A validated experiment file (:func:`parse_config` checks the fields against the domain
    and the registries, with the file's name in every message; ``__post_init__`` the rest)."""

    name: str
    """The experiment's name (its grid folder's runs are named after it)."""
    domain: str
    """A registered domain name, or ``module:attribute`` / ``file.py:attribute`` (the file's
    path absolute: a relative one in the YAML is resolved against the YAML's folder)."""
    steps: int
    """Environment steps of every run."""
    seeds: tuple[int, ...]
    """Distinct seeds; every (algorithm, teacher set) runs once per seed."""
    teacher_sets: tuple[TeacherSet, ...]
    """The named teacher sets (none when every algorithm is a no-advice baseline)."""
    algorithms: tuple[AlgorithmEntry, ...]
    """The algorithms of the grid, with distinct keys."""
    eval: EvalSchedule = EvalSchedule()
    """When and how long the student alone is evaluated."""
    log_interval: int = 2000
    """Steps per logging window of ``progress.csv`` and ``teacher_usage.csv``."""
    teacher_eval_episodes: int = 20
    """Episodes to measure each teacher's own return (reference lines in the plots)."""
    baseline: str | None = None
    """Key of the no-advice algorithm that jumpstarts are measured against."""
    metrics: MetricSettings = MetricSettings()
    """Settings of the report's metrics."""
    description: str = ""
    """Free text for the report."""
    source: str = ""
    """The file it was loaded from (for messages)."""
    domain_name: str | None = None
    """The Domain's own name, which prefixes the run folders' names: :attr:`domain` itself
    for a registered name; for a module or file, its Domain's ``name`` when it was imported,
    else what ``DIR/domain.json`` recorded or the file declares (:func:`declared_domain_name`),
    ``None`` when neither is known."""
    raw: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    """The YAML mapping as loaded (copied to ``DIR/experiment.yaml``: :meth:`raw_in`)."""

    def __post_init__(self) -> None:
        check = Checks(self.source or "<experiment>", file=True)
        check.integer("steps", self.steps, 1)
        check.integer("log_interval", self.log_interval, 1)
        check.integer("teacher_eval_episodes", self.teacher_eval_episodes, 0)
        if not self.seeds or len(set(self.seeds)) != len(self.seeds):
            raise check.error("seeds", "a non-empty list of distinct seeds", list(self.seeds))
        keys = [a.key for a in self.algorithms]
        if not keys or len(set(keys)) != len(keys):
            raise check.error("algorithms", "a non-empty list with distinct keys", keys)

    def raw_in(self, folder: str | Path) -> dict[str, Any]:
        """The YAML mapping to write into ``folder`` (``DIR/experiment.yaml``): :attr:`raw`,
        with a relative domain file rewritten relative to ``folder``, so that the copy names
        the same file (absolute where no relative path leads there)."""
        raw = dict(self.raw)
        written = raw.get("domain")
        written_file = domain_file(written) if isinstance(written, str) else None
        parts = domain_file(self.domain)
        if parts is None or written_file is None or Path(written_file[0]).is_absolute():
            return raw
        try:
            raw["domain"] = f"{os.path.relpath(parts[0], os.path.abspath(folder))}:{parts[1]}"
        except ValueError:  # another drive (Windows)
            raw["domain"] = self.domain
        return raw

    def teacher_set(self, key: str) -> TeacherSet:
        for ts in self.teacher_sets:
            if ts.key == key:
                return ts
        raise KeyError(key)

    def algorithm(self, key: str) -> AlgorithmEntry:
        for a in self.algorithms:
            if a.key == key:
                return a
        raise KeyError(key)


MAX_SEEDS = 10_000
"""The most seeds an experiment file may ask for (each one is a run per teacher set and
algorithm): ``seeds: 100000000`` is refused rather than expanded."""


class _Fields(Checks):
    """The checks of an experiment file (:class:`tlac.validation.Checks`, messages
    ``<file>: field '<path>': <problem>``) and the shapes only files have: mappings with
    known keys, slugs, seed lists."""

    def __init__(self, source: str):
        super().__init__(source, file=True)
        self.source = source

    def problem(self, path: str, problem: str) -> ConfigError:
        return ConfigError(f"{self.source}: field '{path}': {problem}")

    def mapping(self, path: str, value: Any, accepted: tuple[str, ...]) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.problem(path, f"expected a mapping, got {type(value).__name__} {value!r}")
        for k in value:
            if k not in accepted:
                prefix = f"{path}." if path else ""
                raise ConfigError(
                    f"{self.source}: field '{prefix}{k}': unknown key {k!r}; "
                    f"expected one of: {', '.join(accepted)}"
                )
        return value

    def slug(self, path: str, value: Any) -> str:
        if not isinstance(value, str) or not _SLUG.match(value):
            raise self.problem(
                path,
                f"expected a name of letters, digits and '. + - _' (no '__', not starting "
                f"with a symbol), got {value!r}",
            )
        return value

    def string(self, path: str, value: Any) -> str:
        if not isinstance(value, str):
            raise self.problem(path, f"expected a string, got {value!r}")
        return value

    def choice(
        self, path: str, value: Any, kind: str, accepted: list[str] | tuple[str, ...]
    ) -> str:
        if value not in accepted:
            raise self.problem(
                path, f"unknown {kind} {value!r}; expected one of: {', '.join(accepted)}"
            )
        return value

    def seeds(self, path: str, value: Any) -> tuple[int, ...]:
        if isinstance(value, int) and not isinstance(value, bool):
            count = self.integer(path, value, 1)
            if count > MAX_SEEDS:
                raise self.error(path, f"a number of seeds from 1 to {MAX_SEEDS}", value)
            return tuple(range(count))
        if not isinstance(value, list) or not value or len(value) > MAX_SEEDS:
            raise self.problem(
                path,
                f"expected a number of seeds or a non-empty list of at most {MAX_SEEDS} seeds, "
                f"got {str(value)[:60]}",
            )
        seeds = tuple(self.integer(f"{path}[{i}]", s, 0) for i, s in enumerate(value))
        for i, seed in enumerate(seeds):
            if seed > MAX_SEED:
                raise self.error(f"{path}[{i}]", f"a seed from 0 to {MAX_SEED}", seed)
        if len(set(seeds)) != len(seeds):
            raise self.problem(path, f"seeds must be distinct, got {list(seeds)}")
        return seeds


def _eval_schedule(f: _Fields, value: Any) -> EvalSchedule:
    """The ``eval`` mapping of an experiment file."""
    ev = f.mapping("eval", value, EVAL_KEYS)
    every = ev.get("every")
    keep_best = ev.get("keep_best", False)
    if not isinstance(keep_best, bool):
        raise f.problem("eval.keep_best", f"expected true or false, got {keep_best!r}")
    if keep_best and (every is None or ev.get("episodes", 10) == 0):
        raise f.problem(
            "eval.keep_best",
            "it chooses among periodic evaluations: give eval.every and episodes > 0",
        )
    return EvalSchedule(
        every=None if every is None else f.integer("eval.every", every, 1),
        episodes=f.integer("eval.episodes", ev.get("episodes", 10), 0),
        keep_best=keep_best,
        deploy=ev.get("deploy", "greedy"),
    )


def domain_file(spec: str) -> tuple[str, str] | None:
    """``("path/to/my_domain.py", "DOMAIN")`` for a domain named by file
    (``path/to/my_domain.py:DOMAIN``); ``None`` for a name or ``module:attribute``."""
    module, colon, attr = spec.rpartition(":")
    return (module, attr) if colon and module.endswith(".py") else None


def resolve_domain_file(spec: str, folder: str | Path, source: str = "<experiment>") -> str:
    """``spec`` with a relative domain file resolved against ``folder`` (the experiment file's
    folder), as an absolute path; names, ``module:attribute`` and absolute paths unchanged.

    Only ``folder`` is searched, never the working directory, so that a file means the same
    domain from wherever it is run. A missing file raises :class:`ConfigError` naming both
    places, and saying so when the working directory has the file."""
    parts = domain_file(spec)
    if parts is None or Path(parts[0]).is_absolute():
        return spec
    file, attr = parts
    where = Path(os.path.abspath(Path(folder) / file))
    if where.is_file():
        return f"{where}:{attr}"
    in_cwd = Path(os.path.abspath(file))
    if in_cwd.is_file():
        try:
            fix = f"{os.path.relpath(in_cwd, os.path.abspath(folder))}:{attr}"
        except ValueError:  # another drive (Windows)
            fix = f"{in_cwd}:{attr}"
        hint = (
            f"{in_cwd} exists, relative to the working directory, but relative paths in an "
            f"experiment file resolve against the file's folder: write '{fix}' (or an "
            f"absolute path)"
        )
    else:
        hint = f"nor {in_cwd}, relative to the working directory"
    raise ConfigError(
        f"{source}: field 'domain': domain file {file!r} not found: no {where} (relative "
        f"paths resolve against the experiment file's folder); {hint}"
    )


def declared_domain_name(spec: str) -> str | None:
    """The name that the domain file of ``spec`` (``path/my_domain.py:DOMAIN``) gives its
    Domain, read from its source without running it: a top-level ``DOMAIN = Domain(name="...",
    ...)`` (or ``Domain("...", ...)``). ``None`` for a module, a file that is not there or
    does not parse, or a name given any other way."""
    parts = domain_file(spec)
    if parts is None:
        return None
    try:
        tree = ast.parse(Path(parts[0]).read_bytes())
    except (OSError, SyntaxError, ValueError):
        return None
    name = None
    for node in tree.body:
        if not (
            isinstance(node, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == parts[1] for t in node.targets)
        ):
            continue
        name = None  # the last assignment counts
        call = node.value
        if isinstance(call, ast.Call):
            given = [k.value for k in call.keywords if k.arg == "name"] + call.args[:1]
            if given and isinstance(given[0], ast.Constant) and isinstance(given[0].value, str):
                name = given[0].value
    return name if name is not None and re.fullmatch(DOMAIN_NAME, name) else None


def _domain(f: _Fields, value: Any, folder: Path, import_domain: bool) -> tuple[str, Any]:
    """The ``domain`` field: a registered name, or ``module:attribute`` /
    ``file.py:attribute`` (a relative file resolved against ``folder``), imported unless
    ``import_domain`` is false; returns (the name as the grid uses it, the Domain or
    ``None`` when not imported)."""
    if not (isinstance(value, str) and ":" in value):  # "module:attribute": imported
        if isinstance(value, str) and value not in domain_names() and value in gym.registry:
            raise f.problem("domain", gym_id_hint(value))
        value = f.choice("domain", value, "domain", domain_names())
    elif not import_domain:
        parts = domain_file(value)
        if parts is not None and not Path(parts[0]).is_absolute():
            value = f"{os.path.abspath(folder / parts[0])}:{parts[1]}"
        return value, None
    value = resolve_domain_file(value, folder, f.source)
    try:
        return value, get_domain(value)
    except TlacError as exc:
        raise f.problem("domain", str(exc)) from exc


def parse_config(
    data: Any,
    source: str = "<experiment>",
    folder: str | Path | None = None,
    import_domain: bool = True,
) -> ExperimentConfig:
    """Validate a loaded YAML mapping and build the :class:`ExperimentConfig`.

    A domain named by a relative file (``domain: my_domain.py:DOMAIN``) is resolved against
    ``folder`` (default: the folder of ``source``, the working directory for
    ``"<experiment>"``) and kept as an absolute path (:func:`resolve_domain_file`).
    ``import_domain=False`` (what reports and listings read with) imports no module or file
    named by the domain field: its teacher names and presets go unchecked, and its
    :attr:`~ExperimentConfig.domain_name` is what the file declares (or ``None``).
    Raises :class:`ConfigError` naming ``source``, the field and what is accepted.
    """
    f = _Fields(source)
    if data is None:
        raise ConfigError(
            f"{source}: the file is empty; expected a mapping with keys: {', '.join(TOP_KEYS)}"
        )
    top = f.mapping("", data, TOP_KEYS)
    for required in ("domain", "steps", "seeds", "algorithms"):
        if required not in top:
            raise f.problem(required, "missing (required)")

    folder = Path(folder) if folder is not None else Path(source).parent
    domain_name, domain = _domain(f, top["domain"], folder, import_domain)
    if ":" not in domain_name:
        run_prefix: str | None = domain_name
    else:
        run_prefix = domain.name if domain is not None else declared_domain_name(domain_name)

    name = f.slug(
        "name", top.get("name", Path(source).stem if source != "<experiment>" else "experiment")
    )
    steps = f.integer("steps", top["steps"], 1)
    seeds = f.seeds("seeds", top["seeds"])

    schedule = _eval_schedule(f, top.get("eval") or {})
    log_interval = f.integer("log_interval", top.get("log_interval", 2000), 1)
    teacher_eval_episodes = f.integer(
        "teacher_eval_episodes", top.get("teacher_eval_episodes", 20), 0
    )

    m = f.mapping("metrics", top.get("metrics") or {}, METRIC_KEYS)
    metrics = MetricSettings(
        jumpstart_window=f.integer(
            "metrics.jumpstart_window", m.get("jumpstart_window", 10_000), 1
        ),
        final_window=None
        if m.get("final_window") is None
        else f.integer("metrics.final_window", m["final_window"], 1),
        threshold=None
        if m.get("threshold") is None
        else f.number("metrics.threshold", m["threshold"]),
        curve_points=f.integer("metrics.curve_points", m.get("curve_points", 100), 2),
        bootstrap_reps=f.integer("metrics.bootstrap_reps", m.get("bootstrap_reps", 2000), 1),
        bootstrap_seed=f.integer("metrics.bootstrap_seed", m.get("bootstrap_seed", 0), 0),
    )

    # teacher sets: key -> [names] or {label, teachers}
    raw_sets = top.get("teacher_sets") or {}
    if not isinstance(raw_sets, dict):
        raise f.problem(
            "teacher_sets", f"expected a mapping of set name -> list of teachers, got {raw_sets!r}"
        )
    teacher_sets: list[TeacherSet] = []
    for key, value in raw_sets.items():
        path = f"teacher_sets.{key}"
        f.slug(path, key)
        if key == NO_TEACHERS:
            raise f.problem(path, f"{NO_TEACHERS!r} is reserved for the no-advice runs")
        label = key
        if isinstance(value, dict):
            value = f.mapping(path, value, TEACHER_SET_KEYS)
            if "teachers" not in value:
                raise f.problem(f"{path}.teachers", "missing (required)")
            label = f.string(f"{path}.label", value.get("label", key))
            value = value["teachers"]
            path = f"{path}.teachers"
        if not isinstance(value, list) or not value:
            raise f.problem(path, f"expected a non-empty list of teacher names, got {value!r}")
        for i, t in enumerate(value):
            if domain is not None:
                f.choice(f"{path}[{i}]", t, f"teacher for {domain_name}", domain.teacher_names)
            else:
                f.string(f"{path}[{i}]", t)
        teacher_sets.append(TeacherSet(key=key, teachers=tuple(value), label=label))
    set_keys = [ts.key for ts in teacher_sets]

    raw_algos = top["algorithms"]
    if not isinstance(raw_algos, list) or not raw_algos:
        raise f.problem("algorithms", f"expected a non-empty list of algorithms, got {raw_algos!r}")
    algorithms: list[AlgorithmEntry] = []
    for i, entry in enumerate(raw_algos):
        path = f"algorithms[{i}]"
        if isinstance(entry, str):
            entry = {"name": entry}
        entry = f.mapping(path, entry, ALGORITHM_KEYS)
        if "name" not in entry:
            raise f.problem(f"{path}.name", "missing (required)")
        algo = f.choice(f"{path}.name", entry["name"], "algorithm", algorithm_names())
        if domain is not None and algo not in domain.presets and entry.get("preset") is None:
            raise f.problem(
                f"{path}.name",
                f"algorithm {algo!r} has no preset for domain {domain_name!r}; expected one of: "
                f"{', '.join(domain.presets)} (or give 'preset')",
            )
        preset = entry.get("preset")
        if preset is not None:
            f.choice(f"{path}.preset", preset, "preset", preset_names())
            try:
                load_preset(preset, algo)
            except TlacError as exc:
                raise f.problem(f"{path}.preset", str(exc)) from exc
        overrides = entry.get("overrides") or {}
        if not isinstance(overrides, dict):
            raise f.problem(
                f"{path}.overrides",
                f"expected a mapping of hyperparameter -> value, got {overrides!r}",
            )
        selector = "learned"
        if "selector" in entry:
            if algo != "tlac":
                raise f.problem(
                    f"{path}.selector", f"only algorithm 'tlac' has a selector, not {algo!r}"
                )
            selector = f.choice(f"{path}.selector", entry["selector"], "selector", SELECTOR_NAMES)
        algo_seeds = (
            None if entry.get("seeds") is None else f.seeds(f"{path}.seeds", entry["seeds"])
        )
        algo_sets = None
        if entry.get("teacher_sets") is not None:
            if algo in NO_ADVICE:
                raise f.problem(
                    f"{path}.teacher_sets", f"{algo!r} takes no teachers (a no-advice baseline)"
                )
            if not isinstance(entry["teacher_sets"], list):
                raise f.problem(
                    f"{path}.teacher_sets",
                    f"expected a list of teacher-set names, got {entry['teacher_sets']!r}",
                )
            algo_sets = tuple(
                f.choice(f"{path}.teacher_sets[{j}]", k, "teacher set", set_keys)
                for j, k in enumerate(entry["teacher_sets"])
            )
        if "label" in entry:
            key = f.slug(f"{path}.label", entry["label"])
        else:
            key = algo if selector == "learned" else f"{algo}__{selector}"
        if any(a.key == key for a in algorithms):
            raise f.problem(
                path, f"algorithm {key!r} appears twice; give one of them a distinct 'label'"
            )
        algorithms.append(
            AlgorithmEntry(
                name=algo,
                key=key,
                preset=preset,
                overrides=dict(overrides),
                selector=selector,
                seeds=algo_seeds,
                teacher_sets=algo_sets,
            )
        )
        if algo not in NO_ADVICE and not teacher_sets:
            raise f.problem(
                "teacher_sets", f"algorithm {algo!r} needs teachers but no teacher set is declared"
            )

    baseline = top.get("baseline")
    if baseline is not None:
        f.choice(
            "baseline",
            baseline,
            "baseline algorithm (one of the no-advice entries in 'algorithms')",
            [a.key for a in algorithms if a.no_advice],
        )
    else:
        no_advice = [a.key for a in algorithms if a.no_advice]
        baseline = no_advice[0] if no_advice else None

    description = top.get("description", "")
    return ExperimentConfig(
        name=name,
        domain=domain_name,
        steps=steps,
        seeds=seeds,
        teacher_sets=tuple(teacher_sets),
        algorithms=tuple(algorithms),
        eval=schedule,
        log_interval=log_interval,
        teacher_eval_episodes=teacher_eval_episodes,
        baseline=baseline,
        metrics=metrics,
        description=f.string("description", description) if description else "",
        source=source,
        domain_name=run_prefix,
        raw=dict(top),
    )


def load_config(path: str | Path, import_domain: bool = True) -> ExperimentConfig:
    """Read and validate an experiment YAML file (see the module docstring and
    :func:`parse_config` for ``import_domain``)."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: experiment file not found")
    return parse_config(read_yaml_file(p, "experiment file"), str(p), import_domain=import_domain)
