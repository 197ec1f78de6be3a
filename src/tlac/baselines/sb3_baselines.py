"""The no-advice baselines: stable-baselines3's A2C (the paper's baseline) and PPO.

Thin adapters that give SB3's ``A2C`` / ``PPO`` the project's algorithm contract
(``docs/architecture.md``): ``Algo(env, teachers, seed, recorder, **hyperparameters)``,
``learn(total_timesteps, callback, progress_bar)``, ``num_timesteps``, ``predict``, ``save``
and ``load``. The learning itself is SB3's, unchanged (paper, section 4.1: "The A2C baseline
uses the default setting of the Stable Baseline3"; its settings are Tables 4, 7 and 9).

Preset keys are translated to SB3 arguments by :func:`sb3_kwargs` (a pure function):

* ``optimizer: rmsprop_tf`` + ``optimizer_eps`` -> ``policy_kwargs.optimizer_class =
  RMSpropTFLike`` with ``optimizer_kwargs = {alpha: 0.99, eps, weight_decay: 0}`` (the
  rl-baselines3-zoo convention for the tables' "RMSpropTFLike, RMSProp epsilon 1e-5");
  ``adam`` / ``rmsprop`` select torch's optimizers with that epsilon;
* ``net_arch: [64, 64]`` -> ``dict(pi=[64, 64], vf=[64, 64])`` (the tables' "pi=[64, 64],
  vf=[64, 64]": separate actor and critic networks);
* ``ortho_init``, ``log_std_init`` -> ``policy_kwargs``; ``use_sde``, ``sde_sample_freq`` as is;
* schedules ``{linear: [start, end]}`` -> SB3 callables of the remaining progress
  (``learning_rate``, ``clip_range``); PPO's ``target_kl`` takes only a number in SB3, so a
  scheduled ``target_kl`` is re-set from its schedule before every update (see
  :class:`_ContractCallback`).

>>> kw = sb3_kwargs("a2c", {"net_arch": [64, 64], "optimizer": "rmsprop_tf", "optimizer_eps": 1e-5})
>>> kw["policy_kwargs"]["net_arch"], kw["policy_kwargs"]["optimizer_kwargs"]["eps"]
({'pi': [64, 64], 'vf': [64, 64]}, 1e-05)
"""

from __future__ import annotations

import inspect
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch
from stable_baselines3 import A2C, PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import KVWriter, Logger
from stable_baselines3.common.sb2_compat.rmsprop_tf_like import RMSpropTFLike
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from tlac.algorithms.callbacks import split_callbacks
from tlac.algorithms.common import check_total_timesteps, stop_if_not_finite
from tlac.errors import ConfigError
from tlac.memory import FLOAT_BYTES, check_fits, mlp_params, network_bytes
from tlac.presets import Schedule, make_schedule
from tlac.recording import Recorder
from tlac.teachers.sb3 import check_trust_pickle
from tlac.validation import Checks, check_plain_numbers

ContractCallback = Callable[[Any], "bool | None"]

_SB3_CLASSES: dict[str, type[BaseAlgorithm]] = {"a2c": A2C, "ppo": PPO}
_POLICY_KEYS = ("ortho_init", "log_std_init")
_SCHEDULED = ("learning_rate", "clip_range")


def _net_arch(value: Any, name: str = "net_arch") -> dict[str, list[int]]:
    """``[64, 64]`` -> ``{pi: [64, 64], vf: [64, 64]}``; a ``{pi, vf}`` mapping is kept."""

    def sizes(layers: Any) -> bool:
        return isinstance(layers, list | tuple) and all(
            isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in layers
        )

    if isinstance(value, dict) and set(value) == {"pi", "vf"} and all(map(sizes, value.values())):
        return {"pi": list(value["pi"]), "vf": list(value["vf"])}
    if sizes(value):
        return {"pi": list(value), "vf": list(value)}
    raise ConfigError(
        f"{name}: expected a list of positive layer sizes or {{pi: [...], vf: [...]}}, "
        f"got {value!r}"
    )


def _optimizer(name: str, eps: float) -> tuple[type[torch.optim.Optimizer], dict[str, Any]]:
    """The optimizer class and its keyword arguments for a preset's ``optimizer`` name."""
    if name == "rmsprop_tf":
        # Tables 4/7/9: "Optimizer RMSpropTFLike, RMSProp epsilon 1e-5"; alpha 0.99 as SB3's A2C
        return RMSpropTFLike, {"alpha": 0.99, "eps": eps, "weight_decay": 0}
    if name == "rmsprop":
        return torch.optim.RMSprop, {"alpha": 0.99, "eps": eps, "weight_decay": 0}
    if name == "adam":
        return torch.optim.Adam, {"eps": eps}
    raise ConfigError(f"optimizer: expected one of rmsprop_tf, rmsprop, adam, got {name!r}")


