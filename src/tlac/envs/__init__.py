"""Named domains: an environment factory, its teachers, and its region labels.

Each domain module defines a :class:`Domain` object; they are imported lazily so that the
continuous-control domains' optional dependencies (PyBullet, MuJoCo) are only needed when
those domains are used.

>>> d = get_domain("doorkey")
>>> env = d.make_env()
>>> teachers = make_teachers(d, ["optimal", "random", "random"], env, seed=0)
>>> [t.name for t in teachers]
['optimal', 'random_1', 'random_2']
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from tlac.errors import ConfigError, UnknownNameError
from tlac.teachers.base import NamedTeacher, Teacher, unique_names


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
    """``(name, env, seed) -> Teacher``; the env gives the spaces (and unwrapped state if needed)."""
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


# name -> "module:attribute" of its Domain object
_DOMAINS: dict[str, str] = {
    "doorkey": "tlac.envs.doorkey:DOMAIN",
    "hopper-bullet": "tlac.envs.hopper:BULLET_DOMAIN",
    "hopper": "tlac.envs.hopper:MUJOCO_DOMAIN",
    "pickplace": "tlac.envs.pickplace:DOMAIN",
}


def domain_names() -> list[str]:
    return list(_DOMAINS)


def get_domain(name: str) -> Domain:
    """Look up a domain by name; raises :class:`UnknownNameError` listing the accepted ones."""
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
    good / noisy construction, appendix A.1.1, with any probability)."""
    name, colon, prob_text = spec.partition(":")
    if name not in domain.teacher_names:
        raise UnknownNameError(f"teacher for {domain.name}", name, domain.teacher_names)
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


def make_teachers(domain: Domain, names: list[str], env: gym.Env, seed: int) -> list[Teacher]:
    """Build the named teachers of ``domain`` (``NAME`` or ``NAME:P``, see
    :func:`parse_teacher_spec`); duplicates get distinct seeds and names."""
    from tlac.teachers.wrappers import MixedRandomTeacher

    parsed = [parse_teacher_spec(domain, n) for n in names]
    labels = unique_names(list(names))
    teachers: list[Teacher] = []
    for i, ((name, prob), label) in enumerate(zip(parsed, labels, strict=True)):
        teacher_seed = seed + 1000 * (i + 1)
        teacher = domain.make_teacher(name, env, teacher_seed)
        if prob is not None:
            teacher = MixedRandomTeacher(
                teacher, prob, env.action_space, teacher_seed + 1, name=label
            )
        teachers.append(NamedTeacher(teacher, label))
    return teachers
