"""Named domains: an environment factory, its teachers, and its region labels.

Each domain is a package under ``tlac.domains`` (``doorkey``, ``hopper``, ``pickplace``)
holding its environment, its teachers and its regions, and defining a :class:`Domain` object;
the packages are imported lazily, by name, so that the continuous-control domains' optional
dependencies (PyBullet, MuJoCo) are only needed when those domains are used. This module is
the registry, the teacher-set builder and the vectorised-environment factory.

>>> d = get_domain("doorkey")
>>> env = d.make_env()
>>> teachers = make_teachers(d, ["optimal", "random", "random"], env, seed=0)
>>> [t.name for t in teachers]
['optimal', 'random_1', 'random_2']
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.util
import inspect
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

from tlac.errors import ConfigError, UnknownNameError, import_failure
from tlac.gym_ids import GYM_IDS, register_gym_ids  # noqa: F401  (their former home)
from tlac.recording import EpisodeRecorder
from tlac.teachers.base import NamedTeacher, Teacher, unique_names
from tlac.teachers.files import load_teacher_file, teacher_file
from tlac.teachers.human import is_person_teacher
from tlac.teachers.wrappers import MixedRandomTeacher, RandomTeacher


@dataclass(frozen=True)
class Domain:
    """Everything the library needs to know about one named domain."""

    name: str
    """Registry name, e.g. ``doorkey``."""
    description: str
    """One line for ``tlac envs`` and the docs."""
    make_env: Callable[[], gym.Env]
    """Builds one fresh environment (seeded later through ``reset(seed=...)``)."""
    teacher_names: tuple[str, ...]
    """The named teachers of the paper for this domain (``optimal``, ``good``, ...)."""
    make_teacher: Callable[[str, gym.Env, int], Teacher]
    """``(name, env, seed) -> Teacher``; the env gives the spaces (and unwrapped state if
    needed)."""
    region_names: tuple[str, ...] = ("all",)
    """Names of the state-space regions used for teacher-usage statistics."""
    region_of: Callable[[np.ndarray], np.ndarray] | None = None
    """Batched observations ``(n, *obs_shape)`` -> integer region index per row."""
    presets: dict[str, str] = field(default_factory=dict)
    """Algorithm name -> preset name (see ``tlac.presets``), e.g. ``{"tlac": "doorkey"}``."""
    default_teachers: tuple[str, ...] = ("optimal", "random", "random")
    """Teacher set used by ``tlac train`` when none is given."""
    max_episode_steps: int | None = None
    """Episode length limit (time-limit truncation), for documentation and evaluation."""


DOMAIN_NAME = r"[A-Za-z0-9][A-Za-z0-9._-]*"
"""What a domain's name may be (it names run folders and the Gymnasium id ``tlac/<name>-v0``)."""

# name -> "module:attribute" of its Domain object
_DOMAINS: dict[str, str] = {
    "doorkey": "tlac.domains.doorkey:DOMAIN",
    "doorkey-partial": "tlac.domains.doorkey:PARTIAL_DOMAIN",
    "hopper-bullet": "tlac.domains.hopper:BULLET_DOMAIN",
    "hopper": "tlac.domains.hopper:MUJOCO_DOMAIN",
    "pickplace": "tlac.domains.pickplace:DOMAIN",
}


DEFAULT_PRESET_ALGOS = ("tlac", "ppo", "a2c", "dqn-tlql", "ac-teach")
"""The algorithms that ``presets/default.yaml`` sets for a user's domain without its own."""

# domains added with register_domain, by name; and those named "module:attribute", by that
_USER_DOMAINS: dict[str, Domain] = {}
_IMPORTED: dict[str, Domain] = {}


