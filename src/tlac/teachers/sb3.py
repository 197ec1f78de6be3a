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
    the raw ones before asking it (:func:`from_sb3`), or None. A greedy PPO / A2C / DQN
    ``MlpPolicy`` answers through :class:`GreedyPolicy` (the same actions, without the
    Python overhead of SB3's ``predict``)."""

    def __init__(
        self,
        model: Any,
        name: str,
        deterministic: bool = True,
        normalize_obs: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        self.model, self.name, self.deterministic = model, name, deterministic
        self.normalize_obs = normalize_obs
        self.greedy = GreedyPolicy.of(model) if deterministic else None

    def predict(self, obs: np.ndarray) -> np.ndarray:
        if self.normalize_obs is not None:
            obs = self.normalize_obs(obs)
        if self.greedy is not None:
            actions = self.greedy(obs)
            if actions is not None:
                return actions
        actions, _ = self.model.predict(obs, deterministic=self.deterministic)
        return np.asarray(actions)


class GreedyPolicy:
    """``model.predict(obs, deterministic=True)[0]`` of an SB3 PPO / A2C ``MlpPolicy``
    (Discrete actions, or a Box without squashing or gSDE) or DQN ``MlpPolicy``, computed
    from its networks directly: the same float32 operations in the same order (features,
    actor, then PPO's Categorical mode, the argmax of the softmax of its normalised logits;
    a Gaussian's mean clipped to the box; DQN's argmax of Q), so the same actions, bit for
    bit, without what SB3's ``predict`` adds per call (setting the training mode of every
    module, checking the observation's shape, building distribution objects that validate
    their parameters): ~0.3 ms of Python for one row, the cost of a teacher asked once a
    step. ``of`` returns None for anything else (another policy class or feature extractor,
    image or Dict observations, a module whose output depends on the training mode), and a
    call returns None where SB3's own ``predict`` must answer (an observation that is not a
    batch of the space's shape; parameters SB3's distributions would refuse, NaN): the
    caller then asks the model itself."""

    SAFE_MODULES: tuple[str, ...] = (
        "Linear", "Sequential", "Flatten", "Identity", "Tanh", "ReLU", "LeakyReLU", "ELU",
        "SELU", "GELU", "SiLU", "Sigmoid", "Softplus", "Mish", "Hardtanh", "ReLU6", "CELU",
        "FlattenExtractor", "MlpExtractor", "QNetwork", "ActorCriticPolicy", "DQNPolicy",
    )  # fmt: skip
    """Module classes (torch.nn's, SB3's, by name within their own package) whose output does
    not depend on the training mode: no dropout, no batch norm."""

    def __init__(self, policy: Any, kind: str):
        self.policy, self.kind = policy, kind
        space = policy.observation_space
        self.obs_shape = tuple(space.shape)
        self.action_shape = tuple(policy.action_space.shape)
        self.box = policy.action_space if kind == "gaussian" else None

    @classmethod
    def of(cls, model: Any) -> GreedyPolicy | None:
        """The greedy path of ``model`` (an SB3 model or its policy), or None where it has
        none (its own ``predict`` answers)."""
        import gymnasium as gym
        from stable_baselines3.common import distributions, policies, torch_layers
        from stable_baselines3.common.preprocessing import is_image_space
        from stable_baselines3.dqn.policies import DQNPolicy, QNetwork

        policy = getattr(model, "policy", model)
        obs_space = getattr(policy, "observation_space", None)
        if not isinstance(obs_space, gym.spaces.Box) or is_image_space(obs_space):
            return None
        for module in policy.modules():
            cls_ = type(module)
            home = cls_.__module__.split(".")[0]
            if home not in ("torch", "stable_baselines3") or cls_.__name__ not in cls.SAFE_MODULES:
                return None
        kind = None
        if type(policy) is policies.ActorCriticPolicy:
            if type(policy.pi_features_extractor) is not torch_layers.FlattenExtractor:
                return None
            dist, actions = type(policy.action_dist), policy.action_space
            if dist is distributions.CategoricalDistribution:
                kind = "categorical" if isinstance(actions, gym.spaces.Discrete) else None
            elif dist is distributions.DiagGaussianDistribution and not policy.squash_output:
                kind = "gaussian" if isinstance(actions, gym.spaces.Box) else None
        elif (
            type(policy) is DQNPolicy
            and type(policy.q_net) is QNetwork
            and type(policy.q_net.features_extractor) is torch_layers.FlattenExtractor
        ):
            kind = "q"
        return None if kind is None else cls(policy, kind)

    def __call__(self, obs: Any) -> np.ndarray | None:
        """The greedy actions of a batch ``(n, *obs_shape)``, or None: ask SB3's predict."""
        import torch

        if not isinstance(obs, np.ndarray) or obs.dtype.kind not in "biuf":
            return None
        if obs.ndim != len(self.obs_shape) + 1 or obs.shape[1:] != self.obs_shape or not len(obs):
            return None
        policy = self.policy
        if policy.training:  # as SB3's predict leaves it
            policy.set_training_mode(False)
        with torch.no_grad():
            # obs_to_tensor and preprocess_obs: a copy as a tensor, as float32
            x = torch.as_tensor(np.array(obs), device=policy.device).float()
            if self.kind == "q":
                q_net = policy.q_net
                actions = q_net.q_net(q_net.features_extractor(x)).argmax(dim=1).reshape(-1)
            else:
                latent = policy.mlp_extractor.forward_actor(policy.pi_features_extractor(x))
                out = policy.action_net(latent)
                if self.kind == "categorical":  # torch's Categorical(logits=out).probs
                    logits = out - out.logsumexp(dim=-1, keepdim=True)
                    if torch.isnan(logits).any():
                        return None  # Categorical refuses them: SB3's error
                    actions = torch.argmax(torch.softmax(logits, dim=-1), dim=1)
                else:  # Normal(out, ones * exp(log_std)).mean
                    std = torch.ones_like(out) * policy.log_std.exp()
                    if torch.isnan(out).any() or not bool((std > 0).all()):
                        return None  # Normal refuses them: SB3's error
                    actions = out
        result = actions.cpu().numpy().reshape((-1, *self.action_shape))
        if self.box is not None:  # SB3's predict clips an unsquashed Box action
            result = np.clip(result, self.box.low, self.box.high)
        return result


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