def sb3_kwargs(algo: str, hp: dict[str, Any]) -> dict[str, Any]:
    """Translate a preset's settings for ``algo`` (``a2c`` or ``ppo``) into SB3 constructor
    arguments. Unknown keys raise :class:`ConfigError` naming the key and the accepted ones.
    A scheduled ``target_kl`` is returned under the private key ``_target_kl_schedule``."""
    sb3_cls = _SB3_CLASSES[algo]
    hp = dict(hp)
    check_plain_numbers(hp, algo)
    given = hp.pop("policy_kwargs", None) or {}
    if not isinstance(given, dict):
        raise ConfigError(f"{algo} setting policy_kwargs must be a mapping, got {given!r}")
    policy_kwargs: dict[str, Any] = dict(given)
    out: dict[str, Any] = {}
    for key in ("n_steps", "batch_size", "n_epochs"):
        if key in hp:
            Checks(algo).positive_int(key, hp[key])
    if "net_arch" in policy_kwargs:  # SB3's own spelling: it replaces the preset's net_arch
        hp.pop("net_arch", None)
        policy_kwargs["net_arch"] = _net_arch(policy_kwargs["net_arch"], "policy_kwargs.net_arch")
    elif "net_arch" in hp:
        policy_kwargs["net_arch"] = _net_arch(hp.pop("net_arch"))
    eps = float(hp.pop("optimizer_eps", 1e-5))
    name = hp.pop("optimizer", None)
    if name is not None:
        cls, kwargs = _optimizer(str(name), eps)
        policy_kwargs["optimizer_class"] = cls
        policy_kwargs["optimizer_kwargs"] = kwargs
    elif algo == "a2c":
        out["rms_prop_eps"] = eps
    for key in _POLICY_KEYS:
        if key in hp:
            policy_kwargs[key] = hp.pop(key)
    for key in _SCHEDULED:
        if key in hp and isinstance(hp[key], dict):
            out[key] = make_schedule(hp.pop(key), key)
    if algo == "ppo" and isinstance(hp.get("target_kl"), dict):
        out["_target_kl_schedule"] = make_schedule(hp.pop("target_kl"), "target_kl")
    accepted = set(inspect.signature(sb3_cls.__init__).parameters) - {
        "self",
        "policy",
        "env",
        "seed",
        "device",
        "verbose",
        "_init_setup_model",
        "policy_kwargs",
    }
    parameters = inspect.signature(sb3_cls.__init__).parameters
    for key, value in hp.items():
        is_flag = key in parameters and isinstance(parameters[key].default, bool)
        if is_flag and not isinstance(value, bool):
            raise ConfigError(f"{algo} setting {key} must be true or false, got {value!r}")
        if key not in accepted:
            known = sorted(accepted | {"net_arch", "optimizer", "optimizer_eps", *_POLICY_KEYS})
            raise ConfigError(
                f"unknown {algo} hyperparameter {key!r}; expected one of: {', '.join(known)}"
            )
        if isinstance(value, dict):  # a schedule where SB3 takes only a number
            raise ConfigError(
                f"{algo} hyperparameter {key!r} does not accept a schedule, got {value!r}"
            )
        out[key] = value
    out["policy_kwargs"] = policy_kwargs
    return out


NORMALIZATION_SUFFIX = ".normalization.npz"
"""Beside ``model.zip``: the observation statistics of a model trained with ``normalize``."""


def _normalize_setting(algo: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(f"{algo} setting normalize must be true or false, got {value!r}")
    return value


def normalize_observation(obs: np.ndarray, stats: dict[str, np.ndarray]) -> np.ndarray:
    """VecNormalize's ``normalize_obs`` from saved statistics."""
    scaled = (np.asarray(obs) - stats["mean"]) / np.sqrt(stats["var"] + stats["epsilon"])
    return np.clip(scaled, -stats["clip"], stats["clip"]).astype(np.float32)


class _RecorderWriter(KVWriter):
    """Forwards SB3's logged scalars (``train/``, ``rollout/``, ``time/``) to the run folder's
    ``progress.csv`` through :meth:`Recorder.record_metrics`."""

    def __init__(self, recorder: Recorder):
        self.recorder = recorder

    def write(
        self, key_values: dict[str, Any], key_excluded: dict[str, tuple[str, ...]], step: int = 0
    ) -> None:
        scalars = {
            k: float(v)
            for k, v in key_values.items()
            if isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool)
        }
        if scalars:
            self.recorder.record_metrics(int(step), scalars)

    def close(self) -> None:
        pass


