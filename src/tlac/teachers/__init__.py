"""Teachers: the protocol, the generic wrappers (good / noisy / random / partial) and the
shipped-policy teachers (:mod:`.sac`, :mod:`.ppo`). Domain-specific teachers live in their
domain's package (:mod:`tlac.domains.doorkey.teachers`, ...) and are built through each
domain's ``make_teacher``. Measuring a teacher on a domain: :func:`tlac.evaluation.measure_teacher`;
training one: :mod:`tlac.teacher_training`.
"""

from tlac.teachers.base import Teacher, TeacherSpec, as_teacher, check_actions, unique_names
from tlac.teachers.sb3 import from_rl_zoo, from_sb3
from tlac.teachers.wrappers import (
    GaussianNoiseTeacher,
    MixedRandomTeacher,
    PartialTeacher,
    RandomTeacher,
    sample_uniform,
)

__all__ = [
    "GaussianNoiseTeacher",
    "MixedRandomTeacher",
    "PartialTeacher",
    "RandomTeacher",
    "Teacher",
    "TeacherSpec",
    "as_teacher",
    "check_actions",
    "from_rl_zoo",
    "from_sb3",
    "sample_uniform",
    "unique_names",
]
