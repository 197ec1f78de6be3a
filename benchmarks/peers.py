"""TL-AC against what a user with teachers would pick instead: SB3 PPO alone, behaviour cloning
of the best teacher then PPO fine-tuning ("BC then PPO"), and DAgger with the best teacher.

Per case (an environment of benchmarks/user_envs.py with its teachers, or a DoorKey teacher set
of :data:`DOORKEY_CASES`) and learner, every
``--eval-every`` environment steps the student ALONE is scored greedily on the user suite's
fresh evaluation episodes, and the training wall-clock so far is recorded (evaluation time
excluded). The peers that need one teacher get the best one, chosen by its measured return
(an oracle choice that TL-AC does not need):

- ``tlac``: TL-AC's defaults with all of the case's teachers (``TLAC(env, teachers=...)``);
  ``--tlac-setting KEY=VALUE`` (repeatable) sets a TL-AC setting on top, recorded in its runs.
- ``ppo``: SB3 PPO's defaults, no teachers (on DoorKey: the domain's ``ppo`` preset, Table 5's
  settings without the high level, as every DoorKey PPO of this project).
- ``bc-ppo``: ``--demo-steps`` environment steps of the best teacher's demonstrations, behaviour
  cloning of SB3 PPO's ``MlpPolicy`` on them (maximum likelihood of the teacher's actions,
  ``BC_EPOCHS`` epochs of minibatches of 64), then SB3 PPO fine-tuning from those weights for
  the rest of the budget. The demonstrations count towards the budget.
- ``dagger``: DAgger (Ross et al. 2011) with the best teacher: rounds of 2,048 steps acted by
  the teacher with probability beta and by the student otherwise (per step), beta annealed
  linearly from 1 to 0 over ``DAGGER_RAMPDOWN`` rounds (the schedule of the ``imitation``
  package's DAgger), every visited state labelled with the teacher's action and added to the
  aggregated data set, then 320 minibatches of 64 drawn from it (as many gradient steps as SB3
  PPO's defaults make per rollout) on the same ``MlpPolicy`` (and optimiser) as ``ppo``'s.

With ``--onehot-peers`` (DoorKey only) the peers' networks read MiniGrid's indices one-hot
encoded, as TL-AC's do (:class:`OneHotObs`, tlac.algorithms.encoding), instead of the raw indices
that SB3's ``MlpPolicy`` reads; the teachers still see the raw observations.

Reported per case: the student alone at 1e4 / 2e4 / 5e4 / 1e5 steps (mean +- std over seeds)
beside the training return at the end (the mean of the last :data:`TRAINING_WINDOW` training
episodes: TL-AC's with its teachers acting, DAgger's mixed, PPO's sampled), and per learner
the steps and training seconds until the student alone first reaches 90% of the way from the
random policy to the best final score among the learners (mean over the seeds that reach it;
"never" counts the others); one figure per case (the student alone, and the training return
dashed); and issues 45's and 63's acceptance per case (:func:`acceptance_row`). Every run is a JSON
file under ``--out``/runs (rerunning skips it).

    .venv/bin/python benchmarks/peers.py --cases MountainCar-v0+weak Acrobot-v1+weak --seeds 0 1 2 3 4
    .venv/bin/python benchmarks/peers.py --cases DoorKey+1optimal-2random DoorKey+L-R --seeds 0 1 2
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import user_envs  # (the suites, their teachers and their evaluation episodes)

LEARNERS = ("tlac", "ppo", "bc-ppo", "dagger")
MILESTONES = (10_000, 20_000, 50_000, 100_000)
BC_EPOCHS = 10
DAGGER_ROUND = 2048
DAGGER_RAMPDOWN = 15
MINIBATCH = 64
GRADIENT_STEPS_PER_ROUND = 320  # SB3 PPO's 10 epochs x 2048 / 64

DOORKEY_CASES: dict[str, list[str]] = {
    "DoorKey+1optimal-2random": ["optimal", "random", "random"],
    "DoorKey+3noisy": ["ppo-noisy20", "ppo-noisy20", "ppo-noisy20"],
    "DoorKey+L-R": ["ppo-L", "ppo-R"],
}
"""DoorKey 7x7 cases (issue 45): the domain's named teachers (the planner and random ones, and
those derived from the shipped PPO agent as the paper's studies use them), TL-AC with the
domain's preset, PPO with its ``ppo`` preset."""
CASES = [*user_envs.SUITE, *DOORKEY_CASES]


