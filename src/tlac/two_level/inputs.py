"""What a user passes to TL-AC as ``env`` and ``teachers``, turned into a VecEnv and Teacher
objects (:func:`as_vec_env`, :func:`as_teachers`), with the checks and the settings that
come with them."""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import torch
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv

from tlac.algorithms.common import (
    CheckedEnv,
    check_env_spaces,
    check_seed,
    random_seed,
    space_from_data,
)
from tlac.algorithms.obs_spaces import check_space_kinds
from tlac.domains import domain_names, get_domain, make_teachers, make_vec_env
from tlac.errors import ConfigError
from tlac.recording import EpisodeRecorder, find_episode_recorder
from tlac.teachers.base import Teacher, TeacherSpec, as_teacher, teacher_label, unique_names
from tlac.two_level.config import TLACConfig


def policy_first_error(first: Any) -> str:
    """The error for SB3's argument order, ``TLAC(policy, env)``: ``first`` came before env
    (given by name, or as the teachers)."""
    if not isinstance(first, str):
        return "TLAC got env twice: as its first argument and as env=; pass it once"
    return (
        "TLAC takes the environment first and builds its own networks: TLAC(env, "
        f"teachers=[...]), not SB3's TLAC(policy, env); got {first!r:.60} before env (to "
        "choose the networks' kind, pass policy='MlpPolicy' or 'CnnPolicy' by name)"
    )


def is_gym_id(name: str) -> bool:
    """Whether ``name`` is a registered Gymnasium id and not a tlac domain name (a domain's
    name wins: ``doorkey`` is tlac's)."""
    return name not in domain_names() and name in gym.registry


def as_vec_env(env: Any, n_envs: int, seed: int, vec_env: str = "dummy") -> tuple[VecEnv, Any]:
    """Accept a domain name, a Gymnasium id (``"CartPole-v1"``, made as SB3 makes it), a
    Gymnasium env or an SB3 VecEnv; returns (vec_env, domain|None). A domain name or a
    Gymnasium id gets ``n_envs`` environments in a DummyVecEnv or (``vec_env="subproc"``) a
    SubprocVecEnv."""
    if isinstance(env, str) and is_gym_id(env):  # SB3's TLAC("CartPole-v1")
        env_id = env
        vec_env_class = SubprocVecEnv if vec_env == "subproc" else DummyVecEnv
        env = vec_env_class([lambda: gym.make(env_id) for _ in range(n_envs)])
        env.seed(seed)
    if isinstance(env, str):
        if env not in domain_names():
            raise ConfigError(
                f"unknown environment {env!r}: neither a tlac domain ({', '.join(domain_names())}) "
                "nor a registered Gymnasium id"
            )
        domain = get_domain(env)
        return make_vec_env(domain, n_envs, seed, None, subprocesses=vec_env == "subproc"), domain
    if isinstance(env, VecEnv):
        venv = env
    elif isinstance(env, gym.Env):
        check_space_kinds(env.observation_space)  # before DummyVecEnv trips on a text key
        venv = DummyVecEnv([lambda: CheckedEnv(env)])
        venv.seed(seed)
    else:
        raise ConfigError(
            f"env must be a domain name, a gymnasium.Env or an SB3 VecEnv, got {env!r}"
        )
    if find_episode_recorder(venv) is None:
        venv = EpisodeRecorder(venv)
    return venv, None


def check_made_env_settings(env: Any, settings: dict[str, Any]) -> None:
    """``n_envs`` and ``vec_env`` say how TLAC makes the environments from a name; given (by
    name, not by a preset) with an environment already made, they are one ConfigError line
    unless that environment is what they ask for."""
    if isinstance(env, str):
        return
    made = env.num_envs if isinstance(env, VecEnv) else 1
    if settings.get("vec_env", "dummy") != "dummy" and not isinstance(env, SubprocVecEnv):
        raise ConfigError(
            f"vec_env={settings['vec_env']!r} is how TLAC makes the environments from a name "
            "(a Gymnasium id or a domain), and this env is already made: pass its id, or "
            "SB3's SubprocVecEnv of your environments"
        )
    if "n_envs" in settings and settings["n_envs"] != made:
        raise ConfigError(
            f"n_envs={settings['n_envs']!r} is how many environments TLAC makes from a name "
            f"(a Gymnasium id or a domain), and this env is already made, with {made}: pass "
            "its id, or a VecEnv of that many environments"
        )


