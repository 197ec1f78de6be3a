"""Saving and loading TL-AC models: the model file (plain data and tensors, read without
running code from it), the parameters by name (SB3's ``get_parameters`` / ``set_parameters``),
and the training state that an exact resume restores. Plain functions of the model, which
``TLAC.save`` / ``TLAC.load`` call; the model builds itself (:mod:`tlac.two_level.model`)."""

from __future__ import annotations

import copy
import dataclasses
import warnings
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import torch

from tlac.algorithms.common import (
    atomic_torch_save,
    checkpoint_path,
    safe_torch_load,
    space_to_data,
)
from tlac.algorithms.normalization import set_vec_normalize_state, vec_normalize_state
from tlac.algorithms.resume import (
    attributes_state,
    generator_states,
    restore_attributes,
    restore_generator_states,
    restore_vec_env,
    vec_env_state,
)
from tlac.errors import ConfigError, TlacError
from tlac.recording import MetricWindow
from tlac.teachers.sb3 import FrozenObsNormalization
from tlac.two_level.config import SCHEDULES, TLACConfig
from tlac.two_level.graduation import StudentSnapshot
from tlac.validation import check_setting_types

PARAMETERS = ("net", "extractor", "log_std", "optimizer", "normalizer", "deployed")
"""What ``TLAC.get_parameters`` gives, in a model file's order."""

FORMAT = "tlac.TLAC/2"
"""Checkpoint format: plain data and tensors only (loads with weights_only=True). Format 1
pickled the Gymnasium spaces and needed an unsafe load."""


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
    saved = dict(state["config"])
    availability = custom.pop("availability", None)  # an advice setting: by teacher name
    if availability is not None:
        if not isinstance(availability, dict):
            raise ConfigError(
                "custom_objects: availability must be a dict of teachers' availabilities by "
                f"name, got {type(availability).__name__}"
            )
        advice = dict(saved.get("advice") or {})
        advice["availability"] = {**advice.get("availability", {}), **availability}
        saved["advice"] = advice
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
    kept = [k for k in state.get("availability_functions", []) if k not in (availability or {})]
    if kept:
        chances = saved["advice"]["availability"]
        values = ", ".join(f"{k!r} {chances[k]['steps'][0][1]:.3g}" for k in kept)
        message = (
            f"{where}: a teacher's availability given as a function was saved as its value "
            f"then ({values}), a model file holding plain data; to follow it again pass it to "
            f"TLAC.load as custom_objects={{'availability': {{{kept[0]!r}: f}}}}"
        )
        if resume:
            raise ConfigError(message)
        warnings.warn(message, stacklevel=3)
    check_setting_types(TLACConfig, custom, "TL-AC")
    return TLACConfig(**{**saved, **custom})


def file_parameters(state: dict[str, Any]) -> dict[str, Any]:
    """A model file's :data:`PARAMETERS`: ``net``, ``log_std`` and ``optimizer`` it must hold
    (KeyError), the others are None where an older file lacks them."""
    required = ("net", "log_std", "optimizer")
    return {k: state[k] if k in required else state.get(k) for k in PARAMETERS}


def open_model_file(path: str | Path) -> tuple[Path, dict[str, Any]]:
    """The TL-AC model file at ``path`` (``save("x")`` writes x.pt; SB3's names end in .zip,
    either may be left out) and its contents (:func:`read_model_file`)."""
    path = Path(path)
    for suffix in (".pt", ".zip"):
        if not path.exists() and path.with_name(path.name + suffix).exists():
            path = path.with_name(path.name + suffix)
    return path, read_model_file(path)


@contextmanager
def load_errors(path: Path) -> Iterator[None]:
    """A model file that does not load (missing keys, wrong tensor shapes, a broken optimiser
    state) is one ConfigError naming it."""
    try:
        yield
    except TlacError:
        raise
    except (KeyError, TypeError, ValueError, RuntimeError, IndexError) as exc:
        problem = " ".join(str(exc).split())
        raise ConfigError(
            f"{str(path)!r} is not a loadable TL-AC model file: {type(exc).__name__} "
            f"{problem[:200]} (missing keys, wrong tensor shapes or a broken optimizer state)"
        ) from None


def restore(model: Any, state: dict[str, Any], path: Path, resume: bool) -> None:
    """Put a model file's contents ``state`` into ``model``, built from its settings and
    spaces: the parameters, the ``VecNormalize`` statistics and (``resume``) the training
    state."""
    load_parameters(model, file_parameters(state), str(path))
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
        set_training_state(model, state["training"])


def schedule_progress(schedule: tuple[int, int] | None, num_timesteps: int) -> float:
    """The progress remaining (1 -> 0) of the schedules at step ``num_timesteps``, of the
    ``learn`` call in progress or last made (``schedule``: its origin and horizon; None before
    any: 1.0)."""
    if schedule is None:
        return 1.0
    origin, horizon = schedule
    return max(1.0 - (num_timesteps - origin) / horizon, 0.0)