# ------------------------------------------------------------------ the cases
def is_doorkey(case: str) -> bool:
    """A DoorKey case, or tlac's DoorKey domain by the name the teacher sweep gives it."""
    return case == "DoorKey" or case in DOORKEY_CASES


def make_env(case: str) -> Any:
    """A fresh environment of the case (DoorKey: the domain's, with its time limit)."""
    if is_doorkey(case):
        from tlac.domains import get_domain

        return get_domain("doorkey").make_env()
    return gym.make(user_envs.gym_id(case))


Encode = Callable[[np.ndarray], np.ndarray]


def peer_view(case: str, onehot: bool) -> Encode | None:
    """What the peers' networks read of a batch of raw observations: None for the raw
    observations, or (``onehot``) the one-hot encoding of TL-AC's ``obs_encoding: auto``."""
    if not onehot:
        return None
    from tlac.algorithms.encoding import make_encoder

    encoder = make_encoder("onehot", make_env(case).observation_space)
    assert encoder is not None
    return lambda batch: encoder.numpy(np.asarray(batch).reshape(len(batch), -1))


def peer_env(env: Any, view: Encode | None) -> Any:
    """The environment a peer's SB3 model is built on and trained in: ``env``, its
    observations as ``view`` makes them (:class:`OneHotObs`)."""
    return env if view is None else OneHotObs(env, view)


class OneHotObs(gym.ObservationWrapper):
    """``env`` whose observations are ``view`` of its raw ones (a flat float32 Box)."""

    def __init__(self, env: Any, view: Encode):
        super().__init__(env)
        self.view = view
        width = view(env.observation_space.sample()[None]).shape[1]
        self.observation_space = gym.spaces.Box(0.0, 1.0, (width,), np.float32)

    def observation(self, observation: Any) -> np.ndarray:
        return self.view(np.asarray(observation)[None])[0]


def make_teachers(case: str, seed: int, env: Any) -> list[Any]:
    """The case's teachers as batched tlac teachers (``.name``, ``.predict(batch)``)."""
    if is_doorkey(case):
        from tlac.domains import get_domain
        from tlac.domains import make_teachers as domain_teachers

        return domain_teachers(get_domain("doorkey"), DOORKEY_CASES[case], env, seed)
    from tlac.teachers.base import as_teacher

    space = env.action_space
    return [as_teacher(t, space) for t in user_envs.SUITE[case](seed, space)]


def evaluate(
    act_batch: Callable[[np.ndarray], Any],
    case: str,
    episodes: int,
    seed: int = user_envs.EVAL_SEED,
) -> np.ndarray:
    """The returns of ``act_batch`` over the case's fixed evaluation episodes (seeded
    ``seed``, ``seed + 1``, ...: user_envs.EVAL_SEED unless given)."""
    if not is_doorkey(case):
        return user_envs.evaluate(act_batch, case, episodes, seed)
    from tlac.domains import get_domain
    from tlac.evaluation import evaluate_policy

    return evaluate_policy(act_batch, get_domain("doorkey"), episodes, seed)


def reference_returns(case: str, episodes: int) -> dict[str, Any]:
    """Each teacher's own return and the uniformly random policy's."""
    if not is_doorkey(case):
        return user_envs.reference_returns(case, episodes)
    env = make_env(case)
    out: dict[str, Any] = {"env": case, "teachers": {}}
    for teacher in make_teachers(case, 0, env):
        out["teachers"][teacher.name] = float(evaluate(teacher.predict, case, episodes).mean())
    rng = np.random.default_rng(12345)
    uniform = lambda batch: rng.integers(env.action_space.n, size=len(batch))  # noqa: E731
    out["random_policy"] = float(evaluate(uniform, case, episodes).mean())
    return out


def make_ppo(case: str, env: Any, seed: int) -> Any:
    """SB3 PPO for the case: its defaults, or DoorKey's ``ppo`` preset."""
    from stable_baselines3 import PPO

    settings: dict[str, Any] = {}
    if is_doorkey(case):
        from tlac.baselines.sb3_baselines import sb3_kwargs
        from tlac.presets import load_preset

        preset = load_preset("doorkey", "ppo")
        preset.pop("n_envs")
        settings = sb3_kwargs("ppo", preset)
    return PPO("MlpPolicy", env, seed=seed, device="cpu", **settings)


# ------------------------------------------------------------------ measuring
TRAINING_WINDOW = 20
"""Training episodes a point's training return averages (the most recent ones ended), as
TL-AC's episode recorder keeps them."""