def env_name(env: Any, venv: VecEnv) -> str | None:
    """The name a model records of the environment it is trained on (``TLAC.save``): a
    domain's name (also for a VecEnv made by ``tlac.domains.make_vec_env``, as ``tlac
    train`` makes them) or the Gymnasium id given as ``env``; ``None`` when unknown."""
    recorder = find_episode_recorder(venv)
    if recorder is not None and recorder.domain_name is not None:
        return recorder.domain_name
    return env if isinstance(env, str) else None


def other_env_warning(trained_on: str, now: str) -> str:
    """The one line said when a model meets another environment than it was trained on."""
    return (
        f"the model was trained on {trained_on!r} and is used on {now!r}: the observations "
        "may have the same shape and mean something else"
    )


def as_teachers(
    teachers: Sequence[Any], domain: Any, seed: int, action_space: gym.Space
) -> list[Teacher]:
    """What a user passes as ``teachers``: a domain's teacher names (``env`` a domain name), or
    objects / SB3 models or policies / plain functions, named for the logs (unique names); one
    teacher alone (not in a list) is a list of one."""
    if isinstance(teachers, str):
        raise ConfigError(
            f"teachers must be a list, got the string {teachers!r}; did you mean [{teachers!r}]?"
        )
    if callable(teachers) or hasattr(teachers, "predict") or isinstance(teachers, TeacherSpec):
        teachers = [teachers]  # one function, object, model or spec
    teachers = [t.resolve(action_space) if isinstance(t, TeacherSpec) else t for t in teachers]
    if teachers and all(isinstance(t, str) for t in teachers):
        if domain is None:
            raise ConfigError(
                "teacher names need env to be a domain name, e.g. TLAC('doorkey', ['optimal'])"
            )
        return make_teachers(domain, list(teachers), domain.make_env(), seed)
    names = unique_names([teacher_label(t, i) for i, t in enumerate(teachers)])
    return [as_teacher(t, action_space, n) for t, n in zip(teachers, names, strict=True)]


def with_teacher_terms(config: TLACConfig, teachers: Any, names: list[str]) -> TLACConfig:
    """``config`` with the cost and availability of every :class:`TeacherSpec` among
    ``teachers`` (by position; ``names``: the run's teacher names) in its ``teacher_cost`` and
    ``availability`` settings. A teacher given both ways must be given the same value."""
    if isinstance(teachers, TeacherSpec):
        teachers = [teachers]
    if not isinstance(teachers, Sequence) or isinstance(teachers, str):
        return config
    terms = config.advice
    costs, chances = dict(terms.teacher_cost), dict(terms.availability)
    for teacher, name in zip(teachers, names, strict=False):
        if not isinstance(teacher, TeacherSpec):
            continue
        for setting, values, value, default in (
            ("teacher_cost", costs, teacher.cost, 1.0),
            ("availability", chances, teacher.availability, 1.0),
        ):
            if name in values and values[name] != value:
                raise ConfigError(
                    f"teacher {name!r} has {setting} {value!r} in its TeacherSpec and "
                    f"{values[name]!r} in the settings; give it once"
                )
            if value != default:
                values[name] = value
    if (costs, chances) == (terms.teacher_cost, terms.availability):
        return config
    terms = dataclasses.replace(terms, teacher_cost=costs, availability=chances)
    return dataclasses.replace(config, advice=terms)