class _ContractCallback(BaseCallback):
    """Calls the contract's plain callbacks ``f(algo) -> bool | None`` at the end of every rollout
    and re-sets a scheduled PPO ``target_kl``. Returning ``False`` stops training: SB3 still
    updates on the rollout just collected and takes one more environment step (its only
    stopping point is ``on_step``) before it returns."""

    def __init__(
        self, owner: _SB3Baseline, functions: list[ContractCallback], total_timesteps: int
    ):
        super().__init__()
        self.owner, self.functions, self.total = owner, functions, max(1, total_timesteps)
        self._stop = False

    def _set_target_kl(self) -> None:
        schedule = self.owner._target_kl_schedule
        if schedule is not None:
            remaining = 1.0 - min(1.0, self.model.num_timesteps / self.total)
            self.model.target_kl = float(schedule(remaining))  # type: ignore[attr-defined]

    def _on_training_start(self) -> None:
        self._set_target_kl()

    def _on_step(self) -> bool:
        return not self._stop

    def _on_rollout_end(self) -> None:
        # the previous update's result: a diverged policy stops the run, never "finished"
        for param in self.model.policy.parameters():
            stop_if_not_finite(param.data, self.owner.name, self.model.num_timesteps, "parameter")
        self._set_target_kl()  # the update that follows uses this rollout's progress
        for f in self.functions:
            if f(self.owner) is False:
                self._stop = True


def _check_memory(algo: str, kwargs: dict[str, Any], env: VecEnv) -> None:
    """Refuse, before SB3 allocates them, a policy or rollout that would not fit in memory."""
    obs = int(np.prod(env.observation_space.shape or (1,)))
    act = int(np.prod(env.action_space.shape or (1,)))
    n_out = int(getattr(env.action_space, "n", act))
    arch = kwargs["policy_kwargs"].get("net_arch", {"pi": [64, 64], "vf": [64, 64]})
    params = mlp_params(obs, arch["pi"], n_out) + mlp_params(obs, arch["vf"], 1)
    default = inspect.signature(_SB3_CLASSES[algo].__init__).parameters["n_steps"].default
    n_steps = int(kwargs.get("n_steps", default))
    check_fits(
        {
            f"the networks (net_arch {arch})": network_bytes(params),
            f"the rollout (n_steps={n_steps} x {env.num_envs} environments)": FLOAT_BYTES
            * n_steps
            * env.num_envs
            * (obs + act + 8),
        },
        "lower that setting",
    )


