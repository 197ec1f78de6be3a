"""The Pick & Place domain (AC-Teach's task, reused by the paper): the environment, its
regions (holding the box or not) in :mod:`.env`, the scripted teachers in :mod:`.teachers`."""

from __future__ import annotations

from tlac.domains import Domain
from tlac.domains.pickplace.env import MAX_EPISODE_STEPS, REGION_NAMES, make_env, region_of
from tlac.domains.pickplace.teachers import TEACHER_NAMES, make_teacher

DOMAIN = Domain(
    name="pickplace",
    description="Fetch Pick & Place (AC-Teach's): fixed goal, dense reward, 25-dim obs, "
    "4-dim action",
    make_env=make_env,
    teacher_names=TEACHER_NAMES,
    make_teacher=make_teacher,
    region_names=REGION_NAMES,
    region_of=region_of,
    presets={"tlac": "pickplace", "a2c": "pickplace", "ppo": "pickplace", "ac-teach": "pickplace"},
    default_teachers=("optimal", "random", "random"),
    max_episode_steps=MAX_EPISODE_STEPS,
)
