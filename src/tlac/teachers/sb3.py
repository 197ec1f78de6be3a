"""Stable-baselines3 and rl-baselines3-zoo agents as teachers, with their ``VecNormalize``
statistics.

An agent trained under SB3's ``VecNormalize`` acts on NORMALISED observations: given the raw
ones it acts badly (a CartPole PPO agent that scores 500 with its statistics scores about 100
without). TL-AC hands every teacher the environment's raw observations (under a user's own
``VecNormalize`` too, see :func:`tlac.algorithms.common.original_obs`), so such a teacher must
carry its statistics: :func:`from_sb3` and :func:`from_rl_zoo` build one that normalises each
observation with them (frozen: a teacher is never trained) before asking the agent.

Loading an SB3 ``.zip`` or a ``vecnormalize.pkl`` unpickles Python objects, which can run code:
load only files you trust. These functions open such a file only when told so
(``trust_pickle=True``; on the command line ``--trust-pickle``), and nothing in tlac opens one
on its own (:func:`check_trust_pickle`).

An SB3 model given as a teacher that trains under a ``VecNormalize`` of its own
(``model.get_vec_normalize_env()``) carries its statistics already: its teacher normalises
with them (:func:`own_obs_normalization`).
"""

from __future__ import annotations

import pickle
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from tlac.errors import ConfigError

SB3_CLASSES = ("a2c", "ddpg", "dqn", "ppo", "sac", "td3")
"""The stable-baselines3 algorithms a saved agent can be loaded as (rl-zoo's folder names)."""


class FrozenObsNormalization:
    """``VecNormalize.normalize_obs`` with a frozen copy of its statistics, taken when made
    (the ``VecNormalize`` itself is left as it is)."""

    def __init__(self, vec_normalize: Any, name: str):
        rms = vec_normalize.obs_rms
        if isinstance(rms, dict):
            raise ConfigError(
                f"teacher {name!r}: its VecNormalize normalises Dict observations; tlac's "
                "teachers take Box observations"
            )
        self.normalize = bool(vec_normalize.norm_obs)
        self.mean = np.array(rms.mean, dtype=np.float64)
        self.std = np.sqrt(np.array(rms.var, dtype=np.float64) + vec_normalize.epsilon)
        self.clip = float(vec_normalize.clip_obs)
        self.saved: dict[str, Any] | None = None

    @classmethod
    def from_saved(cls, state: dict[str, Any]) -> FrozenObsNormalization:
        """The normalisation of the ``VecNormalize`` whose statistics and settings a TL-AC model
        file holds (tlac.algorithms.normalization.vec_normalize_state), kept as ``saved``."""
        norm = cls.__new__(cls)
        rms = state["obs_rms"]
        norm.normalize = bool(state["norm_obs"])
        norm.mean = np.asarray(rms["mean"], dtype=np.float64)
        norm.std = np.sqrt(np.asarray(rms["var"], dtype=np.float64) + float(state["epsilon"]))
        norm.clip = float(state["clip_obs"])
        norm.saved = state
        return norm

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        if not self.normalize:
            return obs
        return np.clip((obs - self.mean) / self.std, -self.clip, self.clip).astype(np.float32)


class SB3Teacher:
    """A stable-baselines3 model used as a teacher (deterministic actions by default).
    ``normalize_obs``: what the model's ``VecNormalize`` did to its observations, applied to
    the raw ones before asking it (:func:`from_sb3`), or None."""

    def __init__(
        self,
        model: Any,
        name: str,
        deterministic: bool = True,
        normalize_obs: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        self.model, self.name, self.deterministic = model, name, deterministic
        self.normalize_obs = normalize_obs

    def predict(self, obs: np.ndarray) -> np.ndarray:
        if self.normalize_obs is not None:
            obs = self.normalize_obs(obs)
        actions, _ = self.model.predict(obs, deterministic=self.deterministic)
        return np.asarray(actions)


def own_obs_normalization(model: Any, name: str) -> FrozenObsNormalization | None:
    """The observation normalisation of the ``VecNormalize`` that the SB3 model ``model``
    trains under (``model.get_vec_normalize_env()``: a model made or loaded with one), frozen
    as it is now; None without one (a policy, or a model loaded without its environment)."""
    get = getattr(model, "get_vec_normalize_env", None)
    vec_normalize = get() if callable(get) else None
    return None if vec_normalize is None else FrozenObsNormalization(vec_normalize, name)


def check_trust_pickle(
    path: str | Path, trust_pickle: bool, how: str = "trust_pickle=True"
) -> None:
    """Refuse to open the stable-baselines3 file ``path`` unless ``trust_pickle``: its pickled
    objects can run any code when loaded. ``how``: the opt-in the error names
    (``--trust-pickle`` on the command line)."""
    if not trust_pickle:
        raise ConfigError(
            f"{str(path)!r} is a stable-baselines3 file: loading it unpickles Python objects, "
            f"which can run any code, so tlac opens one only when told to; pass {how} if you "
            "trust the file (one you made yourself)"
        )


def sb3_class(algo: str) -> Any:
    """The stable-baselines3 class of ``algo`` (one of :data:`SB3_CLASSES`)."""
    import stable_baselines3

    if algo not in SB3_CLASSES:
        raise ConfigError(f"algo: expected one of {', '.join(SB3_CLASSES)}, got {algo!r}")
    return getattr(stable_baselines3, algo.upper())


def load_vec_normalize(path: str | Path, trust_pickle: bool = False) -> Any:
    """SB3's saved ``VecNormalize`` (``vec_normalize.save(path)``, rl-zoo's
    ``vecnormalize.pkl``) without an environment: only its statistics are used. Unpickles the
    file, so ``trust_pickle=True`` is required: trusted files only."""
    from stable_baselines3.common.vec_env import VecNormalize

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"VecNormalize statistics {str(path)!r}: no such file")
    check_trust_pickle(path, trust_pickle)
    with path.open("rb") as f:
        try:
            vec_normalize = pickle.load(f)  # noqa: S301 - the caller's explicit, documented opt-in
        except Exception as exc:  # noqa: BLE001 - any unpickling failure is a bad file
            raise ConfigError(
                f"VecNormalize statistics {str(path)!r}: not a saved VecNormalize ({exc})"
            ) from None
    if not isinstance(vec_normalize, VecNormalize):
        raise ConfigError(
            f"VecNormalize statistics {str(path)!r}: holds a {type(vec_normalize).__name__}, "
            "not a VecNormalize"
        )
    return vec_normalize


