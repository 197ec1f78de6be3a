"""Evaluate a policy alone: the student (the low-level policy without any teacher), what a
user deploys (from Python, while a model learns: :class:`StudentEvalCallback`), and a teacher
on its own (:func:`measure_teacher`: the mean return the paper quotes beside each teacher)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, sync_envs_normalization, unwrap_vec_normalize

from tlac.domains import Domain, domain_names, get_domain
from tlac.errors import ConfigError, UnknownNameError
from tlac.teachers.base import Teacher, as_teacher, check_actions


def evaluate_policy(
    act: Any,
    domain: Domain,
    episodes: int,
    seed: int,
    n_envs: int = 1,
) -> np.ndarray:
    """Run ``act(obs_batch) -> actions`` for ``episodes`` full episodes on fresh environments
    seeded ``seed, seed+1, ...`` and return the undiscounted return of each episode."""
    envs = [domain.make_env() for _ in range(max(1, min(n_envs, episodes)))]
    try:
        return episode_returns(act, envs, episodes, seed)
    finally:
        for env in envs:
            env.close()


def episode_returns(act: Any, envs: list[gym.Env], episodes: int, seed: int) -> np.ndarray:
    """:func:`evaluate_policy` on the environments ``envs``, which it leaves open."""
    returns: list[float] = []
    next_seed = seed
    obs, live, acc = [], [], []
    for env in envs:
        o, _ = env.reset(seed=next_seed)
        next_seed += 1
        obs.append(o)
        live.append(True)
        acc.append(0.0)
    started = len(envs)
    while any(live):
        idx = [i for i, alive in enumerate(live) if alive]
        actions = np.asarray(act(np.stack([obs[i] for i in idx])))
        for a, i in zip(actions, idx, strict=True):
            o, r, terminated, truncated, _ = envs[i].step(a)
            acc[i] += float(r)
            obs[i] = o
            if terminated or truncated:
                returns.append(acc[i])
                acc[i] = 0.0
                if started < episodes:
                    obs[i], _ = envs[i].reset(seed=next_seed)
                    next_seed += 1
                    started += 1
                else:
                    live[i] = False
    return np.asarray(returns[:episodes], dtype=np.float64)


@contextmanager
def sampling_apart(model: Any, seed: int) -> Iterator[None]:
    """Within the block, ``model.predict(..., deterministic=False)`` samples from generators
    seeded ``seed``, and the model's own are as before afterwards: a sampled evaluation is
    reproducible and leaves training untouched. A tlac model samples from its NumPy acting
    generator (``model.rng``), an SB3 model from torch's."""
    import torch

    rng = getattr(model, "rng", None)
    saved = rng.bit_generator.state if isinstance(rng, np.random.Generator) else None
    with torch.random.fork_rng(devices=[]):  # the CPU generator, restored on leaving
        torch.random.default_generator.manual_seed(seed)  # not the GPUs' (manual_seed's)
        if saved is not None:
            rng.bit_generator.state = np.random.default_rng(seed).bit_generator.state
        try:
            yield
        finally:
            if saved is not None:
                rng.bit_generator.state = saved


def evaluate_student(
    model: Any, domain: Domain, episodes: int, seed: int, deterministic: bool = True
) -> np.ndarray:
    """Returns of ``model.predict`` alone (no teacher) over ``episodes`` episodes seeded
    ``seed, seed + 1, ...``; sampled actions (``deterministic=False``) are drawn apart from the
    model's generators (:func:`sampling_apart`), seeded ``seed``."""
    with draws_apart(model, seed, deterministic):
        return evaluate_policy(
            lambda o: model.predict(o, deterministic=deterministic)[0], domain, episodes, seed
        )


def draws_apart(model: Any, seed: int, deterministic: bool) -> AbstractContextManager[Any]:
    """:func:`sampling_apart` where the actions are sampled; nothing where they are greedy
    (greedy actions draw nothing)."""
    return nullcontext() if deterministic else sampling_apart(model, seed)


