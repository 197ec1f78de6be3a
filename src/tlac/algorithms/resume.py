"""What a checkpoint needs, beyond the weights, for training to continue EXACTLY as if it had
never stopped: the random-number generators of the algorithm and of the teachers, and the
environments with their episodes in progress.

Everything is stored as plain data and tensors (``torch.load(weights_only=True)`` reads it),
except the environments' own state: there is no general way to write a Gymnasium environment
as data, so it is pickled into a byte tensor. Loading the file runs no code; only
:func:`restore_vec_env` unpickles those bytes, and only when a caller asks to resume (resume
your own checkpoints only). Some environments cannot be pickled with their episode in progress
(:func:`env_state_pickles`: PyBullet, MuJoCo); a resume then starts new episodes in them, and
only that part is not exact. See docs/architecture.md, "Checkpoints and exact resume".
"""

from __future__ import annotations

import pickle
import warnings
from collections import deque
from typing import Any

import numpy as np
import torch

from tlac.errors import ConfigError

_SKIP = (str, bytes, int, float, bool, type(None), np.ndarray, torch.Tensor, type)


def _generators(obj: Any, depth: int, seen: set[int]) -> list[np.random.Generator]:
    """The NumPy generators reachable from ``obj``'s attributes, in a fixed order."""
    if (
        depth < 0
        or id(obj) in seen
        or isinstance(obj, _SKIP)
        or (callable(obj) and not hasattr(obj, "__dict__"))
    ):
        return []
    seen.add(id(obj))
    if isinstance(obj, np.random.Generator):
        return [obj]
    found: list[np.random.Generator] = []
    items = list(obj) if isinstance(obj, list | tuple) else None
    if items is None:
        attrs = getattr(obj, "__dict__", None)
        if not isinstance(attrs, dict) or type(obj).__module__.split(".")[0] not in ("tlac",):
            return []
        items = [attrs[k] for k in sorted(attrs)]
    for item in items:
        found += _generators(item, depth - 1, seen)
    return found


def generator_states(obj: Any) -> list[dict[str, Any]]:
    """The states of every NumPy generator held by ``obj`` (a teacher, a selector...) or by the
    tlac objects it holds, up to three levels down.

    >>> from tlac.teachers.wrappers import RandomTeacher
    >>> import gymnasium as gym
    >>> t = RandomTeacher(gym.spaces.Discrete(3), seed=0)
    >>> states = generator_states(t); first = t.predict(np.zeros((4, 2))).tolist()
    >>> restore_generator_states(t, states); t.predict(np.zeros((4, 2))).tolist() == first
    True
    """
    return [g.bit_generator.state for g in _generators(obj, 3, set())]


def restore_generator_states(obj: Any, states: list[dict[str, Any]]) -> None:
    """Put back what :func:`generator_states` saved (the same object structure is required)."""
    generators = _generators(obj, 3, set())
    if len(generators) != len(states):
        raise ConfigError(
            f"the checkpoint holds {len(states)} random-number generators for "
            f"{type(obj).__name__}, it has {len(generators)}: not the same teachers or settings"
        )
    for g, state in zip(generators, states, strict=True):
        g.bit_generator.state = state


def env_state_pickles(env: Any) -> bool:
    """Whether pickling ``env`` keeps its episode in progress. Not for an environment whose
    state lives outside Python (PyBullet's physics server: an unpickled copy is disconnected
    and cannot step) nor for one that pickles as its constructor's arguments (Gymnasium's
    ``EzPickle``: MuJoCo and Gymnasium-Robotics come back as new, un-reset simulations).

    >>> import gymnasium as gym
    >>> env_state_pickles(gym.make("CartPole-v1")), env_state_pickles(gym.make("Hopper-v5"))
    (True, False)
    """
    from gymnasium.utils import EzPickle

    base = getattr(env, "unwrapped", env)
    return not (isinstance(base, EzPickle) or type(base).__module__.startswith("pybullet"))