def recent_mean(returns: Iterable[float]) -> float | None:
    """The mean of the last :data:`TRAINING_WINDOW` of ``returns`` (None: no episode yet).

    >>> recent_mean([]) is None, recent_mean(range(30))
    (True, 19.5)
    """
    last = list(returns)[-TRAINING_WINDOW:]
    return float(np.mean(last)) if last else None


class Curve:
    """The student alone every ``every`` steps, with the training seconds spent so far and
    the training return: how the learner's own training episodes went (TL-AC's with its
    teachers, DAgger's with the teacher acting by beta, BC's demonstrations, PPO's sampled)."""

    def __init__(self, case: str, every: int, episodes: int):
        self.case, self.every, self.episodes = case, every, episodes
        self.next = every
        # [steps, student alone, training seconds, training return (None: no episode yet),
        #  training CPU seconds of this process (runs from 2026-11-29 on)]
        self.points: list[list[Any]] = []
        self.eval_seconds = self.eval_cpu = 0.0
        self.start, self.cpu_start = time.perf_counter(), time.process_time()

    def due(self, steps: int) -> bool:
        return steps >= self.next

    def record(
        self, steps: int, act_batch: Callable[[np.ndarray], Any], training: Iterable[float]
    ) -> None:
        """Score the student now (greedy), beside the training episodes' returns so far
        (``training``, oldest first), and move the next evaluation past ``steps``."""
        t0, c0 = time.perf_counter(), time.process_time()
        score = float(evaluate(act_batch, self.case, self.episodes).mean())
        self.eval_seconds += time.perf_counter() - t0
        self.eval_cpu += time.process_time() - c0
        train_seconds = time.perf_counter() - self.start - self.eval_seconds
        # the CPU seconds do not count what other work on the machine took (the wall clock
        # does): the time measure of runs made side by side
        train_cpu = time.process_time() - self.cpu_start - self.eval_cpu
        self.points.append(
            [int(steps), score, round(train_seconds, 2), recent_mean(training), round(train_cpu, 2)]
        )
        while self.next <= steps:
            self.next += self.every


def greedy(policy: Any, view: Encode | None = None) -> Callable[[np.ndarray], Any]:
    """The greedy action of an SB3 policy (or model) for a batch of raw observations (that it
    reads as ``view`` makes them, if given)."""
    if view is None:
        return lambda batch: policy.predict(batch, deterministic=True)[0]
    return lambda batch: policy.predict(view(batch), deterministic=True)[0]


def sampled(policy: Any) -> Callable[[np.ndarray], Any]:
    """The actions an SB3 or tlac policy samples (``predict``'s default), for a batch."""
    return lambda batch: policy.predict(batch, deterministic=False)[0]


SELECT_SEED = 20_000
"""Seeds of the episodes that choose how a student is deployed (:func:`deployed_alone`), never
the final ones (user_envs.EVAL_SEED, ...): the best of two scores overstates the one chosen."""


def mode_scores(
    modes: dict[str, Callable[[np.ndarray], Any]], case: str, episodes: int, seed: int
) -> dict[str, float]:
    """Each way of acting's mean return over ``episodes`` episodes seeded ``seed``, ....
    What an SB3 policy samples comes from torch's generator, forked here and seeded with
    ``seed``; a tlac model samples from its own acting generator (NumPy), whose state after
    training the run's seed fixes. Either way the scores are reproducible, and, made after
    training, they change nothing of it."""
    import torch

    scores = {}
    for mode, act in modes.items():
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            scores[mode] = float(evaluate(act, case, episodes, seed).mean())
    return scores


def deployed_alone(
    modes: dict[str, Callable[[np.ndarray], Any]], case: str, episodes: int
) -> dict[str, Any]:
    """The student alone as deployed: with one way of acting, its score on the final episodes;
    with several (greedy first, then sampled), the one that scores highest on the selection
    episodes (the first of equal scores), scored again on the final ones, beside every way's
    scores on both."""
    final = mode_scores(modes, case, episodes, user_envs.EVAL_SEED)
    if len(final) == 1:
        return {"student_alone": next(iter(final.values()))}
    selection = mode_scores(modes, case, episodes, SELECT_SEED)
    mode = max(selection, key=selection.__getitem__)
    return {
        "student_alone": final[mode],
        "deployed": mode,
        "selection": selection,
        "alone_by_mode": final,
    }