def register_domain(domain: Domain, replace: bool = False) -> Domain:
    """Add a domain of your own, usable by name from Python (``TLAC("mine", teachers=[...])``),
    ``tlac train --env`` and experiment configs in this process, and as the Gymnasium id
    ``tlac/<name>-v0``. An algorithm without a preset in the domain gets
    ``presets/default.yaml``'s (for TL-AC the one measured on users' environments; for the
    others their own defaults). In another process (``tlac train``, grid workers) name it
    ``module:attribute`` instead: the module is imported and its Domain used (see
    docs/architecture.md, "A domain of your own"). Returns the registered domain.

    >>> import gymnasium as gym
    >>> from tlac.teachers.base import as_teacher
    >>> def teacher(name, env, seed):
    ...     return as_teacher(lambda obs: 1, env.action_space, name=name)
    >>> mine = register_domain(Domain(
    ...     name="cartpole-push-right", description="CartPole, one silly teacher",
    ...     make_env=lambda: gym.make("CartPole-v1"), teacher_names=("right",),
    ...     make_teacher=teacher, default_teachers=("right",)), replace=True)
    >>> mine.presets["tlac"], get_domain("cartpole-push-right") is mine
    ('default', True)
    """
    if not isinstance(domain, Domain):
        raise ConfigError(
            f"register_domain takes a tlac.domains.Domain, got {type(domain).__name__}"
        )
    if not isinstance(domain.name, str) or not re.fullmatch(DOMAIN_NAME, domain.name):
        raise ConfigError(
            f"a domain name must be letters, digits and . _ - (it names run folders and the "
            f"Gymnasium id tlac/<name>-v0), got {domain.name!r}"
        )
    for field_name in ("make_env", "make_teacher"):
        if not callable(getattr(domain, field_name)):
            raise ConfigError(f"domain {domain.name!r}: {field_name} must be callable")
    if not domain.teacher_names or not all(isinstance(t, str) for t in domain.teacher_names):
        raise ConfigError(
            f"domain {domain.name!r}: teacher_names must be a non-empty tuple of names"
        )
    if domain.name in _DOMAINS or (domain.name in _USER_DOMAINS and not replace):
        raise ConfigError(
            f"a domain named {domain.name!r} exists already; pick another name"
            + ("" if domain.name in _DOMAINS else " or pass replace=True")
        )
    missing = {algo: "default" for algo in DEFAULT_PRESET_ALGOS if algo not in domain.presets}
    if missing:  # presets/default.yaml: measured for TL-AC, the others' own defaults
        domain = dataclasses.replace(domain, presets={**domain.presets, **missing})
    if not getattr(domain.make_env, "checks_env", False):
        domain = dataclasses.replace(domain, make_env=_checked_make_env(domain))
    _USER_DOMAINS[domain.name] = domain
    env_id = f"tlac/{domain.name}-v0"
    if env_id in gym.registry:
        del gym.registry[env_id]
    gym.register(id=env_id, entry_point=_gym_factory(domain))
    return domain


def _checked_make_env(domain: Domain) -> Callable[..., gym.Env]:
    """A user's ``make_env`` that checks what it made: anything but a ``gymnasium.Env`` is one
    ConfigError line naming the domain (not an AttributeError deep in training)."""
    make_env = domain.make_env

    @functools.wraps(make_env)  # keeps its signature: gym.make's render_mode is looked up
    def make(*args: object, **kwargs: object) -> gym.Env:
        env = make_env(*args, **kwargs)
        if not isinstance(env, gym.Env):
            raise ConfigError(
                f"domain {domain.name!r}: its make_env returned {type(env).__name__} "
                f"{env!r:.50}; expected a gymnasium.Env, e.g. gym.make('CartPole-v1')"
            )
        return env

    make.checks_env = True  # type: ignore[attr-defined]
    return make


def _gym_factory(domain: Domain) -> Callable[..., gym.Env]:
    """``gym.make("tlac/<name>-v0", render_mode=...)`` for a user's domain: the render mode
    goes to ``make_env`` when it takes one (rl-zoo's video scripts and ``check_env`` ask)."""

    def make(render_mode: str | None = None) -> gym.Env:
        if render_mode is None:
            return domain.make_env()
        parameters = inspect.signature(domain.make_env).parameters
        if "render_mode" not in parameters and not any(
            p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values()
        ):
            raise ConfigError(
                f"domain {domain.name!r}: its make_env takes no render_mode; give it a "
                "render_mode=None parameter (passed to gym.make) to render"
            )
        return domain.make_env(render_mode=render_mode)

    return make


def domain_names() -> list[str]:
    """The built-in domains' names and those registered in this process."""
    return [*_DOMAINS, *_USER_DOMAINS]


def _import_domain(spec: str) -> Domain:
    """``"module:attribute"`` or ``"path/to/file.py:attribute"``: the Domain object
    ``attribute`` of that module (imported, or executed from the file)."""
    module_name, _, attr = spec.rpartition(":")
    try:
        if module_name.endswith(".py"):  # a file: path/to/my_domain.py:DOMAIN
            path = Path(module_name)
            file_spec = importlib.util.spec_from_file_location(path.stem, path)
            if not path.is_file() or file_spec is None or file_spec.loader is None:
                raise ImportError("no such file")
            module = importlib.util.module_from_spec(file_spec)
            file_spec.loader.exec_module(module)
        else:
            module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(f"environment {spec!r}: cannot import {module_name!r} ({exc})") from None
    except Exception as exc:  # the user's module itself: a syntax error, or code that raises
        raise ConfigError(f"environment {spec!r}: {import_failure(exc)}") from None
    domain = getattr(module, attr, None)
    if not isinstance(domain, Domain):
        raise ConfigError(
            f"environment {spec!r}: {module_name}.{attr} is not a tlac.domains.Domain "
            f"(got {type(domain).__name__})"
        )
    _IMPORTED[spec] = register_domain(domain, replace=True)
    return _IMPORTED[spec]


