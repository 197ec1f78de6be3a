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
