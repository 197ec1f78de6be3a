"""Scripted Pick & Place teachers (paper, appendix A.3.1; AC-Teach's hand-coded teachers).

All teachers read only the 25-dim Fetch observation (:mod:`tlac.domains.pickplace.env`):
``grip = obs[0:3]``, ``box = obs[3:6]``, ``rel = obs[6:9] = box - grip``, finger joints
``obs[9:11]`` (0 = closed, 0.05 = fully open; about 0.025 each around the 5 cm box). The goal
is the constant :data:`tlac.domains.pickplace.env.GOAL`. Actions are ``[dx, dy, dz, gripper]`` in
[-1, 1]; Fetch moves the gripper target by 0.05 m per unit of ``dx, dy, dz``.

* :func:`pick_actions`: open the gripper, move laterally above the box, descend, close when
  the grip point is within ~1 cm of the box, then hold (closed, still) once grasping.
* :func:`place_actions`: keep the gripper closed, carry the box toward the goal (lifted while
  far from it in x and y), lower it, open when it is over the goal.
* :func:`optimal_actions`: pick when not holding the box, place when holding it; once the box
  rests at the goal and is released, stay still with the gripper open.

The domain's ``pick`` / ``place`` teachers are the paper's partial teachers, which the paper
took from AC-Teach's public code (Kurenkov et al. 2019). They are never random; each knows one
half of the task and does its own thing in the other half:

* :func:`ac_teach_pick_actions`: pick (as above); once it holds the box it keeps the gripper
  closed and carries the box back to the box's start position (AC-Teach's ``PickAgent`` with
  ``return_to_start``), so it never brings it to the goal.
* :func:`ac_teach_place_actions`: the gripper always closed, heading for the goal (AC-Teach's
  ``PlaceAgent``): holding the box it carries it there (lifted while far, lowered over the
  goal) and opens above it; not holding it, it moves the closed gripper to the goal, so it
  never picks the box up.

``pick-region`` / ``place-region`` are the previous reading of the appendix: the optimal
teacher in one region (not holding / holding) and uniformly random in the other
(:class:`tlac.teachers.wrappers.PartialTeacher`). ``good`` / ``noisy`` add Gaussian noise of
0.01 / 0.1 to the xyz part (rescaled so no component exceeds 1; the gripper command is kept).

The thresholds below were tuned for MuJoCo 3.3 / Gymnasium-Robotics 1.4 (see docs/control.md).
"""

from __future__ import annotations

from collections.abc import Callable

import gymnasium as gym
import numpy as np

from tlac.domains.pickplace.env import GOAL, OBJECT_START_XY, is_holding, region_of
from tlac.errors import UnknownNameError
from tlac.teachers.base import Teacher
from tlac.teachers.wrappers import GaussianNoiseTeacher, PartialTeacher, RandomTeacher

TEACHER_NAMES: tuple[str, ...] = (
    "optimal",
    "good",
    "noisy",
    "pick",
    "place",
    "random",
    "pick-region",
    "place-region",
)
"""Appendix A.3.1's teachers, and the region-based pick / place of our first reading."""

GAIN = 10.0
"""Proportional gain from position error (m) to action; 1/0.05 = 20 would cover the error in
one step if the arm followed the mocap target exactly."""
GRASP_DIST = 0.01
"""Close the gripper when the grip point is this close to the box centre (~1 cm)."""
LATERAL_TOL = 0.01
"""Descend onto the box only once it is this close in x and y."""
APPROACH_HEIGHT = 0.05
"""Height above the box kept while moving laterally toward it."""
CARRY_HEIGHT = 0.05
"""Carry the box this far above the goal while it is far from the goal in x and y."""
PLACE_LATERAL_TOL = 0.01
"""Open the gripper when the box is within this distance of the goal in x and y ..."""
PLACE_HEIGHT_TOL = 0.02
"""... and within this distance of the goal height."""
DONE_DIST = 0.02
"""Box released within this distance of the goal: stay still."""


def _xyz(error: np.ndarray) -> np.ndarray:
    return np.clip(GAIN * error, -1.0, 1.0)


def pick_actions(obs: np.ndarray) -> np.ndarray:
    """The pick sub-policy for a batch of observations (see the module docstring)."""
    obs = np.asarray(obs, dtype=np.float64)
    rel = obs[:, 6:9]
    holding = is_holding(obs)
    lateral = np.linalg.norm(rel[:, :2], axis=1)
    target = rel.copy()
    far = lateral > LATERAL_TOL
    # Far in x, y: move laterally, staying APPROACH_HEIGHT above the box (rel z + height).
    target[far, 2] = rel[far, 2] + APPROACH_HEIGHT
    xyz = _xyz(target)
    close = (np.linalg.norm(rel, axis=1) < GRASP_DIST) | holding
    gripper = np.where(close, -1.0, 1.0)
    xyz[holding] = 0.0  # hold still once grasping
    return np.concatenate([xyz, gripper[:, None]], axis=1).astype(np.float32)


