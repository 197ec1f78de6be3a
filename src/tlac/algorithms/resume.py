"""What a checkpoint needs, beyond the weights, for training to continue EXACTLY as if it had
never stopped: the random-number generators of the algorithm and of the teachers, and the
episodes in progress.

Everything is stored as plain data and tensors, and loaded with
``torch.load(weights_only=True)``: nothing in a checkpoint is unpickled, so no file runs code
when it is read or resumed. The environments are not stored (their objects could only be
pickled): each one's episode in progress is re-created instead, from the seed or generator
state of the reset that began it and the actions since (:class:`tlac.recording.EpisodeLog`),
which works for any environment whose randomness comes from its ``np_random`` as Gymnasium
asks, PyBullet's and MuJoCo's simulations included. An episode that comes out different (its
last observation is checked) or cannot be re-created is dropped with a warning and the resumed
run starts new episodes; only that part is then not exact. See docs/architecture.md,
"Checkpoints, exact resume and safe loading".
"""

from __future__ import annotations

import warnings
from collections import deque
from typing import Any

import numpy as np
import torch

from tlac.errors import ConfigError
from tlac.recording import EpisodeLog, episode_logs

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


def vec_env_state(venv: Any) -> dict[str, Any]:
    """The episodes in progress of a tlac ``EpisodeRecorder`` over a ``DummyVecEnv``: its
    counters, and for each environment what re-creates its episode
    (:meth:`tlac.recording.EpisodeLog.state`; ``None`` where it cannot be)."""
    inner = episode_logs(venv)
    if inner is None:
        raise ConfigError(
            "exact resume needs the environments in memory (a DummyVecEnv, as a domain name "
            f"or a Gymnasium env gives); got {type(getattr(venv, 'venv', venv)).__name__}"
        )
    return {
        "episodes": [env.state() if isinstance(env, EpisodeLog) else None for env in inner.envs],
        "num_timesteps": int(venv.num_timesteps),
        "returns": torch.from_numpy(np.array(venv._returns)),
        "lengths": torch.from_numpy(np.array(venv._lengths)),
        "episode_returns": [float(r) for r in venv.episode_returns],
        "episode_lengths": [int(n) for n in venv.episode_lengths],
        "episodes_done": int(venv.episodes_done),
    }


def restore_vec_env(venv: Any, state: dict[str, Any]) -> bool:
    """Re-create the saved episodes in progress in ``venv``'s fresh environments and put back
    its counters.

    Returns False where an episode cannot be re-created or comes out different (and for a
    checkpoint of an older tlac, which pickled its environments: that pickle is never read):
    the unfinished episodes are then dropped from the counters, and the caller must reset
    ``venv`` before its next step (a warning says so)."""
    inner = episode_logs(venv)
    if inner is None:
        raise ConfigError("exact resume needs the environments in memory (a DummyVecEnv)")
    episodes = state.get("episodes")
    if episodes is not None and len(episodes) != len(inner.envs):
        raise ConfigError(
            f"the checkpoint holds {len(episodes)} environments, "
            f"the given env has {len(inner.envs)}"
        )
    exact = episodes is not None and all(
        isinstance(env, EpisodeLog) and env.replay(episode)
        for env, episode in zip(inner.envs, episodes, strict=True)
    )
    if exact:  # as after the uninterrupted run's first reset: seeds are used once
        inner._reset_seeds()
        inner._reset_options()
    else:
        why = (
            "this checkpoint was written by an older tlac, which pickled its environments "
            "(never unpickled: that could run code)"
            if episodes is None
            else "its episodes in progress could not be re-created as they were"
        )
        warnings.warn(
            f"{type(inner.envs[0].unwrapped).__name__}: {why}, so the resumed run starts new "
            "episodes (the unfinished ones are dropped; the rest is exact)",
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