class StudentEvalCallback(BaseCallback):
    """SB3 callback that evaluates the student alone (``model.predict``, no teacher) every
    ``eval_freq`` environment steps (over all environments, as ``tlac train --eval-every``;
    SB3's ``EvalCallback`` counts steps per environment) on ``n_eval_episodes`` episodes of
    ``eval_env`` (a ``gymnasium.Env``, an SB3 ``VecEnv``, a Gymnasium id or a domain name), and
    logs ``eval/student_alone_mean`` and ``eval/student_alone_std`` to the model's logger, which
    writes them where ``verbose``, ``tensorboard_log`` or ``set_logger`` say. The episodes are
    seeded ``seed, seed + 1, ...`` at every evaluation (default ``10_000 + model.seed``, as
    ``tlac train``'s); the student is evaluated after the update that reaches each multiple of
    ``eval_freq`` (greedy unless ``deterministic=False``), on observations normalised by the
    model's ``VecNormalize`` when it trains under one. A ``VecEnv`` is evaluated as SB3's
    ``evaluate_policy`` does (:func:`vec_episode_returns`); a ``VecNormalize`` in it gets the
    training one's statistics first, as ``EvalCallback`` syncs them. Training is unchanged:
    the evaluation steps its own environment, and sampled actions come from generators seeded
    with the episodes' first seed (:func:`sampling_apart`), the model's own restored after.
    ``evaluations``: every ``(timestep, mean, std)``.

    >>> from tlac import TLAC
    >>> model = TLAC("CartPole-v1", teachers=lambda obs: 0)  # doctest: +SKIP
    >>> callback = StudentEvalCallback("CartPole-v1", eval_freq=5_000)  # doctest: +SKIP
    >>> model.learn(20_000, callback=callback)  # doctest: +SKIP
    """

    def __init__(
        self,
        eval_env: Any,
        eval_freq: int = 10_000,
        n_eval_episodes: int = 10,
        deterministic: bool = True,
        seed: int | None = None,
        verbose: int = 0,
    ):
        super().__init__(verbose)
        for name, value, least in (
            ("eval_freq", eval_freq, 1),
            ("n_eval_episodes", n_eval_episodes, 1),
        ):
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ConfigError(
                    f"StudentEvalCallback: {name} must be a positive integer, got {value!r}"
                )
        self.eval_env = _one_env(eval_env)
        self.eval_freq, self.n_eval_episodes = eval_freq, n_eval_episodes
        self.deterministic, self.seed = bool(deterministic), seed
        self.evaluations: list[tuple[int, float, float]] = []
        self._next_eval = eval_freq

    def _init_callback(self) -> None:
        steps = self.model.num_timesteps
        self._next_eval = (steps // self.eval_freq + 1) * self.eval_freq

    def _on_step(self) -> bool:
        return True

    def _on_rollout_start(self) -> None:  # after the previous rollout's update
        self._evaluate_if_due()

    def _on_training_end(self) -> None:  # after the last update
        self._evaluate_if_due()

    def _evaluate_if_due(self) -> None:
        steps = self.model.num_timesteps
        if steps < self._next_eval:
            return
        self._next_eval = (steps // self.eval_freq + 1) * self.eval_freq
        returns = self._returns()
        mean, std = float(returns.mean()), float(returns.std())
        self.evaluations.append((steps, mean, std))
        self.logger.record("eval/student_alone_mean", mean)
        self.logger.record("eval/student_alone_std", std)
        self.logger.dump(steps)
        if self.verbose:
            print(f"step {steps}: student alone {mean:.3f} +- {std:.3f} ({len(returns)} episodes)")

    def _returns(self) -> np.ndarray:
        """The student's returns on ``n_eval_episodes`` episodes of the evaluation
        environment, on the observations it sees in training."""
        vec_normalize = self.model.get_vec_normalize_env()
        if isinstance(self.eval_env, VecEnv) and unwrap_vec_normalize(self.eval_env) is not None:
            if vec_normalize is not None:  # its statistics, as EvalCallback syncs them
                sync_envs_normalization(self.model.get_env(), self.eval_env)
            vec_normalize = None  # the evaluation environment normalises its observations

        def act(obs: Any) -> np.ndarray:
            if vec_normalize is not None:  # what the student sees in training
                obs = vec_normalize.normalize_obs(obs)
            return self.model.predict(obs, deterministic=self.deterministic)[0]

        seed = 10_000 + int(self.model.seed) if self.seed is None else self.seed
        with draws_apart(self.model, seed, self.deterministic):
            if isinstance(self.eval_env, VecEnv):
                return vec_episode_returns(act, self.eval_env, self.n_eval_episodes, seed)
            return episode_returns(act, [self.eval_env], self.n_eval_episodes, seed)


def vec_episode_returns(act: Any, venv: VecEnv, episodes: int, seed: int) -> np.ndarray:
    """:func:`episode_returns` on an SB3 ``VecEnv`` (seeded ``seed + i`` per environment, then
    reset), as SB3's ``evaluate_policy`` counts them: environment ``i`` plays
    ``(episodes + i) // num_envs`` episodes, so that short episodes do not crowd out long ones.
    An episode's return is its ``Monitor`` record where the environment has one, else the sum
    of its rewards (before a ``VecNormalize`` scaled them)."""
    n = venv.num_envs
    targets = np.array([(episodes + i) // n for i in range(n)])
    counts, running = np.zeros(n, dtype=int), np.zeros(n)
    vec_normalize = unwrap_vec_normalize(venv)
    returns: list[float] = []
    venv.seed(seed)
    obs = venv.reset()
    while (counts < targets).any():
        obs, rewards, dones, infos = venv.step(np.asarray(act(obs)))
        if vec_normalize is not None:
            rewards = vec_normalize.get_original_reward()
        running += rewards
        for i in np.flatnonzero(dones):
            if counts[i] < targets[i]:
                episode = infos[i].get("episode")
                returns.append(float(running[i] if episode is None else episode["r"]))
                counts[i] += 1
            running[i] = 0.0
    return np.asarray(returns, dtype=np.float64)


def _one_env(env: Any) -> gym.Env | VecEnv:
    """The evaluation environment of :class:`StudentEvalCallback`: a Gymnasium env or an SB3
    VecEnv as given, or made from a Gymnasium id or a domain name."""
    if isinstance(env, str) and env in domain_names():
        return get_domain(env).make_env()
    if isinstance(env, str) and env in gym.registry:
        return gym.make(env)
    if isinstance(env, str):
        raise ConfigError(
            f"StudentEvalCallback: unknown environment {env!r}; expected a Gymnasium id or a "
            f"domain name ({', '.join(domain_names())})"
        )
    if not isinstance(env, gym.Env | VecEnv):
        raise ConfigError(
            "StudentEvalCallback: eval_env must be a gymnasium.Env, an SB3 VecEnv, a Gymnasium "
            f"id or a domain name, got {type(env).__name__}"
        )
    return env


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
    """Run ``teacher`` alone for ``episodes`` episodes of ``domain``'s environment: the
    paper reports each teacher's average return over 1000 test episodes (appendices A.1.1,
    A.2.1, A.3.1). ``n_envs`` environments are stepped in lock-step, so that batched teachers
    are queried in batches. Episode ``i`` (0-based) is reset with seed ``seed + i``, so the set
    of episodes does not depend on ``n_envs``; a stochastic teacher's own random draws do (they
    come in batches).

    ``domain`` is a :class:`tlac.domains.Domain` or its name; ``teacher`` is a teacher name of
    the domain (built with ``domain.make_teacher(name, env, seed)``) or anything
    :func:`tlac.teachers.base.as_teacher` accepts. Returns a dict with ``mean``, ``std``
    (population std of the episode returns), ``success_rate``, ``episodes``, ``mean_length``
    and ``returns`` (one per episode, in episode order). Success per episode:
    ``success_fn(episode_return, final_info)`` when given; otherwise the domain's rule in
    :data:`DEFAULT_SUCCESS` (DoorKey: return > 0, i.e. the goal was reached, the reward being
    sparse); otherwise ``final_info["is_success"]`` when the environment reports it (Fetch);
    otherwise no success rate (``None``), e.g. Hopper.
    """
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
