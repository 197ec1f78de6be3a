"""Hopper environments (paper, section 4 and appendix A.2).

* ``hopper-bullet``: the paper's environment, PyBullet's Hopper (``HopperBulletEnv-v0`` from
  ``pybullet-envs-gymnasium``, the Gymnasium port of the "HopperPyBulletEnv-v0" of PyBullet
  Gymperium): 15-dim observation, 3-dim action in [-1, 1], 1000-step episodes.
* ``hopper``: today's standard MuJoCo Hopper (Gymnasium ``Hopper-v5``): 11-dim observation,
  3-dim action, 1000-step episodes.

Teachers (appendix A.2.1): ``optimal`` is a SAC policy (deterministic actions of the shipped
actor, see :mod:`tlac.teachers.sac`); ``good`` follows it with probability 0.8 and acts
uniformly at random otherwise; ``noisy`` with probability 0.2; ``random`` is uniform. Hopper
has no partial teachers (paper, footnote 7), so there is a single region ``all``.
"""

from __future__ import annotations

import os
import sys
from typing import Any

import gymnasium as gym
import numpy as np

from tlac.errors import needs_control_extra


class Float32Observation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Cast observations to float32 (MuJoCo's Hopper-v5 returns float64) so the observation
    matches a float32 ``Box`` and ``check_env`` passes."""

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.ObservationWrapper.__init__(self, env)
        space = env.observation_space
        assert isinstance(space, gym.spaces.Box)
        self.observation_space = gym.spaces.Box(
            low=space.low.astype(np.float32),
            high=space.high.astype(np.float32),
            shape=space.shape,
            dtype=np.float32,
        )

    def observation(self, observation: np.ndarray) -> np.ndarray:
        return np.asarray(observation, dtype=np.float32)


class QuietBulletConnect(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Silence the ``argv[0]=`` line PyBullet's C code prints on stdout when the environment
    connects to the physics server (its first reset), so ``--json`` output stays clean."""

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        self._connected = False

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        if self._connected:
            return self.env.reset(**kwargs)
        self._connected = True
        sys.stdout.flush()
        try:
            saved = os.dup(1)
        except OSError:  # no real stdout (e.g. some notebook kernels): nothing to silence
            return self.env.reset(**kwargs)
        try:
            with open(os.devnull, "w") as devnull:
                os.dup2(devnull.fileno(), 1)
                return self.env.reset(**kwargs)
        finally:
            os.dup2(saved, 1)
            os.close(saved)


def make_bullet_env(render_mode: str | None = None) -> gym.Env:
    """PyBullet Hopper, the paper's environment (1000-step time limit)."""
    try:
        import pybullet_envs_gymnasium  # noqa: F401  (registers the *BulletEnv-v0 ids)
    except ImportError as exc:
        raise needs_control_extra("hopper-bullet", exc) from None
    env = gym.make("HopperBulletEnv-v0", max_episode_steps=1000, render_mode=render_mode)
    return Float32Observation(QuietBulletConnect(env))


def make_mujoco_env(render_mode: str | None = None) -> gym.Env:
    """Gymnasium MuJoCo Hopper-v5 (1000-step time limit)."""
    try:
        env = gym.make("Hopper-v5", max_episode_steps=1000, render_mode=render_mode)
    except (ImportError, gym.error.DependencyNotInstalled) as exc:
        raise needs_control_extra("hopper (MuJoCo)", exc) from None
    return Float32Observation(env)


def region_of(obs: np.ndarray) -> np.ndarray:
    """Hopper has one region, ``all`` (no partial teachers, paper footnote 7)."""
    return np.zeros(len(obs), dtype=np.int64)