class _SB3Baseline:
    """Common adapter; subclasses set :attr:`name`."""

    name: ClassVar[str] = ""

    def __init__(
        self,
        env: VecEnv,
        teachers: list[Any] | None = None,
        seed: int = 0,
        recorder: Recorder | None = None,
        **hyperparameters: Any,
    ):
        if teachers:
            raise ConfigError(
                f"{self.name} is a no-advice baseline and takes no teachers, got "
                f"{[getattr(t, 'name', t) for t in teachers]}"
            )
        self.hyperparameters = dict(hyperparameters)
        self.hyperparameters.pop("n_envs", None)
        normalize = _normalize_setting(self.name, self.hyperparameters.pop("normalize", False))
        kwargs = sb3_kwargs(self.name, self.hyperparameters)
        self._obs_stats: dict[str, np.ndarray] | None = None
        if normalize:  # rl-zoo's `normalize: true`: observations and rewards, VecNormalize
            env = VecNormalize(env, gamma=float(kwargs.get("gamma", 0.99)))
        self._target_kl_schedule: Schedule | None = kwargs.pop("_target_kl_schedule", None)
        self.seed, self.recorder = seed, recorder
        _check_memory(self.name, kwargs, env)
        sb3_cls = _SB3_CLASSES[self.name]
        self.model: BaseAlgorithm = sb3_cls(
            "MlpPolicy", env, seed=seed, device="cpu", verbose=0, **kwargs
        )
        self._attach_recorder()

    @classmethod
    def check_hyperparameters(cls, hyperparameters: dict[str, Any]) -> None:
        """Raise ConfigError for a bad setting, before anything is built or written."""
        _normalize_setting(cls.name, hyperparameters.get("normalize", False))
        skip = ("n_envs", "normalize")
        sb3_kwargs(cls.name, {k: v for k, v in hyperparameters.items() if k not in skip})

    def _attach_recorder(self) -> None:
        if self.recorder is not None:
            self.model.set_logger(
                Logger(folder=None, output_formats=[_RecorderWriter(self.recorder)])
            )

    @property
    def num_timesteps(self) -> int:
        """Environment steps taken so far, over all environments."""
        return int(self.model.num_timesteps)

    def learn(
        self,
        total_timesteps: int,
        callback: Any = None,
        progress_bar: bool = False,
    ) -> _SB3Baseline:
        """Train for ``total_timesteps`` environment steps with SB3's own loop. ``callback``:
        a function ``f(algo)`` run after every rollout (``False`` stops), an SB3
        ``BaseCallback`` (given SB3's own model) or a list of them."""
        total_timesteps = check_total_timesteps(total_timesteps)
        functions, sb3_callbacks = split_callbacks(callback)
        first = self.model.num_timesteps == 0
        total = int(total_timesteps) + (0 if first else self.num_timesteps)
        kwargs: dict[str, Any] = {}
        if self.recorder is not None:
            # SB3 dumps its scalars every `log_interval` iterations: match the run's window
            per_iteration = self.model.n_steps * self.model.n_envs  # type: ignore[attr-defined]
            kwargs["log_interval"] = max(1, self.recorder.log_interval // per_iteration)
        self.model.learn(
            int(total_timesteps),
            callback=[_ContractCallback(self, functions, total), *sb3_callbacks],
            progress_bar=progress_bar,
            reset_num_timesteps=first,
            **kwargs,
        )
        return self

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, None]:
        """The policy's actions (no teacher is involved), with SB3's signature and defaults.
        With ``normalize``, the observations are normalised with the training statistics."""
        stats = self._normalization_stats()
        if stats is not None:
            observation = normalize_observation(observation, stats)
        actions, _ = self.model.predict(observation, deterministic=deterministic)
        return np.asarray(actions), None

    def _normalization_stats(self) -> dict[str, np.ndarray] | None:
        venv = self.model.get_vec_normalize_env()
        if venv is not None:
            return {
                "mean": venv.obs_rms.mean,
                "var": venv.obs_rms.var,
                "clip": np.array(venv.clip_obs),
                "epsilon": np.array(venv.epsilon),
            }
        return self._obs_stats

    exact_resume = False
    """SB3 saves no training state (generators, environments): ``tlac.run`` redoes an
    interrupted run of these baselines instead of resuming it."""

    def save(
        self,
        path: str | Path,
        training_state: bool = False,
        run_state: dict[str, Any] | None = None,
    ) -> Path:
        """Write ``path`` + ``.zip`` (SB3's format; the optimizer state included) and return
        that path. ``training_state`` and ``run_state`` (the contract's, for an exact resume)
        are refused: SB3's file holds no training state."""
        if training_state or run_state is not None:
            raise ConfigError(
                f"{self.name} cannot save a training state for an exact resume "
                "(training_state=True or run_state); save(path) writes its weights"
            )
        p = Path(path)
        stem = p.with_suffix("") if p.suffix == ".zip" else p
        self.model.save(str(stem))
        stats = self._normalization_stats()
        if stats is not None:  # beside the model: predict needs them
            with open(stem.with_name(stem.name + NORMALIZATION_SUFFIX), "wb") as f:
                np.savez(f, **stats)
        return stem.with_name(stem.name + ".zip")

    @classmethod
    def load(
        cls,
        path: str | Path,
        env: VecEnv | None = None,
        teachers: list[Any] | None = None,
        resume: bool = False,
        trust_pickle: bool = False,
    ) -> _SB3Baseline:
        """Load a model written by :meth:`save` (``path`` with or without ``.zip``);
        ``teachers`` must be empty (a no-advice baseline), and ``resume`` is refused (SB3's
        file holds no training state). SB3's zip holds pickles, which can run code when
        loaded: ``trust_pickle=True`` is required (``tlac eval --trust-pickle``)."""
        if resume:
            raise ConfigError(
                f"{cls.name} cannot resume exactly (resume=True): its file holds no training state"
            )
        if teachers:
            raise ConfigError(f"{cls.name} is a no-advice baseline and takes no teachers")
        p = Path(path)
        if p.suffix != ".zip":
            p = p.with_name(p.name + ".zip")
        if not p.exists():
            raise ConfigError(f"no {cls.name} model at {str(p)!r}")
        check_trust_pickle(p, trust_pickle)
        obj = cls.__new__(cls)
        obj.hyperparameters, obj.seed, obj.recorder = {}, 0, None
        obj._target_kl_schedule = None
        try:
            obj.model = _SB3_CLASSES[cls.name].load(str(p), env=env, device="cpu")
        except (ValueError, KeyError, RuntimeError, EOFError, OSError, zipfile.BadZipFile) as exc:
            problem = " ".join(str(exc).split())[:200]
            raise ConfigError(
                f"{str(p)!r} is not a loadable {cls.name} model (SB3 zip): {problem}"
            ) from None
        stats = p.with_name(p.name.removesuffix(".zip") + NORMALIZATION_SUFFIX)
        obj._obs_stats = dict(np.load(stats)) if stats.exists() else None
        return obj


class A2CBaseline(_SB3Baseline):
    """SB3's A2C with the paper's presets (Tables 4, 7, 9); the paper's no-advice baseline."""

    name = "a2c"


class PPOBaseline(_SB3Baseline):
    """SB3's PPO (TL-AC's clipped update without the high level); a second no-advice baseline."""

    name = "ppo"
