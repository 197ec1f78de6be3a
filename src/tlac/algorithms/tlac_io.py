"""TL-AC's input and output: turning what a user passes as ``env`` and ``teachers`` into a VecEnv
and Teacher objects (:func:`as_vec_env`, :func:`as_teachers`); saving and loading a model, with
or without the training state that an exact resume needs (:class:`TLACPersistence`, a mixin of
:class:`tlac.algorithms.two_level.TLAC`); and what ``learn`` logs and shows on its progress bar
(:func:`log_metrics`, :func:`progress_text`)."""

from __future__ import annotations

import copy
import dataclasses
import warnings
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypeVar

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv

from tlac.algorithms.callbacks import check_device
from tlac.algorithms.common import (
    CheckedEnv,
    atomic_torch_save,
    check_env_spaces,
    check_finite_weights,
    checkpoint_path,
    safe_torch_load,
    space_from_data,
    space_to_data,
)
from tlac.algorithms.graduation import StudentSnapshot
from tlac.algorithms.normalization import set_vec_normalize_state, vec_normalize_state
from tlac.algorithms.obs_spaces import ObsPolicy, check_space_kinds
from tlac.algorithms.resume import (
    attributes_state,
    generator_states,
    restore_attributes,
    restore_generator_states,
    restore_vec_env,
    vec_env_state,
)
from tlac.algorithms.tlac_config import SCHEDULES, TLACConfig
from tlac.domains import domain_names, get_domain, make_teachers, make_vec_env
from tlac.errors import ConfigError, TlacError
from tlac.recording import EpisodeRecorder, MetricWindow, find_episode_recorder
from tlac.teachers.base import Teacher, TeacherSpec, as_teacher, teacher_label, unique_names
from tlac.teachers.sb3 import FrozenObsNormalization
from tlac.validation import check_setting_types

PARAMETERS = ("net", "extractor", "log_std", "optimizer", "normalizer", "deployed")
"""What :meth:`TLACPersistence.get_parameters` gives, in a model file's order."""

FORMAT = "tlac.TLAC/2"
"""Checkpoint format: plain data and tensors only (loads with weights_only=True). Format 1
pickled the Gymnasium spaces and needed an unsafe load."""


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
                    f"teacher {name!r} has {setting} {value:g} in its TeacherSpec and "
                    f"{values[name]:g} in the settings; give it once"
                )
            if value != default:
                values[name] = value
    if (costs, chances) == (terms.teacher_cost, terms.availability):
        return config
    terms = dataclasses.replace(terms, teacher_cost=costs, availability=chances)
    return dataclasses.replace(config, advice=terms)


def is_sb3_zip(path: Path) -> bool:
    """Whether ``path`` is a model saved by SB3: a zip archive with SB3's ``data`` (its
    settings, as JSON) at the top (a torch file is a zip too, with its entries in a folder)."""
    if not zipfile.is_zipfile(path):
        return False
    with zipfile.ZipFile(path) as archive:
        return bool({"data", "_stable_baselines3_version"} & set(archive.namelist()))


def read_model_file(path: Path) -> dict[str, Any]:
    """The contents of the TL-AC model file ``path`` (read without running code from it); a
    missing file or another format is a ConfigError naming it."""
    if not path.exists():
        raise ConfigError(f"no TL-AC model at {str(path)!r}")
    if is_sb3_zip(path):
        raise ConfigError(
            f"{str(path)!r} is a stable-baselines3 model, not a TL-AC one: load it with its "
            "SB3 class and pass it as a teacher, e.g. TLAC(env, teachers=[PPO.load(path)])"
        )
    state = safe_torch_load(path, "TL-AC model")
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        found = state.get("format") if isinstance(state, dict) else None
        hint = f" (it is {found}, from an older tlac: retrain it)" if found else ""
        raise ConfigError(f"{str(path)!r} is not a {FORMAT} model file{hint}")
    return state