@dataclasses.dataclass(frozen=True)
class ModelInputs:
    """What a model is built on (:func:`resolve_inputs`)."""

    config: TLACConfig  # with the TeacherSpecs' costs and availabilities
    env: VecEnv | None  # None: a loaded model given no env
    n_envs: int
    env_name: str | None  # the domain or Gymnasium id trained on, where known
    observation_space: gym.Space
    action_space: gym.Space
    teachers: list[Teacher]
    teacher_names: list[str]


def resolve_inputs(
    config: TLACConfig,
    seed: int,
    env: Any,
    teachers: Sequence[Any] | None,
    saved: dict[str, Any] | None = None,
) -> ModelInputs:
    """The environments, spaces and teachers of a new model or (``saved``: a model file's
    contents) a loaded one, whose spaces and teacher names come from the file: ``env`` is then
    optional and must match those spaces, and ``teachers``, when given, must be as many as at
    save time."""
    venv, domain, n_envs = None, None, 1
    trained_on = None if saved is None else saved.get("env_name")
    name = trained_on if isinstance(trained_on, str) else None
    if saved is None or env is not None:  # a loaded model steps its envs in-process
        venv, domain = as_vec_env(
            env, config.n_envs, seed, config.vec_env if saved is None else "dummy"
        )
        n_envs = venv.num_envs
        now = env_name(env, venv)
        if name is not None and now is not None and now != name:
            warnings.warn(other_env_warning(name, now), stacklevel=4)
        name = name or now
    if saved is None:
        assert venv is not None
        obs_space, action_space = venv.observation_space, venv.action_space
        if config.batch_size > config.n_steps * n_envs:
            raise ConfigError(
                f"batch_size {config.batch_size} exceeds the rollout size n_steps * n_envs = "
                f"{config.n_steps * n_envs}; set batch_size to at most that"
            )
    else:
        obs_space = space_from_data(saved["observation_space"])
        action_space = space_from_data(saved["action_space"])
        if venv is not None:
            check_env_spaces(venv, obs_space, action_space)
    made = as_teachers([] if teachers is None else teachers, domain, seed, action_space)
    names = [t.name for t in made] if saved is None else saved["teacher_names"]
    if saved is not None and teachers is not None and len(made) != len(names):
        raise ConfigError(
            f"the model was trained with {len(names)} teachers ({', '.join(names) or 'none'}); "
            f"got {len(made)}"
        )
    if saved is None and teachers is not None:
        config = with_teacher_terms(config, teachers, names)
    return ModelInputs(config, venv, n_envs, name, obs_space, action_space, made, list(names))


def seed_torch(seed: int | None, torch_threads: int | None) -> int:
    """A new model's seed (None: as SB3, a random one), with torch's threads and global
    generator set for the networks' initialisation."""
    seed = random_seed() if seed is None else check_seed(seed)
    if torch_threads is not None:  # before the initialisation: its orthogonal
        torch.set_num_threads(torch_threads)  # matrices (QR) differ with the threads
    torch.manual_seed(seed)  # the networks' initialisation
    return seed


def other_vec_env(
    env: Any, n_envs: int, seed: int, obs_space: gym.Space, action_space: gym.Space
) -> VecEnv:
    """``env`` for ``TLAC.set_env``: a VecEnv of the model's spaces and ``n_envs``
    environments, else a ConfigError."""
    venv, _ = as_vec_env(env, n_envs, seed)
    check_env_spaces(venv, obs_space, action_space)
    if venv.num_envs != n_envs:
        raise ConfigError(
            f"set_env: the model steps {n_envs} environments at a time, got "
            f"{venv.num_envs} (TLAC.load(path, env=...) sets them at load time)"
        )
    return venv


def check_can_learn(env: VecEnv | None, teachers: list[Teacher], names: list[str]) -> None:
    """A model learns with environments and as many teachers as it was trained with."""
    if env is None:
        raise ConfigError("this model has no environment: pass env= to TLAC.load to train it")
    if len(teachers) != len(names):
        raise ConfigError(
            f"this model was trained with {len(names)} teachers "
            f"({', '.join(names)}); "
            "pass the same number as teachers= to TLAC.load to train it further"
        )