def save(
    model: Any,
    path: str | Path,
    training_state: bool = False,
    run_state: dict[str, Any] | None = None,
) -> Path:
    """``TLAC.save``: the model file of ``model`` (see there), written atomically."""
    path = checkpoint_path(path)
    config = dataclasses.asdict(model.config)
    functions = [name for name in SCHEDULES if callable(config[name])]
    for name in functions:  # SB3's Schedule: its value now (load warns of it)
        config[name] = float(config[name](schedule_progress(model._schedule, model.num_timesteps)))
    chances = config["advice"]["availability"]
    availability_functions = [key for key, value in chances.items() if callable(value)]
    for key in availability_functions:  # a function of the step: its value now, as a schedule
        # (a constant schedule: the run stays limited, as it was; load warns of it)
        chance = chances[key](model.num_timesteps)
        if isinstance(chance, bool) or not isinstance(chance, int | float | np.number):
            raise ConfigError(
                f"TL-AC setting availability[{key!r}] must give a number in [0, 1], got "
                f"{chance!r} at step {model.num_timesteps}"
            )
        chances[key] = {"steps": [[0, float(chance)]]}
    state = {
        "format": FORMAT,
        "config": config,
        "seed": model.seed,
        "num_timesteps": model.num_timesteps,
        "observation_space": space_to_data(model.observation_space),
        "action_space": space_to_data(model.action_space),
        "teacher_names": model.teacher_names,
        "env_name": model.env_name,
        "policy": model.obs_policy.to_data(),
        **parameters(model),
    }
    if functions:
        state["functions"] = functions
    if availability_functions:
        state["availability_functions"] = availability_functions
    vec_normalize = model.get_vec_normalize_env()
    if vec_normalize is not None:  # the user's VecNormalize: its statistics, as tensors
        state["vec_normalize"] = vec_normalize_state(vec_normalize)
    elif model.saved_vec_normalize is not None:  # loaded without one: those it was saved with
        state["vec_normalize"] = model.saved_vec_normalize.saved
    if training_state:
        state["training"] = get_training_state(model)
    if run_state is not None:
        state["run"] = run_state
    return atomic_torch_save(state, path)


def parameters(model: Any) -> dict[str, Any]:
    """The :data:`PARAMETERS` of a model file (live state dicts, not copies)."""
    nets = model.nets
    return {
        "net": nets.net.state_dict(),
        "extractor": nets.encoder.module.state_dict() if nets.extractor_params else None,
        "log_std": None if nets.log_std is None else nets.log_std.detach().clone(),
        "optimizer": model.optimizer.state_dict(),
        "normalizer": None if nets.normalizer is None else nets.normalizer.state(),
        "deployed": None if model.deployed is None else model.deployed.state(),
    }


def load_parameters(model: Any, params: dict[str, Any], where: str) -> None:
    """Load the :data:`PARAMETERS` that ``params`` holds (a model file's, or
    ``get_parameters``'); ``where``: what errors name (a file, or the call)."""
    # (checked before anything is loaded, so a refused call leaves the model as it was)
    if model.nets.normalizer is None and params.get("normalizer") is not None:
        raise ConfigError(
            f"{where}: normalisation statistics, which this model's settings do not use (since "
            "2026-11-29 normalize_obs 'auto' reads a Box of unit-scale bounds raw); load it with "
            "custom_objects={'normalize_obs': True}, or build the model with normalize_obs=True"
        )
    if "net" in params:  # checkpoints before the per-layer masks stored all-ones masks
        known = model.nets.net.state_dict()
        model.nets.net.load_state_dict({k: v for k, v in params["net"].items() if k in known})
    if params.get("extractor") is not None:  # the shared CNN
        model.nets.encoder.module.load_state_dict(params["extractor"])
    if params.get("log_std") is not None:
        if model.nets.log_std is None:
            raise ConfigError(f"{where}: a Gaussian's log_std for a model of discrete actions")
        with torch.no_grad():
            model.nets.log_std.copy_(params["log_std"])
    if "optimizer" in params:
        model.optimizer.load_state_dict(params["optimizer"])
    if model.nets.normalizer is not None and "normalizer" in params:
        if params["normalizer"] is None:
            raise ConfigError(
                f"{where}: no normalisation statistics, which this model's settings need "
                "(normalize_obs / normalize_reward)"
            )
        model.nets.normalizer.set_state(params["normalizer"])
    if "deployed" in params:  # the kept student (solo episodes); None: the live weights
        model.deployed = snapshot_of(model, params["deployed"])
    model.collector = None  # new weights: a renewal before the next update takes them


def snapshot_of(model: Any, saved: dict[str, Any] | None) -> StudentSnapshot | None:
    """A saved :class:`StudentSnapshot` of ``model``'s student, rebuilt (None: none saved)."""
    if saved is None:
        return None
    return StudentSnapshot.from_state(
        saved,
        copy.deepcopy(model.nets.normalizer),
        model.nets.encoder.frozen_copy() if model.nets.extractor_params else None,
    )


