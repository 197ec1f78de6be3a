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
