"""Hopper's teachers (appendix A.2.1): ``optimal`` is the shipped SAC actor (deterministic,
:mod:`tlac.teachers.sac`); ``good`` / ``noisy`` follow it with probability 0.8 / 0.2 and act
uniformly at random otherwise; ``random`` is uniform."""

from __future__ import annotations

import gymnasium as gym

from tlac.errors import UnknownNameError
from tlac.teachers.base import Teacher
from tlac.teachers.sac import SACActorTeacher
from tlac.teachers.wrappers import MixedRandomTeacher, RandomTeacher

TEACHER_NAMES: tuple[str, ...] = ("optimal", "good", "noisy", "random")
"""Appendix A.2.1's teacher set."""

P_TEACHER: dict[str, float] = {"good": 0.8, "noisy": 0.2}
"""Probability of following the optimal (SAC) policy; a uniform random action otherwise."""


def teacher_factory(env_name: str):
    def make_teacher(name: str, env: gym.Env, seed: int) -> Teacher:
        space = env.action_space
        if name == "random":
            return RandomTeacher(space, seed, name="random")
        if name == "optimal":
            return SACActorTeacher.load(env_name, name="optimal")
        if name in P_TEACHER:
            base = SACActorTeacher.load(env_name, name="optimal")
            return MixedRandomTeacher(base, P_TEACHER[name], space, seed, name=name)
        raise UnknownNameError(f"teacher for {env_name}", name, TEACHER_NAMES)

    return make_teacher