def deployed_note(runs: list[dict]) -> str:
    """How many of the runs deployed the sampled student (where they could choose).

    >>> deployed_note([{"deployed": "sampled"}, {"deployed": "greedy"}]), deployed_note([{}])
    (' (sampled in 1 of 2)', '')
    """
    chose = [r["deployed"] for r in runs if "deployed" in r]
    return f" (sampled in {chose.count('sampled')} of {len(chose)})" if chose else ""


def best_teacher_name(reference: dict[str, Any]) -> str:
    """The teacher with the best measured return (:func:`reference_returns`): the
    oracle choice of the single-teacher peers."""
    names = list(reference["teachers"])
    return names[int(np.argmax([reference["teachers"][n] for n in names]))]


def best_teacher(case: str, env: Any, seed: int, name: str) -> Any:
    """The case's teacher called ``name``, as a batched tlac teacher."""
    for teacher in make_teachers(case, seed, env):
        if teacher.name == name:
            return teacher
    raise LookupError(f"{case}: no teacher named {name!r}")


# ------------------------------------------------------------------ the learners
def sb3_milestone_callback(curve: Curve, offset: int = 0, view: Encode | None = None) -> Any:
    """An SB3 callback that records ``curve`` when due (``offset``: steps spent before PPO;
    ``view``: what the model reads of raw observations)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Milestones(BaseCallback):
        def _on_step(self) -> bool:
            steps = offset + self.num_timesteps
            if curve.due(steps):
                training = [info["r"] for info in self.model.ep_info_buffer]
                curve.record(steps, greedy(self.model, view), training)
            return True

    return Milestones()


def train_tlac(
    case: str, seed: int, steps: int, curve: Curve, settings: dict[str, Any] | None = None
) -> None:
    """TL-AC with its default (the case's preset), ``settings`` on top (``--tlac-setting``)."""
    from tlac import TLAC
    from tlac.recording import find_episode_recorder

    settings = settings or {}
    if is_doorkey(case):  # the named domain: its preset, its teachers by name
        model = TLAC("doorkey", teachers=DOORKEY_CASES[case], seed=seed, **settings)
    else:
        env = make_env(case)
        teachers = user_envs.SUITE[case](seed, env.action_space)
        model = TLAC(env, teachers=teachers, seed=seed, **settings)

    def after_update(m: Any) -> bool:
        if curve.due(m.num_timesteps):  # the training episodes: teachers included
            curve.record(m.num_timesteps, greedy(m), find_episode_recorder(m.env).episode_returns)
        return True

    model.learn(steps, callback=after_update)


def train_ppo(case: str, seed: int, steps: int, curve: Curve, view: Encode | None) -> Any:
    """SB3 PPO alone on the case, its curve recorded; returns the trained model."""
    model = make_ppo(case, peer_env(make_env(case), view), seed)
    model.learn(steps, callback=sb3_milestone_callback(curve, view=view))
    return model


def demonstrations(
    env: Any, teacher: Any, n: int, seed: int
) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """``n`` steps of the teacher acting alone: (observations, its actions, the returns of the
    episodes that ended within them)."""
    obs_rows, action_rows, returns = [], [], []
    obs, _ = env.reset(seed=seed)
    episode_return = 0.0
    for _ in range(n):
        action = np.asarray(teacher.predict(obs[None]))[0]
        obs_rows.append(obs)
        action_rows.append(action)
        obs, reward, terminated, truncated, _ = env.step(action)
        episode_return += float(reward)
        if terminated or truncated:
            returns.append(episode_return)
            episode_return = 0.0
            obs, _ = env.reset()
    return np.asarray(obs_rows), np.asarray(action_rows), returns


def clone_steps(
    policy: Any,
    obs: np.ndarray,
    actions: np.ndarray,
    n: int,
    rng: Any,
    view: Encode | None = None,
) -> None:
    """``n`` gradient steps of maximum likelihood of ``actions`` under the SB3 policy's actor
    (minibatches of MINIBATCH rows drawn uniformly, read as ``view`` makes them), with the
    policy's own optimizer."""
    import torch

    if view is None:  # the whole data set as one tensor, indexed per minibatch
        obs_t = torch.as_tensor(obs, dtype=torch.float32)
        rows_of = lambda idx: obs_t[idx]  # noqa: E731
    else:  # only the minibatch's rows are encoded
        rows_of = lambda idx: torch.as_tensor(view(obs[idx.numpy()]))  # noqa: E731
    actions_t = torch.as_tensor(actions)
    policy.set_training_mode(True)
    for _ in range(n):
        idx = torch.as_tensor(rng.integers(len(obs), size=MINIBATCH))
        _, log_prob, _ = policy.evaluate_actions(rows_of(idx), actions_t[idx])
        loss = -log_prob.mean()
        policy.optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
        policy.optimizer.step()
    policy.set_training_mode(False)


def train_bc_ppo(
    case: str,
    seed: int,
    steps: int,
    curve: Curve,
    teacher_name: str,
    demo_steps: int,
    view: Encode | None,
) -> None:
    env = make_env(case)
    model = make_ppo(case, peer_env(env, view), seed)
    teacher = best_teacher(case, env, seed, teacher_name)
    obs, actions, demo_returns = demonstrations(make_env(case), teacher, demo_steps, seed)
    rng = np.random.default_rng(seed)
    clone_steps(model.policy, obs, actions, BC_EPOCHS * len(obs) // MINIBATCH, rng, view)
    curve.record(demo_steps, greedy(model, view), demo_returns)  # the teacher's episodes
    model.learn(steps - demo_steps, callback=sb3_milestone_callback(curve, demo_steps, view))


def train_dagger(
    case: str, seed: int, steps: int, curve: Curve, teacher_name: str, view: Encode | None
) -> None:
    env = make_env(case)
    policy = make_ppo(case, peer_env(env, view), seed).policy  # PPO's network and optimiser
    teacher = best_teacher(case, env, seed, teacher_name)
    rng = np.random.default_rng([seed, 0xDA])
    data_obs: list[np.ndarray] = []
    data_actions: list[np.ndarray] = []
    obs, _ = env.reset(seed=seed)
    done_steps, round_index = 0, 0
    episode_return, returns = 0.0, []  # the training episodes (teacher and student mixed)
    while done_steps < steps:
        beta = max(0.0, 1.0 - round_index / DAGGER_RAMPDOWN)
        for _ in range(min(DAGGER_ROUND, steps - done_steps)):
            label = np.asarray(teacher.predict(obs[None]))[0]
            data_obs.append(obs)
            data_actions.append(label)
            if rng.random() < beta:
                act = label
            else:
                seen = obs if view is None else view(obs[None])[0]
                act = policy.predict(seen, deterministic=False)[0]
            obs, reward, terminated, truncated, _ = env.step(act)
            episode_return += float(reward)
            if terminated or truncated:
                returns.append(episode_return)
                episode_return = 0.0
                obs, _ = env.reset()
            done_steps += 1
        clone_steps(
            policy,
            np.asarray(data_obs),
            np.asarray(data_actions),
            GRADIENT_STEPS_PER_ROUND,
            rng,
            view,
        )
        round_index += 1
        if curve.due(done_steps) or done_steps >= steps:
            curve.record(done_steps, greedy(policy, view), returns)


def warm_up() -> None:
    """Once per worker process, before its first run: import the learners' libraries and build
    one throwaway TL-AC and SB3 PPO model. Else the first run of each worker counted those
    one-time costs (torch's import 2.2 s, the first model 1.8 s on this project's machine) in
    its training seconds, as long as TL-AC's first 2,048 steps."""
    from stable_baselines3 import PPO

    from tlac import TLAC

    env = gym.make("CartPole-v1")
    TLAC(env, teachers=[lambda obs: 0], seed=0)
    PPO("MlpPolicy", env, seed=0, device="cpu")


def train_one(
    case: str, learner: str, seed: int, args: argparse.Namespace, teacher_name: str
) -> dict[str, Any]:
    import torch

    torch.set_num_threads(1)
    torch.manual_seed(seed)
    steps = args.steps
    curve = Curve(case, args.eval_every, args.episodes)
    view = peer_view(case, args.onehot_peers)
    settings = user_envs.parse_settings(args.tlac_setting)
    if learner == "tlac":
        train_tlac(case, seed, steps, curve, settings)
    elif learner == "ppo":
        train_ppo(case, seed, steps, curve, view)
    elif learner == "bc-ppo":
        train_bc_ppo(case, seed, steps, curve, teacher_name, args.demo_steps, view)
    else:
        train_dagger(case, seed, steps, curve, teacher_name, view)
    result = {"case": case, "learner": learner, "seed": seed, "steps": steps, "curve": curve.points}
    if learner in ("bc-ppo", "dagger"):
        result["teacher"] = teacher_name
    if learner == "tlac" and settings:
        result["settings"] = settings
    if learner != "tlac" and view is not None:
        result["observations"] = "onehot"
    return result


# ------------------------------------------------------------------ the report
def point_at(curve: list[list[Any]], step: int) -> list[Any]:
    """The last evaluation at or before ``step`` (within one rollout after it: TL-AC's and
    DAgger's evaluations fall at the end of their 2,048-step rollouts); [] if none yet."""
    before = [p for p in curve if p[0] <= step + DAGGER_ROUND]
    return before[-1] if before else []


def score_at(curve: list[list[float]], step: int) -> float:
    """The student alone at the last evaluation at or before ``step`` (NaN: none yet)."""
    point = point_at(curve, step)
    return point[1] if point else float("nan")


def training_at(curve: list[list[Any]], step: int) -> float:
    """The training return at the last evaluation at or before ``step`` (NaN: none recorded,
    as in runs made before 2026-11-28, or no training episode ended yet)."""
    point = point_at(curve, step)
    return float("nan") if len(point) < 4 or point[3] is None else float(point[3])


def training_at_end(run: dict) -> float:
    """The training return at the run's last evaluation (:func:`training_at`)."""
    return training_at(run["curve"], run["steps"])


def first_reach_point(curve: list[list[Any]], threshold: float) -> list[Any] | None:
    """The first evaluation (a :class:`Curve` point) at or above ``threshold``."""
    return next((point for point in curve if point[1] >= threshold), None)


def first_reach(curve: list[list[float]], threshold: float) -> tuple[float, float] | None:
    """(steps, training seconds) of the first evaluation at or above ``threshold``."""
    point = first_reach_point(curve, threshold)
    return None if point is None else (point[0], point[2])


def _mean_std(values: list[float | None], decimals: int = 1) -> str:
    """``mean +- std`` of the values that are numbers (None: a run with no episode yet, as
    :func:`recent_mean` gives it; NaN), ``-`` if none is.

    >>> _mean_std([0.0, None, float("nan"), 2.0]), _mean_std([None])
    ('1.0 +- 1.0', '-')
    """
    values = [v for v in values if v is not None and np.isfinite(v)]
    return f"{np.mean(values):.{decimals}f} +- {np.std(values):.{decimals}f}" if values else "-"


def finals_and_threshold(
    runs: dict[str, list[dict]], random_policy: float
) -> tuple[dict[str, float], float]:
    """Each learner's student alone at the end (seed mean), and 90% of the way from the random
    policy to the best of them."""
    finals = {
        lr: float(np.mean([score_at(r["curve"], r["steps"]) for r in rs]))
        for lr, rs in runs.items()
    }
    return finals, random_policy + 0.9 * (max(finals.values()) - random_policy)


def case_table(case: str, runs: dict[str, list[dict]], random_policy: float) -> list[str]:
    """The rows of one case: student alone at the milestones, the training return at the end,
    steps/seconds to 90%."""
    finals, threshold = finals_and_threshold(runs, random_policy)
    best = max(finals.values())
    d = 3 if is_doorkey(case) else 1  # DoorKey's returns lie in [0, 1]
    rows = []
    for learner, rs in runs.items():
        cells = [_mean_std([score_at(r["curve"], m) for r in rs], d) for m in MILESTONES]
        cells.append(_mean_std([training_at_end(r) for r in rs], d))
        reached = [first_reach(r["curve"], threshold) for r in rs]
        hit = [x for x in reached if x is not None]
        never = len(reached) - len(hit)
        to_steps = f"{np.mean([h[0] for h in hit]):.0f}" if hit else "never"
        to_secs = f"{np.mean([h[1] for h in hit]):.0f}" if hit else "never"
        if hit and never:
            to_steps, to_secs = f"{to_steps} ({never} never)", f"{to_secs} ({never} never)"
        rows.append(
            f"| {case} | {learner} | {len(rs)} | "
            + " | ".join(cells)
            + f" | {to_steps} | {to_secs} |"
        )
    rows.append(
        f"| {case} | (90% of the way from random {random_policy:.{d}f} to the best final "
        f"{best:.{d}f}: {threshold:.{d}f}) | | | | | | | | |"
    )
    return rows


def time_to_ninety(runs: list[dict], threshold: float) -> tuple[int, float]:
    """(seeds that never reach ``threshold``, mean training seconds of those that do; inf if
    none): smaller is sooner, a learner that always gets there before one that sometimes never
    does."""
    hit = [h[1] for h in (first_reach(r["curve"], threshold) for r in runs) if h is not None]
    return len(runs) - len(hit), float(np.mean(hit)) if hit else float("inf")


FIRST_FACTOR = 1.2
"""Issue 63: TL-AC first to 90% of the best final score, or within this many times the first
learner's training seconds."""


def acceptance_row(case: str, runs: dict[str, list[dict]], random_policy: float) -> str:
    """The acceptance for one case. Issue 45's: TL-AC's student alone at the end (seed mean) at
    or above every peer's; TL-AC at 90% of the best final score sooner in training seconds than
    PPO alone and BC then PPO; and within twice DAgger's seconds (:func:`time_to_ninety`).
    Issue 63's: TL-AC first to 90%, or within :data:`FIRST_FACTOR` times the first learner's
    seconds, with no more seeds that never get there."""
    finals, threshold = finals_and_threshold(runs, random_policy)
    d = 3 if is_doorkey(case) else 1
    below = [f"{lr} {finals[lr]:.{d}f}" for lr in finals if finals[lr] > finals["tlac"]]
    cells = [f"yes ({finals['tlac']:.{d}f})" if not below else "no: " + ", ".join(below)]
    ours = time_to_ninety(runs["tlac"], threshold)

    def shown(key: tuple[int, float], decimals: int = 0) -> str:
        seconds = "never" if not np.isfinite(key[1]) else f"{key[1]:.{decimals}f} s"
        return seconds + (f", {key[0]} never" if key[0] and np.isfinite(key[1]) else "")

    def within(theirs: tuple[int, float], factor: float) -> bool:
        sooner = ours[1] < theirs[1] if factor == 1.0 else ours[1] <= factor * theirs[1]
        return bool(np.isfinite(ours[1])) and (
            ours[0] < theirs[0] or (ours[0] == theirs[0] and bool(sooner))
        )

    for peer, factor in (("ppo", 1.0), ("bc-ppo", 1.0), ("dagger", 2.0)):
        if peer not in runs:
            cells.append("-")
            continue
        theirs = time_to_ninety(runs[peer], threshold)
        cells.append(
            f"{'yes' if within(theirs, factor) else 'no'} ({shown(ours)} against {shown(theirs)})"
        )
    times = {lr: time_to_ninety(rs, threshold) for lr, rs in runs.items()}
    first = min(times, key=lambda lr: (times[lr][0], times[lr][1], lr != "tlac"))
    reached = bool(np.isfinite(ours[1]))  # (no learner reaching it makes nobody first)
    ok = reached and (first == "tlac" or within(times[first], FIRST_FACTOR))
    ratio = ours[1] / times[first][1] if reached and times[first][1] > 0 else None
    detail = (
        ("TL-AC first" if reached else "no learner reaches it")
        if first == "tlac"
        else f"{first} first, {shown(times[first], 2)}; TL-AC {shown(ours, 2)}"
        + (f", {ratio:.3f}x" if ratio is not None and ours[0] == times[first][0] else "")
    )
    cells.append(f"{'yes' if ok else 'no'} ({detail})")
    return f"| {case} | " + " | ".join(cells) + " |"


def load_runs(out: Path, case: str) -> dict[str, list[dict]]:
    runs: dict[str, list[dict]] = {}
    for learner in LEARNERS:
        found = sorted((out / "runs").glob(f"{case}__{learner}__seed*.json"))
        if found:
            runs[learner] = [json.loads(p.read_text()) for p in found]
    return runs


def plot_case(out: Path, case: str, runs: dict[str, list[dict]], random_policy: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for learner, rs in runs.items():
        grid = sorted({p[0] for r in rs for p in r["curve"]})
        scores = np.array([[score_at(r["curve"], s) for s in grid] for r in rs])
        mean, std = np.nanmean(scores, 0), np.nanstd(scores, 0)
        (line,) = ax.plot(grid, mean, label=f"{learner}, student alone")
        ax.fill_between(grid, mean - std, mean + std, alpha=0.2)
        training = np.array([[training_at(r["curve"], s) for s in grid] for r in rs])
        if np.isfinite(training).any(axis=0).all():  # runs made before 2026-11-28 have none
            ax.plot(
                grid,
                np.nanmean(training, 0),
                "--",
                color=line.get_color(),
                label=f"{learner}, training",
            )
    ax.axhline(random_policy, color="grey", linestyle=":", label="random policy")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("return (student alone: greedy)")
    ax.set_title(case)
    ax.legend(fontsize=7, ncol=2, loc="lower right")
    fig.tight_layout()
    fig.savefig(out / f"{case}.png", dpi=100)
    plt.close(fig)


def report(out: Path, cases: list[str]) -> str:
    header = (
        "| case | learner | seeds | 1e4 | 2e4 | 5e4 | 1e5 | training return at the end "
        "| steps to 90% | training seconds to 90% |\n"
        "|---|---|---|---|---|---|---|---|---|---|"
    )
    verdicts = [
        "| case | student alone at the end >= every peer | first to 90% (training seconds), "
        "against PPO alone | against BC then PPO | within 2x DAgger "
        "| first, or within 1.2x of the first (issue 63) |",
        "|---|---|---|---|---|---|",
    ]
    lines = [header]
    for case in cases:
        runs = load_runs(out, case)
        if not runs:
            continue
        random_policy = json.loads((out / "reference" / f"{case}.json").read_text())[
            "random_policy"
        ]
        lines += case_table(case, runs, random_policy)
        if "tlac" in runs and len(runs) > 1:
            verdicts.append(acceptance_row(case, runs, random_policy))
        plot_case(out, case, runs, random_policy)
    acceptance = "\n\nIssues 45's and 63's acceptance, per case (seed means):\n\n" + "\n".join(
        verdicts
    )
    return "\n".join(lines) + (acceptance if len(verdicts) > 2 else "") + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", required=True, choices=CASES)
    parser.add_argument("--learners", nargs="+", default=list(LEARNERS), choices=LEARNERS)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--eval-every", type=int, default=10_000)
    parser.add_argument("--episodes", type=int, default=user_envs.EVAL_EPISODES)
    parser.add_argument("--demo-steps", type=int, default=10_000, help="bc-ppo's demonstrations")
    parser.add_argument(
        "--onehot-peers",
        action="store_true",
        help="DoorKey only: the peers' networks read the observations one-hot encoded, as TL-AC's",
    )
    parser.add_argument(
        "--tlac-setting",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a TL-AC setting for every TL-AC run, on top of its preset (repeatable)",
    )
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("results/peers"))
    args = parser.parse_args()
    user_envs.parse_settings(args.tlac_setting)  # a malformed pair stops here, before any run
    if "bc-ppo" in args.learners and not 0 < args.demo_steps < args.steps:
        parser.error(
            f"--demo-steps (bc-ppo's demonstrations) must be between 0 and --steps "
            f"({args.steps}), got {args.demo_steps}"
        )
    if args.onehot_peers and not all(is_doorkey(c) for c in args.cases):
        parser.error(
            "--onehot-peers applies to DoorKey cases only (integer observations), got "
            + " ".join(c for c in args.cases if not is_doorkey(c))
        )
    (args.out / "runs").mkdir(parents=True, exist_ok=True)
    (args.out / "reference").mkdir(parents=True, exist_ok=True)
    for case in args.cases:
        ref_path = args.out / "reference" / f"{case}.json"
        if not ref_path.exists():
            ref_path.write_text(json.dumps(reference_returns(case, 100), indent=1))
    best = {
        case: best_teacher_name(json.loads((args.out / "reference" / f"{case}.json").read_text()))
        for case in args.cases
    }
    todo = [
        (case, learner, seed)
        for seed in args.seeds
        for case in args.cases
        for learner in args.learners
        if not (args.out / "runs" / f"{case}__{learner}__seed{seed}.json").exists()
    ]
    print(f"{len(todo)} runs to do with {args.workers} worker(s) -> {args.out}", flush=True)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    with ProcessPoolExecutor(max_workers=args.workers, initializer=warm_up) as pool:
        futures = {pool.submit(train_one, c, lr, s, args, best[c]): (c, lr, s) for c, lr, s in todo}
        for done, future in enumerate(as_completed(futures), 1):
            case, learner, seed = futures[future]
            result = future.result()
            path = args.out / "runs" / f"{case}__{learner}__seed{seed}.json"
            path.write_text(json.dumps(result, indent=1))
            last = result["curve"][-1]
            print(
                f"[{done}/{len(todo)}] {case} {learner} seed {seed}: student alone {last[1]:.1f} "
                f"at {last[0]} steps ({last[2]:.0f} s of training)",
                flush=True,
            )
    table = report(args.out, args.cases)
    command = shlex.join(["python", "benchmarks/peers.py", *sys.argv[1:]])
    (args.out / "report.md").write_text(f"Made by `{command}`\n\n{table}")
    print(table)


if __name__ == "__main__":
    main()
