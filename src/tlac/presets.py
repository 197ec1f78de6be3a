"""The paper's hyperparameter tables as named presets, and structured schedules.

Presets live in ``tlac/presets/<name>.yaml``, one mapping per algorithm
(``tlac``, ``ppo``, ``a2c``, ``dqn-tlql``, ``ac-teach``). A schedule is either a number or
``{linear: [start, end]}`` (never an ``eval``'d string, unlike rl-zoo), or, given from Python,
SB3's ``Schedule``: a function of the progress remaining (rl-zoo's ``linear_schedule(3e-4)``):

>>> sched = make_schedule({"linear": [1.0, 0.0]})
>>> sched(1.0), sched(0.25)   # argument: progress remaining, 1 -> 0 as in SB3
(1.0, 0.25)
>>> make_schedule(0.2)(0.5)
0.2
"""

from __future__ import annotations

import bisect
import itertools
import math
import numbers
from collections.abc import Callable
from importlib import resources
from typing import Any

import yaml

from tlac.errors import ConfigError, UnknownNameError

Schedule = Callable[[float], float]


def preset_names() -> list[str]:
    files = resources.files("tlac") / "presets"
    return sorted(p.name[: -len(".yaml")] for p in files.iterdir() if p.name.endswith(".yaml"))


def load_preset(name: str, algo: str) -> dict[str, Any]:
    """The settings of ``algo`` in preset file ``name`` (a fresh dict, safe to modify)."""
    if name not in preset_names():
        raise UnknownNameError("preset", name, preset_names())
    text = (resources.files("tlac") / "presets" / f"{name}.yaml").read_text()
    table = yaml.safe_load(text) or {}
    if algo not in table:
        raise UnknownNameError(f"algorithm in preset {name!r}", algo, list(table))
    return dict(table[algo] or {})


VARIANTS = ("graduate", "paper")
"""TL-AC's variants (``TLACConfig.variant``), the keys of a preset value given per variant."""
DEFAULT_VARIANT = "graduate"


def settle_variant_values(settings: dict[str, Any]) -> dict[str, Any]:
    """``settings`` with every value given per TL-AC variant (``{graduate: 100.0, paper: 0.5}``
    in a preset) replaced by the one of the run's variant (``settings["variant"]``, else
    the default, graduate). A preset gives a value per variant where the paper's table and the
    graduate variant need different ones on the same domain.

    >>> settle_variant_values({"max_grad_norm": {"graduate": 100.0, "paper": 0.5}})
    {'max_grad_norm': 100.0}
    >>> settle_variant_values(
    ...     {"variant": "paper", "max_grad_norm": {"graduate": 100.0, "paper": 0.5}}
    ... )
    {'variant': 'paper', 'max_grad_norm': 0.5}
    """
    variant = settings.get("variant") or DEFAULT_VARIANT
    if variant not in VARIANTS:
        raise UnknownNameError("variant", variant, list(VARIANTS))
    settled = dict(settings)
    for name, value in settings.items():
        if isinstance(value, dict) and value and set(value) <= set(VARIANTS):
            if variant not in value:
                raise ConfigError(
                    f"setting {name} is given per variant ({', '.join(value)}) but not for the "
                    f"run's variant {variant!r}"
                )
            settled[name] = value[variant]
    return settled


def validate_schedule(field: str, value: Any) -> None:
    """Raise :class:`ConfigError` unless ``value`` is a number, ``{linear: [start, end]}`` or a
    function (SB3's ``Schedule``)."""
    if callable(value):
        return
    if isinstance(value, bool):
        raise ConfigError(f"{field}: expected a number or {{linear: [start, end]}}, got {value!r}")
    if isinstance(value, int | float):
        return
    if (
        isinstance(value, dict)
        and list(value) == ["linear"]
        and isinstance(value["linear"], list | tuple)
        and len(value["linear"]) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value["linear"])
    ):
        return
    raise ConfigError(f"{field}: expected a number or {{linear: [start, end]}}, got {value!r}")


def make_schedule(value: Any, field: str = "schedule") -> Schedule:
    """Turn a number or ``{linear: [start, end]}`` into ``f(progress_remaining) -> value``; a
    function is that already (SB3's ``Schedule``), and is returned as it is."""
    validate_schedule(field, value)
    if callable(value):
        return value
    if isinstance(value, dict):
        start, end = (float(v) for v in value["linear"])
        return lambda progress_remaining: end + progress_remaining * (start - end)
    constant = float(value)
    return lambda _progress_remaining: constant


SCHEDULE_HORIZON = "schedule_horizon"
"""The run setting (``--set schedule_horizon=N``, or an experiment's ``overrides``) that makes
a run shorter than the paper's follow the paper's schedules (:func:`stretch_schedules`)."""


def stretch_schedules(hp: dict[str, Any], steps: int, horizon: Any) -> dict[str, Any]:
    """``hp`` with every ``{linear: [start, end]}`` rewritten so that a run of ``steps`` steps
    follows the schedule the paper ran over ``horizon`` steps, up to where the run stops: a
    linear schedule at step ``t`` of the paper's run is ``start + (end - start) * t / horizon``,
    so over ``t`` in ``[0, steps]`` it is the linear schedule from ``start`` to
    ``start + (end - start) * steps / horizon``, exactly (Hopper's Table 8 schedules span 1e6
    steps; our 3e5-step studies stop at 30% of them). Numbers are kept as they are.

    >>> hp = {"learning_rate": {"linear": [5e-4, 3e-5]}, "gamma": 0.99}
    >>> stretch_schedules(hp, 300_000, 1_000_000)
    {'learning_rate': {'linear': [0.0005, 0.000359]}, 'gamma': 0.99}
    >>> stretch_schedules({"clip_range": {"linear": [0.3, 0.1]}}, 10, 5)
    Traceback (most recent call last):
    tlac.errors.ConfigError: schedule_horizon: expected an integer >= the run's 10 steps, got 5
    """
    if isinstance(horizon, bool) or not isinstance(horizon, int) or horizon < steps:
        raise ConfigError(
            f"{SCHEDULE_HORIZON}: expected an integer >= the run's {steps} steps, got {horizon!r}"
        )
    out = dict(hp)
    for key, value in hp.items():
        if isinstance(value, dict) and list(value) == ["linear"]:
            validate_schedule(key, value)
            start, end = (float(v) for v in value["linear"])
            reached = start + (end - start) * steps / horizon
            out[key] = {"linear": [start, round(reached, 12)]}
    return out