def set_parameters(
    model: Any, load_path_or_dict: str | Path | dict[str, Any], exact_match: bool = True
) -> None:
    """``TLAC.set_parameters`` (see there): ``get_parameters``' dict, or a model file's."""
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
        load_parameters(model, params, where)
    except (KeyError, TypeError, ValueError, RuntimeError, IndexError, AttributeError) as exc:
        problem = " ".join(str(exc).split())
        raise ConfigError(
            f"set_parameters: {where} does not fit this model ({type(exc).__name__} "
            f"{problem[:200]}): the parameters of a model with other spaces or networks?"
        ) from None


def get_training_state(model: Any) -> dict[str, Any]:
    """What ``save`` writes with ``training_state=True`` (plain data and tensors)."""
    buf = model.advice_buffer

    def tensor(a: np.ndarray | None) -> torch.Tensor | None:
        return None if a is None else torch.from_numpy(np.array(a))

    return {
        "rng": model.rng.bit_generator.state,
        "generator": model.generator.get_state(),
        "replay_generator": model._replay_generator.get_state(),
        "selector": attributes_state(model.selector),
        "solo": None if model.solo is None else attributes_state(model.solo),
        "advice": None
        if buf is None
        else {
            "obs": buf.obs[: buf.size].clone(),
            "advice": buf.advice[: buf.size].clone(),
            "next": buf.next,
            "size": buf.size,
            "labelled": None if buf.labelled is None else buf.labelled[: buf.size].clone(),
        },
        "advice_ledger": None if model.advice is None else attributes_state(model.advice),
        "last_obs": tensor(
            model._last_obs
            if model._last_obs is None or model.nets.obs_layout is None
            else model.nets.flat_rows(model._last_obs)  # a dict: its flat rows
        ),
        "episode_starts": tensor(getattr(model, "_episode_starts", None)),
        "episode_returns": tensor(getattr(model, "_episode_returns", None)),
        "sde_noise": tensor(model.nets.sde_noise),
        "teachers": [generator_states(t) for t in model.teachers],
        "env": vec_env_state(model.env),
        "schedule": None if model._schedule is None else list(model._schedule),
        "n_updates": model._n_updates,
        "collector": None if model.collector is None else model.collector.state(),
        "log_window": None
        if model._log_window is None
        else {
            "metrics": {k: tensor(v) for k, v in model._log_window[0].state().items()},
            "usage": tensor(model._log_window[1]),
        },
    }


def set_training_state(model: Any, state: dict[str, Any]) -> None:
    """Restore what :func:`get_training_state` saved (see :mod:`tlac.algorithms.resume`)."""
    model.rng.bit_generator.state = state["rng"]
    model.generator.set_state(state["generator"])
    model._replay_generator.set_state(state["replay_generator"])
    restore_attributes(model.selector, state["selector"])
    if (state["solo"] is None) != (model.solo is None):
        raise ConfigError("the checkpoint's solo-episode statistics do not match the settings")
    if model.solo is not None:
        restore_attributes(model.solo, state["solo"])
        if "untrained_se" not in state["solo"]:  # saved before the harm gate: it stays off
            model.solo.untrained_se = float("inf")
    if state["advice"] is not None and model.advice_buffer is not None:
        buf, saved = model.advice_buffer, state["advice"]
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
    if state.get("advice_ledger") is not None and model.advice is not None:
        restore_attributes(model.advice, state["advice_ledger"])

    def array(value: torch.Tensor | None) -> np.ndarray | None:
        return None if value is None else value.numpy().copy()

    model._last_obs, model.nets.sde_noise = array(state["last_obs"]), array(state["sde_noise"])
    model._episode_starts = array(state["episode_starts"])
    model._episode_returns = array(state["episode_returns"])
    if model._last_obs is not None and model.nets.obs_layout is not None:
        model._last_obs = model.nets.obs_layout.unflatten(model._last_obs)
    if len(state["teachers"]) != len(model.teachers):
        raise ConfigError(
            f"the checkpoint was saved with {len(state['teachers'])} teachers, "
            f"got {len(model.teachers)}"
        )
    for teacher, states in zip(model.teachers, state["teachers"], strict=True):
        restore_generator_states(teacher, states)
    if not restore_vec_env(model.env, state["env"]):
        model._last_obs = None  # new episodes: collect() resets the environments
    schedule = state["schedule"]
    model._resumed_schedule = None if schedule is None else (int(schedule[0]), int(schedule[1]))
    model._n_updates = int(state.get("n_updates", 0))
    # a checkpoint from before 2026-11-30 has none: the first rollout's renewals take the live
    # weights, as the rule before did
    model.collector = snapshot_of(model, state.get("collector"))
    saved_window = state.get("log_window")
    if saved_window is not None:
        window = MetricWindow(counts=("train/n_updates",))
        window.restore({k: v.numpy() for k, v in saved_window["metrics"].items()})
        model._log_window = (window, saved_window["usage"].numpy().copy())