def gym_id_hint(env_id: str) -> str:
    """What to do with a Gymnasium id where a domain is expected (an experiment config)."""
    return (
        f"{env_id!r} is a Gymnasium id, not a tlac domain ({', '.join(domain_names())}): "
        f"from Python TLAC({env_id!r}, teachers=[...]) and tlac train --env {env_id} "
        "--teachers path/to/file.py:NAME take it; experiment configs take a domain file that "
        "makes it and names its teachers, path/to/file.py:DOMAIN (examples/my_domain.py is one "
        "for CartPole-v1)"
    )


_GYM_DOMAINS: dict[str, Domain] = {}


def gym_domain(env_id: str) -> Domain:
    """A registered Gymnasium id as ``tlac train`` and ``tlac eval`` use it: its environment
    made by ``gym.make``, ``random`` its only teacher by name (the others are named by file:
    tlac.teachers.files), ``presets/default.yaml``'s settings (as ``TLAC(env_id)``), and no
    default teachers (tlac cannot guess any)."""
    if env_id not in _GYM_DOMAINS:
        spec = gym.spec(env_id)
        _GYM_DOMAINS[env_id] = Domain(
            name=env_id.replace("/", "_"),  # it names run folders
            description=f"the Gymnasium id {env_id}",
            make_env=functools.partial(gym.make, env_id),
            teacher_names=("random",),
            make_teacher=_random_teacher,
            presets={algo: "default" for algo in DEFAULT_PRESET_ALGOS},
            default_teachers=(),
            max_episode_steps=spec.max_episode_steps,
        )
    return _GYM_DOMAINS[env_id]


def is_gym_domain(domain: Domain) -> bool:
    """Whether ``domain`` is a Gymnasium id's (:func:`gym_domain`)."""
    return any(domain is d for d in _GYM_DOMAINS.values())


def _random_teacher(name: str, env: gym.Env, seed: int) -> Teacher:
    return RandomTeacher(env.action_space, seed, name=name)


def get_domain(name: str) -> Domain:
    """Look up a domain: a built-in or registered name, ``"module:attribute"`` /
    ``"path/to/file.py:attribute"`` naming a Domain object, or a registered Gymnasium id
    (:func:`gym_domain`); raises :class:`UnknownNameError` listing the accepted names."""
    if not isinstance(name, str):
        raise UnknownNameError("environment", repr(name), domain_names())
    if name in _USER_DOMAINS or name in _IMPORTED:
        return _USER_DOMAINS.get(name) or _IMPORTED[name]
    if name not in _DOMAINS and ":" in name:
        return _import_domain(name)
    if name not in _DOMAINS and name in gym.registry:
        return gym_domain(name)
    if name not in _DOMAINS:
        raise UnknownNameError("environment", name, domain_names())
    module_name, attr = _DOMAINS[name].split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:  # optional dependency missing
        raise UnknownNameError(
            "environment (its dependencies are not installed: pip install 'tlac[control]')",
            name,
            domain_names(),
        ) from exc
    return getattr(module, attr)


def parse_teacher_spec(domain: Domain, spec: str) -> tuple[str, float | None]:
    """``"good"`` -> ``("good", None)``; ``"optimal:0.7"`` -> ``("optimal", 0.7)``: the named
    teacher's action with probability 0.7, a uniformly random action otherwise (the paper's
    good / noisy construction, appendix A.1.1, with any probability). A teacher named by file
    (``path/to/file.py:NAME``, ``agent.zip``, an rl-zoo folder: tlac.teachers.files), with any
    domain, gives the file's spec without its ``:P``."""
    if is_person_teacher(spec):  # a person (tlac teach), a recording
        return _person_teacher(spec), None
    found = teacher_file(spec)
    if found is not None:
        name, colon, prob_text = found.source(), found.prob is not None, found.prob or ""
    else:
        name, colon, prob_text = spec.partition(":")  # type: ignore[assignment]
    if found is None and name not in domain.teacher_names:
        raise UnknownNameError(
            f"teacher for {domain.name}",
            name,
            [*domain.teacher_names, "path/to/file.py:NAME", "path/to/agent.zip"],
        )
    if not colon:
        return name, None
    try:
        prob = float(prob_text)
    except ValueError:
        raise ConfigError(
            f"teacher {spec!r}: {prob_text!r} is not a probability in [0, 1]"
        ) from None
    if not 0.0 <= prob <= 1.0:  # NaN fails this too
        raise ConfigError(f"teacher {spec!r}: probability {prob} is outside [0, 1]")
    return name, prob


