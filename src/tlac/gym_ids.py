"""The built-in domains' Gymnasium ids, registered by ``import tlac`` with entry-point strings:
nothing but Gymnasium is imported until ``gym.make`` builds one (the domain, and with it
stable-baselines3 and torch, is imported then).

>>> import gymnasium as gym
>>> register_gym_ids()
>>> gym.spec("tlac/DoorKey-v0").max_episode_steps
490
"""

from __future__ import annotations

import gymnasium as gym

# id -> ("module:factory", its episodes' step limit); the factories take render_mode
GYM_IDS: dict[str, tuple[str, int]] = {
    "tlac/DoorKey-v0": ("tlac.domains.doorkey.env:make_doorkey_env", 490),  # MiniGrid's 10 * 7**2
    "tlac/DoorKeyPartial-v0": ("tlac.domains.doorkey.env:make_partial_doorkey_env", 490),
    "tlac/HopperBullet-v0": ("tlac.domains.hopper.env:make_bullet_env", 1000),
    "tlac/Hopper-v0": ("tlac.domains.hopper.env:make_mujoco_env", 1000),
    "tlac/PickPlace-v0": ("tlac.domains.pickplace.env:make_env", 100),
}


def register_gym_ids() -> None:
    """Register every built-in domain with Gymnasium (``gym.make("tlac/DoorKey-v0")``); done
    by ``import tlac``. The factories are imported only when an id is made."""
    for env_id, (entry_point, max_episode_steps) in GYM_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry_point, max_episode_steps=max_episode_steps)
