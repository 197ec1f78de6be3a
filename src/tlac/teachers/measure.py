"""Measure a teacher on its own: the mean return the paper quotes beside each teacher.

The paper reports each teacher's average return over 1000 test episodes (appendices A.1.1,
A.2.1, A.3.1). :func:`measure_teacher` runs a teacher alone on a domain's environment, over
several environments stepped in lock-step so that batched teachers are queried in batches.

Episode ``i`` (0-based) is reset with seed ``seed + i``, so the set of episodes does not
depend on ``n_envs``; a stochastic teacher's own random draws do (they come in batches).

Success per episode:

* ``success_fn(episode_return, final_info)`` when given;
* otherwise the domain's rule in :data:`DEFAULT_SUCCESS` (DoorKey: return > 0, i.e. the goal
  was reached, the reward being sparse);
* otherwise ``final_info["is_success"]`` when the environment reports it (Fetch);
* otherwise no success rate (``None``), e.g. Hopper.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from tlac.errors import ConfigError, UnknownNameError
from tlac.teachers.base import Teacher, as_teacher, check_actions

if TYPE_CHECKING:  # tlac.domains imports this package: import it lazily at run time
    from tlac.domains import Domain

SuccessFn = Callable[[float, dict[str, Any]], bool]

DEFAULT_SUCCESS: dict[str, SuccessFn] = {
    # DoorKey's only reward is given on reaching the goal (MiniGrid: 1 - 0.9 t / max_steps).
    "doorkey": lambda episode_return, info: episode_return > 0.0,
}


def measure_teacher(
    domain: Domain | str,
    teacher: Teacher | str | Any,
    episodes: int,
    seed: int,
    n_envs: int = 8,
    success_fn: SuccessFn | None = None,
) -> dict[str, Any]:
    """Run ``teacher`` alone for ``episodes`` episodes of ``domain``'s environment.

    ``domain`` is a :class:`tlac.domains.Domain` or its name; ``teacher`` is a teacher name of
    the domain (built with ``domain.make_teacher(name, env, seed)``) or anything
    :func:`tlac.teachers.base.as_teacher` accepts. Returns a dict with ``mean``, ``std``
    (population std of the episode returns), ``success_rate`` (or None, see the module
    docstring), ``episodes``, ``mean_length`` and ``returns`` (one per episode, in episode
    order).
    """
    from tlac.domains import Domain, get_domain

    if isinstance(domain, str):
        domain = get_domain(domain)
    if not isinstance(domain, Domain):
        raise ConfigError(f"expected a Domain or a domain name; got {domain!r}")
    if int(episodes) < 1:
        raise ConfigError(f"episodes must be >= 1; got {episodes}")
    if int(n_envs) < 1:
        raise ConfigError(f"n_envs must be >= 1; got {n_envs}")
    episodes, n_envs = int(episodes), min(int(n_envs), int(episodes))

    envs = [domain.make_env() for _ in range(n_envs)]
    space = envs[0].action_space
    if isinstance(teacher, str):
        if teacher not in domain.teacher_names:
            raise UnknownNameError(f"teacher for {domain.name}", teacher, domain.teacher_names)
        teacher = domain.make_teacher(teacher, envs[0], seed)
    teacher = as_teacher(teacher, space)
    if success_fn is None:
        success_fn = DEFAULT_SUCCESS.get(domain.name)

    returns = np.zeros(episodes)
    lengths = np.zeros(episodes, dtype=np.int64)
    successes: list[bool | None] = [None] * episodes

    # Slot j of the batch runs episode episode_of[j]; -1 once no episodes are left.
    next_episode = 0
    episode_of = np.full(n_envs, -1)
    obs = [None] * n_envs
    for j, env in enumerate(envs):
        obs[j], _ = env.reset(seed=seed + next_episode)
        episode_of[j] = next_episode
        next_episode += 1
    try:
        while (episode_of >= 0).any():
            active = np.flatnonzero(episode_of >= 0)
            batch = np.stack([obs[j] for j in active])
            actions = check_actions(teacher.name, teacher.predict(batch), space, len(active))
            for j, action in zip(active, actions, strict=True):
                ep = episode_of[j]
                step_action = int(action) if actions.ndim == 1 else action
                obs[j], reward, terminated, truncated, info = envs[j].step(step_action)
                returns[ep] += float(reward)
                lengths[ep] += 1
                if terminated or truncated:
                    if success_fn is not None:
                        successes[ep] = bool(success_fn(float(returns[ep]), info))
                    elif "is_success" in info:
                        successes[ep] = bool(info["is_success"])
                    if next_episode < episodes:
                        obs[j], _ = envs[j].reset(seed=seed + next_episode)
                        episode_of[j] = next_episode
                        next_episode += 1
                    else:
                        episode_of[j] = -1
    finally:
        for env in envs:
            env.close()

    known = [s for s in successes if s is not None]
    return {
        "mean": float(returns.mean()),
        "std": float(returns.std()),
        "success_rate": float(np.mean(known)) if len(known) == episodes else None,
        "episodes": episodes,
        "mean_length": float(lengths.mean()),
        "returns": returns.tolist(),
    }


__all__ = ["DEFAULT_SUCCESS", "measure_teacher"]
