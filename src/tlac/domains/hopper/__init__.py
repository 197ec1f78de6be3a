"""The Hopper domains: ``hopper-bullet`` (PyBullet, the paper's) and ``hopper`` (MuJoCo
Hopper-v5); environments in :mod:`.env`, teachers in :mod:`.teachers`. One region, ``all``:
Hopper has no partial teachers (paper, footnote 7)."""

from __future__ import annotations

from tlac.domains import Domain
from tlac.domains.hopper.env import make_bullet_env, make_mujoco_env, region_of
from tlac.domains.hopper.teachers import TEACHER_NAMES, teacher_factory

_PRESETS = {"tlac": "hopper", "a2c": "hopper", "ppo": "hopper", "ac-teach": "hopper"}

BULLET_DOMAIN = Domain(
    name="hopper-bullet",
    description="PyBullet Hopper (HopperBulletEnv-v0, the paper's), 15-dim obs, 3-dim action",
    make_env=make_bullet_env,
    teacher_names=TEACHER_NAMES,
    make_teacher=teacher_factory("hopper-bullet"),
    region_names=("all",),
    region_of=region_of,
    presets=dict(_PRESETS),
    default_teachers=("optimal", "random", "random"),
    max_episode_steps=1000,
)

MUJOCO_DOMAIN = Domain(
    name="hopper",
    description="MuJoCo Hopper (Gymnasium Hopper-v5), 11-dim obs, 3-dim action",
    make_env=make_mujoco_env,
    teacher_names=TEACHER_NAMES,
    make_teacher=teacher_factory("hopper"),
    region_names=("all",),
    region_of=region_of,
    presets=dict(_PRESETS),
    default_teachers=("optimal", "random", "random"),
    max_episode_steps=1000,
)
