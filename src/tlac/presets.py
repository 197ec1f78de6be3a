"""The paper's hyperparameter tables as named presets, and structured schedules.

Presets live in ``tlac/presets/<name>.yaml``, one mapping per algorithm
(``tlac``, ``ppo``, ``a2c``, ``dqn-tlql``, ``ac-teach``). A schedule is either a number or
``{linear: [start, end]}`` (never an ``eval``'d string, unlike rl-zoo):

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


def validate_schedule(field: str, value: Any) -> None:
    """Raise :class:`ConfigError` unless ``value`` is a number or ``{linear: [start, end]}``."""
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
    """Turn a number or ``{linear: [start, end]}`` into ``f(progress_remaining) -> value``."""
    validate_schedule(field, value)
    if isinstance(value, dict):
        start, end = (float(v) for v in value["linear"])
        return lambda progress_remaining: end + progress_remaining * (start - end)
    constant = float(value)
    return lambda _progress_remaining: constant
