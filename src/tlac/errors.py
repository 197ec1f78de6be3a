"""Exception types for bad input. Every message names the culprit and what was expected.

The CLI turns any :class:`TlacError` into one line on stderr and exit status 2.
"""

from __future__ import annotations

import traceback


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


class StorageError(TlacError):
    """A folder tlac writes cannot be written: the disk is full, the file system read-only, a
    file size limit reached, or the permission missing."""


class TeacherError(TlacError):
    """A teacher returned an action that is not a valid member of the action space."""


def require_extra(extra: str, what: str, *modules: str) -> None:
    """ConfigError naming the missing modules and tlac's extra that installs them, unless every
    module in ``modules`` is importable (``import tlac`` and ``learn`` need none of them).

    >>> require_extra("experiments", "tlac report", "json")
    >>> require_extra("experiments", "tlac report", "no_such_module_x")
    Traceback (most recent call last):
    tlac.errors.ConfigError: tlac report needs no_such_module_x, which is not installed:
    pip install 'tlac[experiments]'
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
        return strict_yaml_load(text, repr(str(p)))
    except yaml.YAMLError as exc:
        raise ConfigError(f"{str(p)!r}: not valid YAML ({yaml_problem(exc)})") from None
    except RecursionError:
        raise ConfigError(f"{str(p)!r}: nested too deeply to be a tlac file") from None


MAX_YAML_VALUES = 1_000_000
"""The most values a tlac YAML file may expand to, its aliases followed (a 'billion laughs'
document is a few lines that expand to 10**9)."""


def strict_yaml_load(text: str, where: str) -> object:
    r"""``yaml.safe_load`` that refuses, as a ConfigError naming ``where`` and the line, a key
    given twice in one mapping (safe_load keeps the last silently) and a document whose aliases
    expand to more than :data:`MAX_YAML_VALUES` values.

    >>> strict_yaml_load("steps: 5\nseeds: 2\nsteps: 6\n", "x.yaml")
    Traceback (most recent call last):
    tlac.errors.ConfigError: x.yaml: line 3: key 'steps' is given twice (first on line 1);
    give each key once
    """
    import yaml

    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_yaml_node(node, where, {})
        return loader.construct_document(node)
    finally:
        loader.dispose()


def _check_yaml_node(node: object, where: str, sizes: dict[int, int]) -> int:
    """The number of values ``node`` expands to (aliases followed: a shared node is counted
    once per use, computed once), checking each mapping's keys are distinct."""
    import yaml

    if id(node) in sizes:
        return sizes[id(node)]
    size = 1
    if isinstance(node, yaml.MappingNode):
        first: dict[str, int] = {}
        for key, value in node.value:
            if isinstance(key, yaml.ScalarNode) and key.tag != "tag:yaml.org,2002:merge":
                line = key.start_mark.line + 1
                if key.value in first:
                    raise ConfigError(
                        f"{where}: line {line}: key {key.value!r} is given twice (first on line "
                        f"{first[key.value]}); give each key once"
                    )
                first[key.value] = line
            size += _check_yaml_node(key, where, sizes) + _check_yaml_node(value, where, sizes)
    elif isinstance(node, yaml.SequenceNode):
        size += sum(_check_yaml_node(item, where, sizes) for item in node.value)
    if size > MAX_YAML_VALUES:
        raise ConfigError(
            f"{where}: its aliases expand to more than {MAX_YAML_VALUES:,} values; write the "
            "values out rather than nesting aliases"
        )
    sizes[id(node)] = size
    return size


def import_failure(exc: Exception) -> str:
    """Where and why importing a user's domain module failed, in one line: the file and line
    of a syntax error, or of the deepest frame of the module's own code that raised."""
    if isinstance(exc, SyntaxError):
        return f"syntax error in {exc.filename}, line {exc.lineno}: {exc.msg}"
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if "importlib" not in f.filename]
    where = f" in {frames[-1].filename}, line {frames[-1].lineno}" if frames else ""
    detail = str(exc).splitlines()[0] if str(exc) else ""
    return f"importing it raised {type(exc).__name__}{where}" + (f": {detail}" if detail else "")