def loaded_config(
    state: dict[str, Any], custom_objects: dict[str, Any] | None, where: str, resume: bool
) -> TLACConfig:
    """A model file's settings, with ``custom_objects`` (SB3's: settings by name, such as a
    schedule function that the file kept only the value of) in place of the saved ones. A
    function schedule not given again is loaded as its value at save time, with a warning
    (with ``resume``, an error: the resumed run would not follow the same schedule)."""
    if custom_objects is not None and not isinstance(custom_objects, dict):
        raise ConfigError(
            "custom_objects must be a dict of TL-AC settings by name (as SB3's), got "
            f"{type(custom_objects).__name__}"
        )
    custom = dict(custom_objects or {})
    if "lr_schedule" in custom:  # SB3's name of the learning rate's schedule
        custom.setdefault("learning_rate", custom.pop("lr_schedule"))
    unknown = sorted(set(custom) - {f.name for f in dataclasses.fields(TLACConfig)})
    if unknown:
        raise ConfigError(
            f"custom_objects: unknown {unknown}; it takes TL-AC settings by name "
            "(TLACConfig's), e.g. {'learning_rate': 1e-4}"
        )
    functions = [name for name in state.get("functions", []) if name not in custom]
    if functions:
        values = ", ".join(f"{name} {state['config'][name]:.3g}" for name in functions)
        message = (
            f"{where}: a function schedule was saved as its value then ({values}), a model "
            "file holding plain data; to follow it again pass it to TLAC.load as "
            f"custom_objects={{{functions[0]!r}: f}}"
        )
        if resume:
            raise ConfigError(message)
        warnings.warn(message, stacklevel=3)
    check_setting_types(TLACConfig, custom, "TL-AC")
    return TLACConfig(**{**state["config"], **custom})


def file_parameters(state: dict[str, Any]) -> dict[str, Any]:
    """A model file's :data:`PARAMETERS`: ``net``, ``log_std`` and ``optimizer`` it must hold
    (KeyError), the others are None where an older file lacks them."""
    required = ("net", "log_std", "optimizer")
    return {k: state[k] if k in required else state.get(k) for k in PARAMETERS}


def log_metrics(
    model: Any,
    metrics: dict[str, float],
    fps: float,
    episodes: EpisodeRecorder | None,
    sb3_output: bool,
    sb3_only: dict[str, float] | None = None,
) -> None:
    """A logging step of ``model.learn``: the window's statistics, the speed and the recent
    training episodes, to the run folder's progress.csv and (verbose / TensorBoard) SB3's
    logger; ``sb3_only``: scalars for SB3's logger alone (the high level's choices, which a
    run folder keeps per region in teacher_usage.csv)."""
    metrics["time/fps"] = fps
    metrics["time/total_timesteps"] = model.num_timesteps
    if episodes is not None and episodes.episode_returns:
        metrics["rollout/ep_rew_mean"] = episodes.mean_recent_return()
        metrics["rollout/ep_len_mean"] = episodes.mean_recent_length()
    if model.recorder is not None:
        model.recorder.record_metrics(model.num_timesteps, metrics)
    if sb3_output:
        for key, value in {**metrics, **(sb3_only or {})}.items():
            model.logger.record(key, value)
        model.logger.dump(model.num_timesteps)


def progress_text(
    episodes: EpisodeRecorder | None,
    usage: np.ndarray,
    teacher_names: list[str],
    span: str = "recent:",
) -> str:
    """The progress bar's text: the training return (teachers included; the student alone is
    what evaluations print) and the share of each teacher and the agent in the high level's
    choices ``usage`` (counts), made over ``span``: the recent ones while ``learn`` runs, all
    of the call's at its end.

    >>> progress_text(None, np.array([3.0, 1.0]), ["optimal"])
    'training return nan | recent: optimal 75% agent 25%'
    >>> progress_text(None, np.array([26.0, 74.0]), ["optimal"], "all 100 steps:")
    'training return nan | all 100 steps: optimal 26% agent 74%'
    """
    ret = episodes.mean_recent_return() if episodes is not None else float("nan")
    parts = [f"training return {ret:.3g}"]
    if teacher_names and usage.sum() > 0:
        frac = usage / usage.sum()
        names = [*teacher_names, "agent"]
        shares = " ".join(f"{n} {f:.0%}" for n, f in zip(names, frac, strict=True))
        parts.append(f"{span} {shares}")
    return " | ".join(parts)