def place_actions(obs: np.ndarray) -> np.ndarray:
    """The place sub-policy for a batch of observations (see the module docstring)."""
    obs = np.asarray(obs, dtype=np.float64)
    box = obs[:, 3:6]
    err = GOAL[None, :] - box
    lateral = np.linalg.norm(err[:, :2], axis=1)
    target = err.copy()
    far = lateral > PLACE_LATERAL_TOL
    # Lift while far from the goal in x, y; lower onto it once above it.
    target[far, 2] = err[far, 2] + CARRY_HEIGHT
    xyz = _xyz(target)
    release = ~far & (np.abs(err[:, 2]) < PLACE_HEIGHT_TOL)
    gripper = np.where(release, 1.0, -1.0)
    return np.concatenate([xyz, gripper[:, None]], axis=1).astype(np.float32)


def ac_teach_pick_actions(obs: np.ndarray) -> np.ndarray:
    """AC-Teach's pick teacher: :func:`pick_actions` until it holds the box, then it carries
    the box, gripper closed, back to where boxes start (``OBJECT_START_XY`` on the table)."""
    obs = np.asarray(obs, dtype=np.float64)
    actions = pick_actions(obs)
    holding = is_holding(obs)
    if holding.any():
        start = np.array([*OBJECT_START_XY, GOAL[2]])  # the goal lies on the table too
        err = start[None, :] - obs[holding, 3:6]
        actions[holding, :3] = _xyz(err)
        actions[holding, 3] = -1.0
    return actions


def ac_teach_place_actions(obs: np.ndarray) -> np.ndarray:
    """AC-Teach's place teacher: gripper closed, always heading for the goal. Holding the box:
    :func:`place_actions` (carry it there and open above it). Not holding it: the closed
    gripper moves to the goal, lifted while far from it in x and y (it never grasps)."""
    obs = np.asarray(obs, dtype=np.float64)
    actions = place_actions(obs)
    free = ~is_holding(obs)
    if free.any():
        err = GOAL[None, :] - obs[free, 0:3]
        far = np.linalg.norm(err[:, :2], axis=1) > PLACE_LATERAL_TOL
        err[far, 2] += CARRY_HEIGHT
        actions[free, :3] = _xyz(err)
        actions[free, 3] = -1.0
    return actions


def optimal_actions(obs: np.ndarray) -> np.ndarray:
    """Pick when not holding the box, place when holding it; idle once it is at the goal."""
    obs = np.asarray(obs, dtype=np.float64)
    holding = is_holding(obs)
    actions = pick_actions(obs)
    if holding.any():
        actions[holding] = place_actions(obs[holding])
    done = ~holding & (np.linalg.norm(GOAL[None, :] - obs[:, 3:6], axis=1) < DONE_DIST)
    actions[done] = np.array([0.0, 0.0, 0.0, 1.0], dtype=np.float32)
    return actions


class ScriptedTeacher:
    """A batched teacher from one of the functions above."""

    def __init__(self, fn: Callable[[np.ndarray], np.ndarray], name: str):
        self.fn, self.name = fn, name

    def predict(self, obs: np.ndarray) -> np.ndarray:
        return self.fn(np.asarray(obs).reshape(len(obs), -1))


def make_pickplace_teacher(name: str, action_space: gym.Space, seed: int) -> Teacher:
    """Appendix A.3.1's teachers by name: optimal, good, noisy, pick, place, random, and the
    region-based pick-region / place-region."""
    optimal = ScriptedTeacher(optimal_actions, "optimal")
    if name == "optimal":
        return optimal
    if name in ("good", "noisy"):
        sigma = 0.01 if name == "good" else 0.1
        return GaussianNoiseTeacher(optimal, sigma, action_space, seed, dims=3, name=name)
    if name == "pick":  # AC-Teach's: picks, then carries the box back to its start
        return ScriptedTeacher(ac_teach_pick_actions, "pick")
    if name == "place":  # AC-Teach's: gripper closed, always heading for the goal
        return ScriptedTeacher(ac_teach_place_actions, "place")
    if name == "pick-region":  # optimal when not holding the box (region 0), random otherwise
        return PartialTeacher(optimal, region_of, [0], action_space, seed, name=name)
    if name == "place-region":  # optimal when holding the box (region 1), random otherwise
        return PartialTeacher(optimal, region_of, [1], action_space, seed, name=name)
    if name == "random":
        return RandomTeacher(action_space, seed, name="random")
    raise UnknownNameError("teacher for pickplace", name, TEACHER_NAMES)


def make_teacher(name: str, env: gym.Env, seed: int) -> Teacher:
    """The domain's ``make_teacher``: :func:`make_pickplace_teacher` on ``env``'s action space."""
    return make_pickplace_teacher(name, env.action_space, seed)