def vec_env_state(venv: Any) -> dict[str, Any]:
    """The episodes in progress of a tlac ``EpisodeRecorder`` over a ``DummyVecEnv``: its
    counters as data and the environments pickled into a uint8 tensor (``None`` where they
    cannot be, :func:`env_state_pickles`)."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    inner = getattr(venv, "venv", None)
    if not isinstance(inner, DummyVecEnv):
        raise ConfigError(
            "exact resume needs the environments in memory (a DummyVecEnv, as a domain name "
            f"or a Gymnasium env gives); got {type(inner or venv).__name__}"
        )
    exact = all(env_state_pickles(env) for env in inner.envs)
    try:
        blob = pickle.dumps(inner.envs) if exact else None
    except (pickle.PicklingError, AttributeError, TypeError):  # a wrapper holding a lambda
        blob = None  # (gymnasium's FilterObservation): resumed with new episodes
    return {
        "envs": None if blob is None else torch.frombuffer(bytearray(blob), dtype=torch.uint8),
        "num_timesteps": int(venv.num_timesteps),
        "returns": torch.from_numpy(np.array(venv._returns)),
        "lengths": torch.from_numpy(np.array(venv._lengths)),
        "episode_returns": [float(r) for r in venv.episode_returns],
        "episode_lengths": [int(n) for n in venv.episode_lengths],
        "episodes_done": int(venv.episodes_done),
    }


def restore_vec_env(venv: Any, state: dict[str, Any]) -> bool:
    """Put the saved environments and counters into ``venv`` (unpickles the environments).

    Returns False where the environments cannot come back with their episodes in progress
    (:func:`env_state_pickles`, also for checkpoints written before that check): ``venv`` keeps
    its own environments, the unfinished episodes are dropped from the counters, and the caller
    must reset ``venv`` before its next step (a warning says so)."""
    inner = venv.venv
    exact = state["envs"] is not None and all(env_state_pickles(env) for env in inner.envs)
    if exact:
        envs = pickle.loads(state["envs"].numpy().tobytes())  # noqa: S301 - resume of own files
        if len(envs) != len(inner.envs):
            raise ConfigError(
                f"the checkpoint holds {len(envs)} environments, the given env has {len(inner.envs)}"
            )
        for env in inner.envs:
            env.close()
        inner.envs = envs
    else:
        warnings.warn(
            f"{type(inner.envs[0].unwrapped).__name__}: its simulation cannot be saved, so the "
            "resumed run starts new episodes (the unfinished ones are dropped; the rest is exact)",
            stacklevel=2,
        )
    venv.num_timesteps = state["num_timesteps"]
    venv._returns[:] = state["returns"].numpy() if exact else 0
    venv._lengths[:] = state["lengths"].numpy() if exact else 0
    venv.episode_returns.clear()
    venv.episode_returns.extend(state["episode_returns"])
    venv.episode_lengths.clear()
    venv.episode_lengths.extend(state.get("episode_lengths", []))
    venv.episodes_done = state["episodes_done"]
    return exact


def attributes_state(obj: Any) -> dict[str, Any]:
    """A small object's attributes as data: arrays as tensors, deques and lists of numbers
    as lists, numbers as they are, NumPy generators as their states (a selector, the solo
    statistics). Other attributes are left out: they are rebuilt from the settings.

    >>> from collections import deque
    >>> class Stats: pass
    >>> s = Stats(); s.counts = np.array([1, 2]); s.recent = deque([0.5], maxlen=3); s.best = 0.9
    >>> state = attributes_state(s); s.counts[:] = 0; s.recent.clear(); s.best = 0.0
    >>> restore_attributes(s, state); s.counts.tolist(), list(s.recent), s.best
    ([1, 2], [0.5], 0.9)
    """
    out: dict[str, Any] = {}
    for name, value in sorted(vars(obj).items()):
        if isinstance(value, np.random.Generator):
            out[name] = {"generator": value.bit_generator.state}
        elif isinstance(value, np.ndarray):
            out[name] = torch.from_numpy(value.copy())
        elif isinstance(value, deque | list) and all(isinstance(v, int | float) for v in value):
            out[name] = {"sequence": [float(v) for v in value]}
        elif isinstance(value, bool | int | float):
            out[name] = value
    return out


def restore_attributes(obj: Any, state: dict[str, Any]) -> None:
    """Put back what :func:`attributes_state` saved, in place."""
    for name, value in state.items():
        current = getattr(obj, name)
        if isinstance(value, dict) and "generator" in value:
            current.bit_generator.state = value["generator"]
        elif isinstance(value, torch.Tensor):
            current[...] = value.numpy()
        elif isinstance(value, dict) and "sequence" in value:
            current.clear()
            current.extend(value["sequence"])
        else:
            setattr(obj, name, value)
