"""tlac's Gymnasium ids as Gymnasium and rl-zoo's scripts use them (issue 43, point 5): each
passes check_env, takes render_mode and declares its step limit."""

from __future__ import annotations

import importlib.util
import warnings

import gymnasium as gym
import pytest
from gymnasium.utils.env_checker import check_env

import tlac  # noqa: F401  (registers the ids)
from tlac.domains import GYM_IDS, Domain, register_domain
from tlac.errors import ConfigError
from tlac.teachers.base import as_teacher

NEEDS = {
    "tlac/HopperBullet-v0": "pybullet_envs_gymnasium",
    "tlac/Hopper-v0": "mujoco",
    "tlac/PickPlace-v0": "gymnasium_robotics",
}


@pytest.mark.parametrize("env_id", list(GYM_IDS))
def test_every_id_passes_check_env_and_renders(env_id: str) -> None:
    module = NEEDS.get(env_id)
    if module is not None and importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} is not installed (an optional extra)")
    assert gym.spec(env_id).max_episode_steps == GYM_IDS[env_id][1]
    env = gym.make(env_id, render_mode="rgb_array")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # check_env's advice (float64 spaces and the like)
        check_env(env.unwrapped, skip_render_check=True)
        check_env(env, skip_render_check=True)
    env.reset(seed=0)
    if module not in ("mujoco", "gymnasium_robotics"):  # MuJoCo renders through OpenGL: no
        frame = env.render()  # display here (MUJOCO_GL=egl where a GPU driver is)
        assert frame is not None and frame.ndim == 3
    assert env.render_mode == "rgb_array"
    env.close()


def test_a_users_domain_id_takes_render_mode() -> None:
    def teacher(name, env, seed):
        return as_teacher(lambda obs: 1, env.action_space, name=name)

    common = dict(
        description="CartPole",
        teacher_names=("right",),
        make_teacher=teacher,
        default_teachers=("right",),
    )
    register_domain(
        Domain(
            name="cartpole-renders",
            make_env=lambda render_mode=None: gym.make("CartPole-v1", render_mode=render_mode),
            **common,
        ),
        replace=True,
    )
    env = gym.make("tlac/cartpole-renders-v0", render_mode="rgb_array")
    env.reset(seed=0)
    assert env.render().ndim == 3
    register_domain(
        Domain(name="cartpole-blind", make_env=lambda: gym.make("CartPole-v1"), **common),
        replace=True,
    )
    gym.make("tlac/cartpole-blind-v0").reset(seed=0)
    with pytest.raises(ConfigError, match="its make_env takes no render_mode"):
        gym.make("tlac/cartpole-blind-v0", render_mode="rgb_array")