def _person_teacher(spec: str) -> str:
    """``human`` (the person at tlac teach's page) or ``replay:RUN`` (a person's answers in
    RUN/advice.csv, tlac.teachers.human), checked: a recording that is not there is a
    ConfigError before anything is built."""
    if spec.startswith("replay:"):
        run = Path(spec.removeprefix("replay:"))
        csv_file = run if run.suffix == ".csv" else run / "advice.csv"
        if not csv_file.is_file():
            raise ConfigError(
                f"teacher {spec!r}: {str(csv_file)!r} does not exist (replay:RUN replays the "
                "answers a person gave in the tlac teach run RUN)"
            )
    return spec


def _make_person_teacher(name: str, env: gym.Env, seed: int) -> Teacher:
    """The ``human`` or ``replay:RUN`` teacher (tlac.teachers.human; no web framework needed)."""
    from tlac.teachers.human import HumanTeacher, ReplayTeacher

    if name == "human":
        return HumanTeacher(env.action_space)
    return ReplayTeacher(name.removeprefix("replay:"), env.action_space, seed)


class ParsedTeacher(NamedTuple):
    """A teacher as a run names it (``spec``: ``optimal:0.7``, ``path/to/file.py:NAME``...),
    parsed once (:func:`parse_teachers`): the teacher's ``name`` and its ``prob``."""

    spec: str
    name: str
    prob: float | None


def parse_teachers(domain: Domain, specs: list[str]) -> list[ParsedTeacher]:
    """Each of ``specs`` parsed (:func:`parse_teacher_spec`); an unknown teacher or a bad
    probability is a ConfigError naming it."""
    return [ParsedTeacher(spec, *parse_teacher_spec(domain, spec)) for spec in specs]


def make_teachers(
    domain: Domain,
    names: list[str] | list[ParsedTeacher],
    env: gym.Env,
    seed: int,
    trust_pickle: bool = False,
) -> list[Teacher]:
    """Build the named teachers of ``domain`` (``NAME`` or ``NAME:P``, see
    :func:`parse_teacher_spec`, or as :func:`parse_teachers` parsed them; or named by file,
    an agent's pickles opened only with ``trust_pickle``); duplicates get distinct seeds and
    names."""
    parsed = [
        n if isinstance(n, ParsedTeacher) else ParsedTeacher(n, *parse_teacher_spec(domain, n))
        for n in names
    ]
    labels = unique_names([_teacher_label(p.spec) for p in parsed])
    teachers: list[Teacher] = []
    for i, ((_, name, prob), label) in enumerate(zip(parsed, labels, strict=True)):
        teacher_seed = seed + 1000 * (i + 1)
        person = is_person_teacher(name)
        found = None if person else teacher_file(name)
        if person:
            teacher = _make_person_teacher(name, env, teacher_seed)
        elif found is None:
            teacher = domain.make_teacher(name, env, teacher_seed)
        else:
            teacher = load_teacher_file(found, env, trust_pickle)
        if prob is not None:
            teacher = MixedRandomTeacher(
                teacher, prob, env.action_space, teacher_seed + 1, name=label
            )
        teachers.append(NamedTeacher(teacher, label))
    return teachers


def _teacher_label(spec: str) -> str:
    """A teacher's name in logs: a domain's spec as it is, a file's its object's or agent's
    name (with its ``:P``); a person's recorded answers ``replay``."""
    if spec.startswith("replay:"):
        return "replay"
    found = teacher_file(spec)
    if found is None:
        return spec
    return found.label() + ("" if found.prob is None else f":{found.prob}")


def make_vec_env(
    domain: Domain,
    n_envs: int,
    seed: int,
    episodes_csv: Path | None,
    subprocesses: bool = False,
) -> EpisodeRecorder:
    """``n_envs`` copies of the domain's env in a DummyVecEnv (or, with ``subprocesses``, a
    SubprocVecEnv: one process each), seeded ``seed + i``, recording finished episodes to
    ``episodes_csv``."""
    if not isinstance(n_envs, int) or n_envs <= 0:
        raise ConfigError(f"n_envs must be a positive integer, got {n_envs!r}")
    factories = [domain.make_env for _ in range(n_envs)]
    venv = SubprocVecEnv(factories) if subprocesses else DummyVecEnv(factories)
    venv.seed(seed)
    recorder = EpisodeRecorder(venv, episodes_csv)
    recorder.domain_name = domain.name
    return recorder
