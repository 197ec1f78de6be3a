"""Exception types for bad input. Every message names the culprit and what was expected.

The CLI turns any :class:`TlacError` into one line on stderr and exit status 2.
"""

from __future__ import annotations


class TlacError(ValueError):
    """Base class for every user-facing error raised by tlac."""


class ConfigError(TlacError):
    """A setting, config file or command-line value is invalid."""


class UnknownNameError(ConfigError):
    """A name (environment, teacher, algorithm, selector, preset) is not known."""

    def __init__(self, kind: str, name: str, accepted: list[str] | tuple[str, ...]):
        self.kind, self.name, self.accepted = kind, name, list(accepted)
        super().__init__(f"unknown {kind} {name!r}; expected one of: {', '.join(self.accepted)}")


class TrainingError(TlacError):
    """Training diverged (a non-finite loss or gradient); the run stops and is not finished."""


class TeacherError(TlacError):
    """A teacher returned an action that is not a valid member of the action space."""


def require_extra(extra: str, what: str, *modules: str) -> None:
    """ConfigError naming the missing modules and tlac's extra that installs them, unless every
    module in ``modules`` is importable (``import tlac`` and ``learn`` need none of them).

    >>> require_extra("experiments", "tlac report", "json")
    >>> require_extra("experiments", "tlac report", "no_such_module_x")
    Traceback (most recent call last):
    tlac.errors.ConfigError: tlac report needs no_such_module_x, which is not installed: pip install 'tlac[experiments]'
    """
    import importlib.util

    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise ConfigError(
            f"{what} needs {', '.join(missing)}, which {'is' if len(missing) == 1 else 'are'} "
            f"not installed: pip install 'tlac[{extra}]'"
        )


def needs_control_extra(what: str, exc: Exception) -> ConfigError:
    """The error for a continuous-control domain whose simulator is not installed (Gymnasium's
    own message names its extra, not tlac's)."""
    missing = getattr(exc, "name", None)  # an ImportError's module; Gymnasium's names its extra
    detail = f" ({missing})" if missing else ""
    return ConfigError(
        f"{what} needs its simulator, which is not installed{detail}: pip install 'tlac[control]'"
    )


def yaml_problem(exc: Exception) -> str:
    """A YAML parse error as one short line: ``line 3: expected ',' or '}'``."""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    mark = getattr(exc, "problem_mark", None)
    return f"line {mark.line + 1}: {problem}" if mark is not None else str(problem)


def read_yaml_file(path: object, what: str) -> object:
    """Parse the YAML file ``path``; a missing, unreadable or malformed file is one
    :class:`ConfigError` naming the file."""
    from pathlib import Path

    import yaml

    p = Path(str(path))
    try:
        text = p.read_text()
    except FileNotFoundError:
        raise ConfigError(f"{what} {str(p)!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read {what} {str(p)!r}: {exc}") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{str(p)!r}: not valid YAML ({yaml_problem(exc)})") from None