AVAILABILITY_FORMS = (
    "a number in (0, 1], {linear: [start, end]} or {steps: [[step, chance], ...]} with chances "
    "in [0, 1], or (from Python) a function of the environment step"
)
"""What a teacher's ``availability`` may be (docs/advice.md)."""


def _chance(value: Any) -> bool:
    """A real number in [0, 1] (not a bool)."""
    return (
        isinstance(value, numbers.Real)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and 0.0 <= value <= 1.0
    )


def availability_problem(value: Any) -> str | None:
    """None where ``value`` is a teacher's availability, else what was expected: a number in
    (0, 1] (0 would be a teacher never there: leave it out), ``{linear: [start, end]}`` over the
    ``learn`` call's progress as :func:`make_schedule`'s, ``{steps: [[step, chance], ...]}``
    (piecewise constant in the environment step, from step 0, steps increasing), each chance in
    [0, 1] (a schedule may reach 0: the teacher has left), or a function of the step.

    >>> availability_problem({"steps": [[0, 1.0], [20_000, 0.0]]}) is None
    True
    >>> availability_problem({"steps": [[100, 1.0]]})
    '{steps: [[step, chance], ...]} starting at step 0, steps increasing, chances in [0, 1]'
    """
    if callable(value):
        return None
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return None if _chance(value) and value > 0 else "in (0, 1]"
    if isinstance(value, dict) and list(value) == ["linear"]:
        try:
            validate_schedule("availability", value)
        except ConfigError:
            return "{linear: [start, end]} with start and end in [0, 1]"
        if all(_chance(v) for v in value["linear"]):
            return None
        return "{linear: [start, end]} with start and end in [0, 1]"
    if isinstance(value, dict) and list(value) == ["steps"]:
        pairs = value["steps"]
        expected = (
            "{steps: [[step, chance], ...]} starting at step 0, steps increasing, chances in [0, 1]"
        )
        if not isinstance(pairs, list | tuple) or not pairs:
            return expected
        steps = []
        for pair in pairs:
            if not (isinstance(pair, list | tuple) and len(pair) == 2 and _chance(pair[1])):
                return expected
            step = pair[0]
            if isinstance(step, bool) or not isinstance(step, numbers.Real):
                return expected
            if not math.isfinite(step) or step != int(step):
                return expected
            steps.append(int(step))
        if steps[0] != 0 or any(b <= a for a, b in itertools.pairwise(steps)):
            return expected
        return None
    return AVAILABILITY_FORMS


def make_availability(value: Any) -> Callable[[int, float], float]:
    """A teacher's availability (checked: :func:`availability_problem`) as ``f(step,
    progress_remaining)``, the chance that it is present in an episode starting at environment
    step ``step`` (``num_timesteps``) of a ``learn`` call whose schedules' progress remaining
    is ``progress_remaining`` (1 -> 0): a number is that number; ``{linear: [start, end]}``
    follows the progress as every tlac schedule (:func:`make_schedule`); ``{steps: ...}`` and a
    function read the step. A function's value is returned as it is (the caller checks it).

    >>> f = make_availability({"steps": [[0, 1.0], [20_000, 0.5], [50_000, 0.0]]})
    >>> f(0, 1.0), f(19_999, 0.5), f(20_000, 0.5), f(10**6, 0.0)
    (1.0, 1.0, 0.5, 0.0)
    >>> make_availability({"linear": [1.0, 0.0]})(123, 0.25)
    0.25
    >>> make_availability(lambda step: 1.0 if step < 100 else 0.0)(100, 1.0)
    0.0
    """
    if callable(value):
        return lambda step, _progress_remaining: value(step)
    if isinstance(value, dict) and list(value) == ["linear"]:
        schedule = make_schedule(value, "availability")
        return lambda _step, progress_remaining: schedule(progress_remaining)
    if isinstance(value, dict) and list(value) == ["steps"]:
        starts = [int(s) for s, _ in value["steps"]]
        chances = [float(c) for _, c in value["steps"]]
        return lambda step, _progress_remaining: chances[bisect.bisect_right(starts, step) - 1]
    constant = float(value)
    return lambda _step, _progress_remaining: constant


def availability_form(value: Any) -> Any:
    """A teacher's availability as a run reports it (result.json, config files): a number as
    a float, a schedule as its mapping, a function as ``"callable"``.

    >>> availability_form(0.5), availability_form(lambda step: 1.0)
    (0.5, 'callable')
    >>> availability_form({"steps": ((0, 1), (10, 0))})
    {'steps': [[0, 1.0], [10, 0.0]]}
    """
    if callable(value):
        return "callable"
    if isinstance(value, dict) and list(value) == ["linear"]:
        return {"linear": [float(v) for v in value["linear"]]}
    if isinstance(value, dict) and list(value) == ["steps"]:
        return {"steps": [[int(s), float(c)] for s, c in value["steps"]]}
    return float(value)
