"""Pick & Place (paper, section 4 and appendix A.3): AC-Teach's version of Fetch PickAndPlace.

The paper reuses the task of Kurenkov et al. (2019): pick up a box and put it at a FIXED
target on the table. Compared with Gymnasium-Robotics' ``FetchPickAndPlace-v4``:

* the goal is fixed at ``GOAL = (1.45, 0.55, 0.425)`` on the table (not sampled, never in the
  air);
* the box starts at ``(1.25, 0.55)`` plus uniform noise of +-0.05 m in x and y (instead of
  +-0.15 m around the gripper);
* the gripper start is jittered by +-0.05 m (x, y) and +-0.025 m (z) around Fetch's usual
  start, by moving the mocap target and letting the arm settle before the episode begins;
* the reward is dense: ``-distance(box, goal)`` per step; episodes last 100 steps;
* the observation is Fetch's 25-dim ``observation`` vector alone (the goal is constant),
  float32; the action is Fetch's 4-dim action in [-1, 1] (xyz displacement scaled by 0.05 m,
  gripper +1 open / -1 close).

``info["is_success"]`` (bool) is True when the box is within 5 cm of the goal (Fetch's own
threshold). Regions for teacher-usage statistics: ``not_holding`` / ``holding`` the box, the
split that defines the paper's Pick and Place partial teachers (appendix A.3.1).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from tlac.errors import needs_control_extra

GOAL = np.array([1.45, 0.55, 0.425])
"""The fixed target position of the box (on the table)."""
OBJECT_START_XY = np.array([1.25, 0.55])
OBJECT_RANGE = 0.05
GRIPPER_JITTER = np.array([0.05, 0.05, 0.025])
MAX_EPISODE_STEPS = 100

"""Appendix A.3.1's teacher set."""
REGION_NAMES: tuple[str, ...] = ("not_holding", "holding")


def _fixed_goal_env_class() -> type:
    try:
        from gymnasium_robotics.envs.fetch.pick_and_place import MujocoFetchPickAndPlaceEnv
    except (ImportError, gym.error.DependencyNotInstalled) as exc:
        raise needs_control_extra("pickplace (Gymnasium-Robotics, MuJoCo)", exc) from None

    class FixedGoalPickAndPlaceEnv(MujocoFetchPickAndPlaceEnv):
        """Fetch PickAndPlace with AC-Teach's fixed goal, narrow box start and gripper jitter."""

        def _reset_sim(self) -> bool:
            # Parent reset: robot at its initial configuration, box somewhere (overwritten).
            super()._reset_sim()
            utils, mj = self._utils, self._mujoco
            # Gripper jitter: move the mocap target and let the arm follow (as Fetch's own
            # _env_setup does for the initial pose).
            utils.reset_mocap2body_xpos(self.model, self.data)
            jitter = self.np_random.uniform(-GRIPPER_JITTER, GRIPPER_JITTER)
            self.data.mocap_pos[0] = self.data.mocap_pos[0] + jitter
            mj.mj_step(self.model, self.data, nstep=10 * self.n_substeps)
            # Box start: (1.25, 0.55) + U(+-0.05) in x and y, resting on the table, at rest.
            qpos = utils.get_joint_qpos(self.model, self.data, "object0:joint").copy()
            qpos[:2] = OBJECT_START_XY + self.np_random.uniform(-OBJECT_RANGE, OBJECT_RANGE, 2)
            qpos[2] = self.height_offset
            qpos[3:] = [1.0, 0.0, 0.0, 0.0]
            utils.set_joint_qpos(self.model, self.data, "object0:joint", qpos)
            utils.set_joint_qvel(self.model, self.data, "object0:joint", np.zeros(6))
            mj.mj_forward(self.model, self.data)
            return True

        def _sample_goal(self) -> np.ndarray:
            return GOAL.copy()

    return FixedGoalPickAndPlaceEnv


class FetchVectorObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Keep only Fetch's 25-dim ``observation`` vector (float32); ``is_success`` as a bool."""

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(25,), dtype=np.float32)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        info = dict(info)
        info["is_success"] = bool(np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"]) < 0.05)
        return obs["observation"].astype(np.float32), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        info = dict(info)
        info["is_success"] = bool(info.get("is_success", 0.0))
        return obs["observation"].astype(np.float32), float(reward), terminated, truncated, info


def make_env(max_episode_steps: int = MAX_EPISODE_STEPS, render_mode: str | None = None) -> gym.Env:
    """AC-Teach's Pick & Place: fixed goal, dense reward, 100-step episodes."""
    env = _fixed_goal_env_class()(reward_type="dense", render_mode=render_mode)
    env = FetchVectorObservation(env)
    return gym.wrappers.TimeLimit(env, max_episode_steps=max_episode_steps)


HOLD_DIST = 0.03
"""Holding: grip point within this distance of the box centre ..."""
HOLD_WIDTH = (0.03, 0.06)
"""... and finger opening (sum of both finger joints) in this range (closed on the box)."""


def is_holding(obs: np.ndarray) -> np.ndarray:
    """Boolean per row: the gripper holds the box (region ``holding`` of the domain)."""
    obs = np.asarray(obs, dtype=np.float64)
    dist = np.linalg.norm(obs[:, 6:9], axis=1)
    width = obs[:, 9] + obs[:, 10]
    return (dist < HOLD_DIST) & (width > HOLD_WIDTH[0]) & (width < HOLD_WIDTH[1])


def region_of(obs: np.ndarray) -> np.ndarray:
    """0 = ``not_holding``, 1 = ``holding`` the box (:func:`is_holding`)."""
    return is_holding(np.asarray(obs).reshape(len(obs), -1)).astype(np.int64)
