"""Teachers: the protocol, the generic wrappers (good / noisy / random / partial) and
teacher measurement. Domain-specific scripted teachers live in their own modules
(:mod:`tlac.teachers.doorkey`, ...) and are built through each domain's ``make_teacher``.
"""

from tlac.teachers.base import Teacher, as_teacher, check_actions, unique_names
from tlac.teachers.measure import measure_teacher
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
    "as_teacher",
    "check_actions",
    "measure_teacher",
    "sample_uniform",
    "unique_names",
]
