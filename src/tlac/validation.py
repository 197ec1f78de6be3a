"""The one helper behind every config's checks (TL-AC's, DQN-TLQL's, AC-Teach's settings and
the experiment files): each check raises one :class:`~tlac.errors.ConfigError` that names the
field, the value and what was expected.

tlac's configs share one style: a frozen dataclass with a docstring under every field, checked
in ``__post_init__`` with a :class:`Checks` (so that a config that exists is valid, however it
was built), and built from a preset or file mapping by :func:`from_mapping` (unknown keys and
wrong types named before the dataclass is made).

>>> Checks("dqn-tlql").positive_int("batch_size", 0)
Traceback (most recent call last):
tlac.errors.ConfigError: dqn-tlql setting batch_size must be a positive integer, got 0
>>> Checks("x.yaml", file=True).integer("steps", "5e5", 1)
Traceback (most recent call last):
tlac.errors.ConfigError: x.yaml: field 'steps': expected an integer >= 1, got '5e5'
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Iterable
from typing import Any, TypeVar

import numpy as np

from tlac.errors import ConfigError, UnknownNameError

C = TypeVar("C")


class Checks:
    """Checks of one config's fields. ``owner`` names the config in messages: an algorithm
    (``"TL-AC setting gamma must be in [0, 1], got 2"``) or, with ``file=True``, the file the
    fields come from (``"x.yaml: field 'steps': expected an integer >= 1, got 0"``)."""

    def __init__(self, owner: str, file: bool = False):
        self.owner, self.file = owner, file

    def error(self, name: str, expected: str, value: Any) -> ConfigError:
        """The ConfigError for field ``name`` holding ``value`` where ``expected`` was."""
        if self.file:
            return ConfigError(f"{self.owner}: field '{name}': expected {expected}, got {value!r}")
        return ConfigError(f"{self.owner} setting {name} must be {expected}, got {value!r}")

    def integer(self, name: str, value: Any, minimum: int) -> int:
        """An integer >= ``minimum`` (YAML's ``5e5``, a whole float, counts as one)."""
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not isinstance(value, int | np.integer) or isinstance(value, bool) or value < minimum:
            expected = "a positive integer" if minimum == 1 and not self.file else None
            raise self.error(name, expected or f"an integer >= {minimum}", value)
        return int(value)

    def positive_int(self, name: str, value: Any) -> int:
        """An integer >= 1, not a float."""
        if isinstance(value, float):
            raise self.error(name, "a positive integer", value)
        return self.integer(name, value, 1)

    def number(
        self,
        name: str,
        value: Any,
        low: float = -math.inf,
        high: float = math.inf,
        open_low: bool = False,
        open_high: bool = False,
    ) -> float:
        """A finite number in the interval from ``low`` to ``high`` (open at an end whose
        ``open_*`` is true); NaN is never in it."""
        if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
            raise self.error(name, "a number", value)
        ok = math.isfinite(value) and (value > low if open_low else value >= low)
        ok = ok and (value < high if open_high else value <= high)
        if not ok:
            raise self.error(name, _interval(low, high, open_low, open_high), value)
        return float(value)

    def one_of(self, name: str, value: Any, accepted: Iterable[Any]) -> Any:
        """One of ``accepted`` (an :class:`~tlac.errors.UnknownNameError`, a ConfigError)."""
        accepted = list(accepted)
        if value not in accepted:
            if self.file:
                raise ConfigError(
                    f"{self.owner}: field '{name}': unknown {name.rsplit('.', 1)[-1]} "
                    f"{value!r}; expected one of: {', '.join(map(str, accepted))}"
                )
            error = UnknownNameError(name, value, [str(a) for a in accepted])
            error.args = (f"{self.owner}: {error.args[0]}",)  # which algorithm's setting
            raise error
        return value


def _interval(low: float, high: float, open_low: bool, open_high: bool) -> str:
    """How :meth:`Checks.number` states its interval: ``> 0``, ``>= 0``, ``in (0, 1]``...

    >>> _interval(0, math.inf, True, False), _interval(0.0, 1.0, True, False)
    ('> 0', 'in (0, 1]')
    """

    def text(x: float) -> str:
        return f"{x:g}"

    if high == math.inf:
        return "a finite number" if low == -math.inf else f"{'>' if open_low else '>='} {text(low)}"
    if low == -math.inf:
        return f"{'<' if open_high else '<='} {text(high)}"
    return f"in {'(' if open_low else '['}{text(low)}, {text(high)}{')' if open_high else ']'}"


# --------------------------------------------------------------------------- typed settings
POSITIVE_SETTINGS = frozenset(
    {
        "learning_rate",
        "actor_lr",
        "critic_lr",
        "clip_range",
        "target_kl",
        "optimizer_eps",
    }
)
"""Settings that must be > 0 wherever they appear (a number, or a schedule's end points)."""


def _type_error(algo: str, name: str, expected: str, value: Any) -> ConfigError:
    return Checks(algo).error(name, expected, value)


def _check_number(
    algo: str, name: str, value: Any, integer: bool, schedule_end: bool = False
) -> None:
    """A finite number (whole where ``integer``), > 0 for :data:`POSITIVE_SETTINGS`, or
    >= 0 at a schedule's end (``schedule_end``: SB3's schedules decay to 0)."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise _type_error(algo, name, "an integer" if integer else "a number", value)
    if integer and not isinstance(value, int | np.integer):
        raise _type_error(algo, name, "an integer", value)
    if not np.isfinite(value):
        raise _type_error(algo, name, "a finite number", value)
    if name in POSITIVE_SETTINGS and schedule_end and value < 0:
        raise _type_error(algo, name, ">= 0 at the end of its schedule", value)
    if name in POSITIVE_SETTINGS and not schedule_end and value <= 0:
        raise _type_error(algo, name, "> 0", value)


def _check_schedule(algo: str, name: str, value: dict[str, Any]) -> None:
    """``{linear: [start, end]}`` with two finite end points (where the setting must be > 0:
    the start > 0, the end >= 0)."""
    points = value.get("linear") if len(value) == 1 else None
    if not isinstance(points, list | tuple) or len(points) != 2:
        raise _type_error(algo, name, "a number or {linear: [start, end]}", value)
    _check_number(algo, name, points[0], integer=False)
    _check_number(algo, name, points[1], integer=False, schedule_end=True)


def _check_function_schedule(algo: str, name: str, value: Any) -> None:
    """SB3's ``Schedule``: a function of the progress remaining (1 -> 0) that gives a finite
    number; tried once, at the start (1.0), so that a schedule's factory given uncalled
    (``linear_schedule`` for ``linear_schedule(3e-4)``) is said here rather than mid-run."""
    expected = "a function of the progress remaining (1 -> 0) that returns a number"
    if name in POSITIVE_SETTINGS:
        expected += ", > 0 at the start"
    try:
        start = value(1.0)
    except Exception as exc:  # noqa: BLE001 - whatever the user's function raises, said in one line
        problem = " ".join(f"{type(exc).__name__}: {exc}".split())
        raise _type_error(algo, name, f"{expected} (f(1.0) raised {problem:.120})", value) from None
    try:
        _check_number(algo, name, start, integer=False)
    except ConfigError:
        gave = " ".join(repr(start).split())
        raise _type_error(algo, name, f"{expected} (f(1.0) gave {gave:.60})", value) from None


def check_setting_types(cls: type, values: dict[str, Any], algo: str) -> None:
    """Check every given setting against the type annotation of the dataclass field of the
    same name: booleans are ``true``/``false`` (not strings or numbers), integers are whole,
    numbers are finite (no NaN, no infinity), and the settings of :data:`POSITIVE_SETTINGS`
    are > 0. Schedules (``{linear: [start, end]}``) have their end points checked (the end
    may be 0), and a function schedule its value at the start. Raises one
    :class:`ConfigError` naming the setting and what it accepts.

    >>> from dataclasses import dataclass
    >>> @dataclass
    ... class C:
    ...     learning_rate: float = 1e-3
    ...     normalize: bool = True
    >>> check_setting_types(C, {"learning_rate": float("nan")}, "demo")
    Traceback (most recent call last):
    tlac.errors.ConfigError: demo setting learning_rate must be a finite number, got nan
    >>> check_setting_types(C, {"normalize": "maybe"}, "demo")
    Traceback (most recent call last):
    tlac.errors.ConfigError: demo setting normalize must be true or false, got 'maybe'
    """
    hints = typing.get_type_hints(cls)
    for name, value in values.items():
        hint = hints.get(name)
        if hint is not None:
            _check_type(algo, name, value, hint)


def _check_type(algo: str, name: str, value: Any, hint: Any) -> None:
    text = str(hint)
    if value is None:
        if "None" not in text:
            raise _type_error(algo, name, "set (not null)", value)
        return
    if text == "bool | str":  # a switch with named modes besides true / false (normalize_obs)
        if not isinstance(value, bool | np.bool_ | str):
            raise _type_error(algo, name, "true, false or 'auto'", value)
    elif hint is bool or text.startswith("bool"):
        if not isinstance(value, bool | np.bool_):
            raise _type_error(algo, name, "true or false", value)
    elif hint is int or text in ("int", "int | None", "typing.Optional[int]"):
        _check_number(algo, name, value, integer=True)
    elif callable(value) and "Callable" in text:  # SB3's f(progress_remaining)
        _check_function_schedule(algo, name, value)
    elif text.startswith("dict[str, float]"):  # a number per teacher name (teacher_cost)
        if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
            raise _type_error(algo, name, "a mapping of teacher names to numbers", value)
        for key, number in value.items():
            _check_number(algo, f"{name}[{key!r}]", number, integer=False)
    elif text.startswith("dict[str, typing.Any]"):  # a value per teacher name (availability:
        # a number, a schedule or a function; its owner's own checks read each value)
        if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
            raise _type_error(algo, name, "a mapping of teacher names to values", value)
    elif isinstance(value, dict) and "dict" in text:
        _check_schedule(algo, name, value)
    elif "float" in text:
        _check_number(algo, name, value, integer=False)
    elif "list[int]" in text:
        if not isinstance(value, list | tuple) or not all(
            isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in value
        ):
            raise _type_error(algo, name, "a list of positive integers", value)
    elif text.startswith("str") and not isinstance(value, str):
        raise _type_error(algo, name, "a name (text)", value)


def check_plain_numbers(values: dict[str, Any], algo: str) -> None:
    """For settings without a dataclass (the SB3 baselines): every number is finite, the
    settings of :data:`POSITIVE_SETTINGS` are > 0, and schedules' end points likewise."""
    for name, value in values.items():
        if isinstance(value, dict) and set(value) == {"linear"}:
            _check_schedule(algo, name, value)
        elif isinstance(value, int | float) and not isinstance(value, bool):
            _check_number(algo, name, value, integer=False)


def from_mapping(
    cls: type[C],
    owner: str,
    values: dict[str, Any],
    noun: str = "setting",
    sort_names: bool = False,
) -> C:
    """Build the config dataclass ``cls`` from a mapping (a preset, ``--set`` values,
    keyword arguments): an unknown key raises ConfigError naming it and listing the accepted
    ones (``unknown <owner> <noun> 'key'; expected one of: ...``, in declaration order or
    sorted), a value of the wrong type likewise (:func:`check_setting_types`); the remaining
    checks are the dataclass's own ``__post_init__``.

    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class Demo:
    ...     steps: int = 1
    >>> from_mapping(Demo, "demo", {"stepz": 2})
    Traceback (most recent call last):
    tlac.errors.ConfigError: unknown demo setting 'stepz'; expected one of: steps
    """
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    for key in values:
        if key not in names:
            listed = sorted(names) if sort_names else names
            raise ConfigError(
                f"unknown {owner} {noun} {key!r}; expected one of: {', '.join(listed)}"
            )
    check_setting_types(cls, values, owner)
    return cls(**values)