def from_sb3(
    model: Any,
    vec_normalize: Any = None,
    algo: str = "ppo",
    name: str | None = None,
    deterministic: bool = True,
    trust_pickle: bool = False,
) -> Any:
    """A teacher from an SB3 agent: ``model`` is a loaded SB3 model or the path of its
    ``.zip`` (loaded as ``algo``); ``vec_normalize`` is its ``VecNormalize`` (an object, or the
    path of its saved statistics), or None: the model's own where it has one
    (``model.get_vec_normalize_env()``), else raw observations. Opening
    a file unpickles it: pass ``trust_pickle=True`` for files you trust (else ConfigError).

    >>> import gymnasium as gym
    >>> from stable_baselines3 import PPO
    >>> teacher = from_sb3(PPO("MlpPolicy", gym.make("CartPole-v1")), name="ppo")
    >>> teacher.predict(np.zeros((3, 4), np.float32)).shape
    (3,)
    """
    if isinstance(model, str | Path):
        path = Path(model)
        if not path.is_file():
            raise ConfigError(f"SB3 model {str(path)!r}: no such file")
        check_trust_pickle(path, trust_pickle)
        model = sb3_class(algo).load(str(path), device="cpu")
    label = name or type(model).__name__.lower()
    if vec_normalize is None:
        return SB3Teacher(model, label, deterministic, own_obs_normalization(model, label))
    if isinstance(vec_normalize, str | Path):
        vec_normalize = load_vec_normalize(vec_normalize, trust_pickle)
    return SB3Teacher(model, label, deterministic, FrozenObsNormalization(vec_normalize, label))


def from_rl_zoo(
    folder: str | Path, algo: str | None = None, name: str | None = None, trust_pickle: bool = False
) -> Any:
    """A teacher from an rl-baselines3-zoo run folder (``logs/<algo>/<EnvId>_<n>/``): its
    ``<EnvId>.zip`` (else ``best_model.zip``) and, when the run normalised, its
    ``<EnvId>/vecnormalize.pkl``. ``algo``: the SB3 class (default: the parent folder's name,
    as rl-zoo lays runs out). Both files are pickles: ``trust_pickle=True`` is required."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(f"rl-zoo run folder {str(folder)!r}: no such folder")
    env_id = re.sub(r"_\d+$", "", folder.name)
    algo = algo or folder.parent.name.lower()
    if algo not in SB3_CLASSES:
        raise ConfigError(
            f"rl-zoo run folder {str(folder)!r}: cannot tell the algorithm from its parent "
            f"folder {folder.parent.name!r}; pass algo= one of {', '.join(SB3_CLASSES)}"
        )
    zips = [folder / f"{env_id}.zip", folder / "best_model.zip"]
    model = next((p for p in zips if p.is_file()), None)
    if model is None:
        raise ConfigError(
            f"rl-zoo run folder {str(folder)!r}: holds neither {env_id}.zip nor best_model.zip"
        )
    stats = folder / env_id / "vecnormalize.pkl"
    return from_sb3(
        model,
        stats if stats.is_file() else None,
        algo=algo,
        name=name or f"{algo}-{env_id}",
        trust_pickle=trust_pickle,
    )