_Model = TypeVar("_Model", bound="TLACPersistence")


class TLACPersistence:
    """Save / load for :class:`~tlac.algorithms.two_level.TLAC` (its ``config``, networks,
    optimizer, normaliser and, on request, its training state), and the one construction path
    that ``TLAC(...)`` and ``TLAC.load`` share (:meth:`_setup`)."""

    def _setup(
        self,
        config: TLACConfig,
        seed: int,
        env: Any,
        teachers: Sequence[Any] | None,
        recorder: Any,
        saved: dict[str, Any] | None = None,
    ) -> None:
        """Settings, environments, teachers and networks, for a new model or (``saved``: a
        checkpoint's contents) a loaded one, whose spaces and teacher names come from the file:
        ``env`` is then optional and must match those spaces, and ``teachers``, when given,
        must be as many as at save time."""
        self.config, self.seed, self.recorder = config, seed, recorder
        self.saved_vec_normalize: FrozenObsNormalization | None = None  # TLAC.load sets it
        self.num_timesteps = 0 if saved is None else int(saved["num_timesteps"])
        self._last_obs: np.ndarray | None = None
        self.env, domain, self.n_envs = None, None, 1
        trained_on = None if saved is None else saved.get("env_name")
        self.env_name = trained_on if isinstance(trained_on, str) else None
        if saved is None or env is not None:  # a loaded model steps its envs in-process
            vec_env = config.vec_env if saved is None else "dummy"
            self.env, domain = as_vec_env(env, config.n_envs, seed, vec_env)
            self.n_envs = self.env.num_envs
            now = env_name(env, self.env)
            if self.env_name is not None and now is not None and now != self.env_name:
                warnings.warn(other_env_warning(self.env_name, now), stacklevel=4)
            self.env_name = self.env_name or now
        if saved is None:
            obs_space, action_space = self.env.observation_space, self.env.action_space
            if config.batch_size > config.n_steps * self.n_envs:
                raise ConfigError(
                    f"batch_size {config.batch_size} exceeds the rollout size n_steps * n_envs = "
                    f"{config.n_steps * self.n_envs}; set batch_size to at most that"
                )
        else:
            obs_space = space_from_data(saved["observation_space"])
            action_space = space_from_data(saved["action_space"])
            if self.env is not None:
                check_env_spaces(self.env, obs_space, action_space)
        self.teachers = as_teachers(
            [] if teachers is None else teachers, domain, seed, action_space
        )
        names = [t.name for t in self.teachers] if saved is None else saved["teacher_names"]
        if saved is not None and teachers is not None and len(self.teachers) != len(names):
            raise ConfigError(
                f"the model was trained with {len(names)} teachers ({', '.join(names) or 'none'}); "
                f"got {len(self.teachers)}"
            )
        if saved is None and teachers is not None:
            self.config = with_teacher_terms(config, teachers, names)
        self._build(obs_space, action_space, names)

    def set_env(self, env: Any, force_reset: bool = True) -> None:
        """Train on other environments from now on (SB3's ``set_env``): a VecEnv, a Gymnasium
        env or id, with the model's spaces and number of environments. ``force_reset``: start
        new episodes at the next ``learn`` (SB3's default); False continues the current ones,
        which only makes sense for the same environments."""
        venv, _ = as_vec_env(env, self.n_envs, self.seed)
        check_env_spaces(venv, self.observation_space, self.action_space)
        if venv.num_envs != self.n_envs:
            raise ConfigError(
                f"set_env: the model steps {self.n_envs} environments at a time, got "
                f"{venv.num_envs} (TLAC.load(path, env=...) sets them at load time)"
            )
        self.env, self.n_envs = venv, venv.num_envs
        if force_reset:
            self._last_obs = None

    def save(
        self,
        path: str | Path,
        training_state: bool = False,
        run_state: dict[str, Any] | None = None,
    ) -> Path:
        """Save the networks, optimizer and settings (never the teachers) to ``path`` (.pt).
        A schedule given as a function (SB3's ``Schedule``) is saved as its value at this step:
        a model file holds plain data, and :meth:`load` runs no code from it; ``load`` warns,
        and takes the function again as ``custom_objects``.

        ``training_state``: also everything that training needs to continue exactly as if it
        had never stopped (random-number generators, the teachers' generators, the advice
        buffer, the solo statistics and the environments with their episodes in progress);
        ``load(..., resume=True)`` restores it. Such a file is larger (the advice buffer).
        ``run_state``: plain data saved alongside under ``"run"`` (``tlac.run``: what the run
        folder's writers need to continue), in the same file so that both change together."""
        path = checkpoint_path(path)
        config = dataclasses.asdict(self.config)
        functions = [name for name in SCHEDULES if callable(config[name])]
        for name in functions:  # SB3's Schedule: its value now (load warns of it)
            config[name] = float(config[name](self._schedule_progress()))
        state = {
            "format": FORMAT,
            "config": config,
            "seed": self.seed,
            "num_timesteps": self.num_timesteps,
            "observation_space": space_to_data(self.observation_space),
            "action_space": space_to_data(self.action_space),
            "teacher_names": self.teacher_names,
            "env_name": self.env_name,
            "policy": self.obs_policy.to_data(),
            **self._parameters(),
        }
        if functions:
            state["functions"] = functions
        vec_normalize = self.get_vec_normalize_env()
        if vec_normalize is not None:  # the user's VecNormalize: its statistics, as tensors
            state["vec_normalize"] = vec_normalize_state(vec_normalize)
        elif self.saved_vec_normalize is not None:  # loaded without one: those it was saved with
            state["vec_normalize"] = self.saved_vec_normalize.saved
        if training_state:
            state["training"] = self._training_state()
        if run_state is not None:
            state["run"] = run_state
        return atomic_torch_save(state, path)

    def _schedule_progress(self) -> float:
        """The progress remaining (1 -> 0) of the schedules at this step: in the ``learn`` call
        in progress or last made (1.0 before any)."""
        if self._schedule is None:
            return 1.0
        origin, horizon = self._schedule
        return max(1.0 - (self.num_timesteps - origin) / horizon, 0.0)

    def _parameters(self) -> dict[str, Any]:
        """The :data:`PARAMETERS` of a model file (live state dicts, not copies)."""
        return {
            "net": self.net.state_dict(),
            "extractor": self.encoder.module.state_dict() if self._extractor_params else None,
            "log_std": None if self.log_std is None else self.log_std.detach().clone(),
            "optimizer": self.optimizer.state_dict(),
            "normalizer": None if self.normalizer is None else self.normalizer.state(),
            "deployed": None if self.deployed is None else self.deployed.state(),
        }

    def _load_parameters(self, params: dict[str, Any], where: str) -> None:
        """Load the :data:`PARAMETERS` that ``params`` holds (a model file's, or
        :meth:`get_parameters`'); ``where``: what errors name (a file, or the call)."""
        if "net" in params:  # checkpoints before the per-layer masks stored all-ones masks
            known = self.net.state_dict()
            self.net.load_state_dict({k: v for k, v in params["net"].items() if k in known})
        if params.get("extractor") is not None:  # the shared CNN
            self.encoder.module.load_state_dict(params["extractor"])
        if params.get("log_std") is not None:
            if self.log_std is None:
                raise ConfigError(f"{where}: a Gaussian's log_std for a model of discrete actions")
            with torch.no_grad():
                self.log_std.copy_(params["log_std"])
        if "optimizer" in params:
            self.optimizer.load_state_dict(params["optimizer"])
        if self.normalizer is not None and "normalizer" in params:
            if params["normalizer"] is None:
                raise ConfigError(
                    f"{where}: no normalisation statistics, which this model's settings need "
                    "(normalize_obs / normalize_reward)"
                )
            self.normalizer.set_state(params["normalizer"])
        if "deployed" in params:  # the kept student (solo episodes); None: the live weights
            saved = params["deployed"]
            self.deployed = (
                None
                if saved is None
                else StudentSnapshot.from_state(
                    saved,
                    copy.deepcopy(self.normalizer),
                    self.encoder.frozen_copy() if self._extractor_params else None,
                )
            )

    def get_parameters(self) -> dict[str, Any]:
        """SB3's ``get_parameters``: a copy of the model's parameters by name, each a state dict
        (plain data and tensors, as a model file holds them): ``"net"`` (the three networks,
        stacked), ``"optimizer"``, and, None where the model has none, ``"extractor"`` (the
        shared CNN), ``"log_std"`` (the Gaussian's, a tensor), ``"normalizer"`` (tlac's
        observation and reward statistics) and ``"deployed"`` (the kept student that
        ``predict`` deploys). :meth:`set_parameters` loads them back."""
        return copy.deepcopy(self._parameters())

    def set_parameters(
        self,
        load_path_or_dict: str | Path | dict[str, Any],
        exact_match: bool = True,
        device: str = "auto",
    ) -> None:
        """SB3's ``set_parameters``: load parameters from :meth:`get_parameters`' dict or from
        a TL-AC model file, into a model of the same spaces and networks. ``exact_match``:
        every name of :meth:`get_parameters` must be given (False: those given only).
        ``device``: ``"auto"`` or ``"cpu"``, where tlac runs."""
        check_device(device)
        where, params = "the dict given", load_path_or_dict
        if isinstance(params, str | Path):
            where = repr(str(params))
            try:
                params = file_parameters(read_model_file(Path(params)))
            except KeyError as exc:
                raise ConfigError(f"{where} is not a loadable TL-AC model file: no {exc}") from None
        if not isinstance(params, dict):
            raise ConfigError(
                f"set_parameters: expected get_parameters()' dict or a model file path, got "
                f"{type(params).__name__}"
            )
        unknown = sorted(set(params) - set(PARAMETERS))
        missing = [k for k in PARAMETERS if k not in params]
        if unknown or (exact_match and missing):
            culprit = f"unknown {unknown}" if unknown else f"missing {missing}"
            raise ConfigError(
                f"set_parameters: {culprit}; expected the names {list(PARAMETERS)} "
                "(exact_match=False loads those given)"
            )
        try:
            self._load_parameters(params, where)
        except (KeyError, TypeError, ValueError, RuntimeError, IndexError, AttributeError) as exc:
            problem = " ".join(str(exc).split())
            raise ConfigError(
                f"set_parameters: {where} does not fit this model ({type(exc).__name__} "
                f"{problem[:200]}): the parameters of a model with other spaces or networks?"
            ) from None

    def _training_state(self) -> dict[str, Any]:
        """What :meth:`save` writes with ``training_state=True`` (plain data and tensors)."""
        buf = self.advice_buffer

        def tensor(a: np.ndarray | None) -> torch.Tensor | None:
            return None if a is None else torch.from_numpy(np.array(a))

        return {
            "rng": self.rng.bit_generator.state,
            "generator": self.generator.get_state(),
            "replay_generator": self._replay_generator.get_state(),
            "selector": attributes_state(self.selector),
            "solo": None if self.solo is None else attributes_state(self.solo),
            "advice": None
            if buf is None
            else {
                "obs": buf.obs[: buf.size].clone(),
                "advice": buf.advice[: buf.size].clone(),
                "next": buf.next,
                "size": buf.size,
                "labelled": None if buf.labelled is None else buf.labelled[: buf.size].clone(),
            },
            "advice_ledger": None if self.advice is None else attributes_state(self.advice),
            "last_obs": tensor(
                self._last_obs
                if self._last_obs is None or self.obs_layout is None
                else self._flat_rows(self._last_obs)  # a dict: its flat rows
            ),
            "episode_starts": tensor(getattr(self, "_episode_starts", None)),
            "episode_returns": tensor(getattr(self, "_episode_returns", None)),
            "sde_noise": tensor(self._sde_noise),
            "teachers": [generator_states(t) for t in self.teachers],
            "env": vec_env_state(self.env),
            "schedule": None if self._schedule is None else list(self._schedule),
            "n_updates": self._n_updates,
            "log_window": None
            if self._log_window is None
            else {
                "metrics": {k: tensor(v) for k, v in self._log_window[0].state().items()},
                "usage": tensor(self._log_window[1]),
            },
        }

    def _load_training_state(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`_training_state` saved (see :mod:`tlac.algorithms.resume`)."""
        self.rng.bit_generator.state = state["rng"]
        self.generator.set_state(state["generator"])
        self._replay_generator.set_state(state["replay_generator"])
        restore_attributes(self.selector, state["selector"])
        if (state["solo"] is None) != (self.solo is None):
            raise ConfigError("the checkpoint's solo-episode statistics do not match the settings")
        if self.solo is not None:
            restore_attributes(self.solo, state["solo"])
        if state["advice"] is not None and self.advice_buffer is not None:
            buf, saved = self.advice_buffer, state["advice"]
            if tuple(saved["advice"].shape[1:]) != tuple(buf.advice.shape[1:]):
                raise ConfigError(
                    f"the checkpoint's advice buffer holds rows of shape "
                    f"{tuple(saved['advice'].shape[1:])}, these settings "
                    f"{tuple(buf.advice.shape[1:])} (a Box run saved before 2026-11-27 stored no "
                    "information column); resume it with the tlac version that saved it"
                )
            buf.obs[: saved["size"]] = saved["obs"]
            buf.advice[: saved["size"]] = saved["advice"]
            buf.next, buf.size = saved["next"], saved["size"]
            if buf.labelled is not None and saved.get("labelled") is not None:
                buf.labelled[: saved["size"]] = saved["labelled"]
        if state.get("advice_ledger") is not None and self.advice is not None:
            restore_attributes(self.advice, state["advice_ledger"])
        for name in ("last_obs", "episode_starts", "episode_returns", "sde_noise"):
            value = state[name]
            setattr(self, f"_{name}", None if value is None else value.numpy().copy())
        if self._last_obs is not None and self.obs_layout is not None:
            self._last_obs = self.obs_layout.unflatten(self._last_obs)
        if len(state["teachers"]) != len(self.teachers):
            raise ConfigError(
                f"the checkpoint was saved with {len(state['teachers'])} teachers, "
                f"got {len(self.teachers)}"
            )
        for teacher, states in zip(self.teachers, state["teachers"], strict=True):
            restore_generator_states(teacher, states)
        if not restore_vec_env(self.env, state["env"]):
            self._last_obs = None  # new episodes: collect() resets the environments
        schedule = state["schedule"]
        self._resumed_schedule = None if schedule is None else (int(schedule[0]), int(schedule[1]))
        self._n_updates = int(state.get("n_updates", 0))
        saved_window = state.get("log_window")
        if saved_window is not None:
            window = MetricWindow(counts=("train/n_updates",))
            window.restore({k: v.numpy() for k, v in saved_window["metrics"].items()})
            self._log_window = (window, saved_window["usage"].numpy().copy())

    @classmethod
    def load(
        cls: type[_Model],
        path: str | Path,
        env: Any = None,
        teachers: Sequence[Any] | None = None,
        resume: bool = False,
        trust_pickle: bool = False,
        device: str = "auto",
        custom_objects: dict[str, Any] | None = None,
    ) -> _Model:
        """Load a saved model. Pass ``env`` (and, to train on with advice, the same number of
        ``teachers`` as at save time) to continue training; ``predict`` needs neither.
        ``device``: as SB3's, ``"auto"`` or ``"cpu"``, where tlac runs. ``custom_objects``: as
        SB3's, settings by name that replace the saved ones (``{"learning_rate": 1e-4}``; a
        schedule function, which a model file keeps only the value of; SB3's ``lr_schedule``
        is ``learning_rate``). A model saved by SB3 (its .zip) is refused in one line: it is
        loaded with its SB3 class, and TL-AC takes it as a teacher.

        A model trained under a ``VecNormalize`` holds its statistics: loaded with
        ``env=VecNormalize(...)`` they are put in it (as SB3's ``VecNormalize.load`` would),
        and ``predict`` takes the observations it gives; loaded without one (no env, or a raw
        one), ``predict`` takes RAW observations and normalises them with those statistics,
        frozen (``model.saved_vec_normalize``; set it to None to pass observations you
        normalise yourself).

        ``resume``: restore the training state of a file saved with ``training_state=True``
        (needs ``env`` and the same ``teachers``), so that ``learn`` continues exactly where
        the saved model stopped; the next ``learn`` call keeps the schedules (learning rate,
        clip range...) of the call that was interrupted, so a run resumed with its remaining
        steps follows the same schedules as an uninterrupted one. The episodes in progress are
        re-created in ``env``'s environments (:mod:`tlac.algorithms.resume`). Loading, with or
        without ``resume``, runs no code from the file (``torch.load(weights_only=True)``), so
        ``trust_pickle`` (the contract's, for SB3's zips) changes nothing."""
        check_device(device)
        path = Path(path)
        for suffix in (".pt", ".zip"):  # save("x") writes x.pt; SB3's names end in .zip
            if not path.exists() and path.with_name(path.name + suffix).exists():
                path = path.with_name(path.name + suffix)
        state = read_model_file(path)
        try:
            config = loaded_config(state, custom_objects, repr(str(path)), resume)
            model = cls._from_state(state, config, path, env, teachers, resume)
        except TlacError:
            raise
        except (KeyError, TypeError, ValueError, RuntimeError, IndexError) as exc:
            problem = " ".join(str(exc).split())
            raise ConfigError(
                f"{str(path)!r} is not a loadable TL-AC model file: {type(exc).__name__} "
                f"{problem[:200]} (missing keys, wrong tensor shapes or a broken optimizer state)"
            ) from None
        check_finite_weights(model.net.state_dict(), path)
        return model

    @classmethod
    def _from_state(
        cls: type[_Model],
        state: dict[str, Any],
        config: TLACConfig,
        path: Path,
        env: Any,
        teachers: Sequence[Any] | None,
        resume: bool,
    ) -> _Model:
        """:meth:`load` once the file is read: the model its ``state`` describes, with the
        settings ``config``."""
        model = cls.__new__(cls)
        model.obs_policy = ObsPolicy.from_data(state.get("policy"))
        model._setup(config, state["seed"], env, teachers, None, state)
        model._load_parameters(file_parameters(state), str(path))
        vec_normalize, saved = model.get_vec_normalize_env(), state.get("vec_normalize")
        if vec_normalize is not None and saved is not None:
            set_vec_normalize_state(vec_normalize, saved)  # as at save time
        elif saved is not None and "norm_obs" in saved:  # predict normalises raw observations
            model.saved_vec_normalize = FrozenObsNormalization.from_saved(saved)
        elif saved is not None:
            warnings.warn(
                f"{str(path)!r}: the model was trained under a VecNormalize whose settings this "
                "file (from an older tlac) lacks: predict expects observations normalised by "
                "its statistics; load it with env=VecNormalize(...) to have them",
                stacklevel=3,
            )
        if resume:
            if "training" not in state:
                raise ConfigError(
                    f"{str(path)!r} holds no training state; save it with training_state=True"
                )
            if model.env is None:
                raise ConfigError("resume=True needs env (the environments are restored into it)")
            model._load_training_state(state["training"])
        return model
