"""A domain of your own: CartPole-v1 with a PD controller and a random teacher.

Use it by file and attribute, from anywhere (no installation, no registration):

    tlac train --env examples/my_domain.py:DOMAIN --teachers pd,random --steps 20000
    # in an experiment config, relative to the config's folder:  domain: my_domain.py:DOMAIN

or from Python, by the name it registers:

    from tlac import TLAC, register_domain
    from examples.my_domain import DOMAIN      # or define it in your own code
    register_domain(DOMAIN)
    model = TLAC("cartpole-pd", teachers=["pd", "random"]).learn(20_000)
    gym.make("tlac/cartpole-pd-v0")            # and as a Gymnasium id
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from tlac.domains import Domain
from tlac.teachers.base import Teacher, as_teacher
from tlac.teachers.wrappers import RandomTeacher


def pd_controller(obs: np.ndarray) -> int:
    """Push the cart towards where the pole is falling (0 = left, 1 = right)."""
    return int(obs[2] + 0.5 * obs[3] > 0)


def make_teacher(name: str, env: gym.Env, seed: int) -> Teacher:
    """``(teacher name, an env for its spaces, seed) -> Teacher``, as Domain asks."""
    if name == "pd":
        return as_teacher(pd_controller, env.action_space, name="pd")
    return RandomTeacher(env.action_space, seed=seed, name="random")


def region_of(obs: np.ndarray) -> np.ndarray:
    """Teacher-usage statistics per half of the track: 0 = left, 1 = right."""
    return (np.asarray(obs)[:, 0] > 0).astype(np.int64)


DOMAIN = Domain(
    name="cartpole-pd",
    description="CartPole-v1 with a PD controller and a random teacher (an example domain)",
    make_env=lambda: gym.make("CartPole-v1"),
    teacher_names=("pd", "random"),
    make_teacher=make_teacher,
    region_names=("left", "right"),
    region_of=region_of,
    default_teachers=("pd", "random"),
    max_episode_steps=500,
)
