"""The DoorKey domains: ``doorkey`` (the full grid, the paper's studies) and
``doorkey-partial`` (MiniGrid's own partial view). Environment and regions in :mod:`.env`,
the partial view in :mod:`.view`, the scripted planner in :mod:`.planner`, the teachers in
:mod:`.teachers`."""

from __future__ import annotations

from tlac.domains import Domain
from tlac.domains.doorkey.env import (
    MAX_STEPS,
    REGION_NAMES,
    make_doorkey_env,
    make_partial_doorkey_env,
    region_of,
)
from tlac.domains.doorkey.teachers import (
    PARTIAL_TEACHER_NAMES,
    TEACHER_NAMES,
    make_partial_teacher,
    make_teacher,
)

DOMAIN = Domain(
    name="doorkey",
    description="MiniGrid DoorKey 7x7, fully observed grid flattened to 147 values, 6 actions",
    make_env=make_doorkey_env,
    teacher_names=TEACHER_NAMES,
    make_teacher=make_teacher,
    region_names=REGION_NAMES,
    region_of=region_of,
    presets={
        "tlac": "doorkey",
        "a2c": "doorkey",
        "ppo": "doorkey",
        "dqn-tlql": "doorkey",
        "ac-teach": "doorkey",
    },
    default_teachers=("optimal", "random", "random"),
    max_episode_steps=MAX_STEPS,
)


PARTIAL_DOMAIN = Domain(
    name="doorkey-partial",
    description="MiniGrid DoorKey 7x7 as MiniGrid observes it: the agent's 7x7 view "
    "(147 values), 6 actions",
    make_env=make_partial_doorkey_env,
    teacher_names=PARTIAL_TEACHER_NAMES,
    make_teacher=make_partial_teacher,
    presets=dict(DOMAIN.presets),
    default_teachers=("ppo", "random", "random"),
    max_episode_steps=MAX_STEPS,
)
