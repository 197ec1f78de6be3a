"""The student alone against its teachers' quality (issue 63): teachers can only help.

A user never knows how good their teachers are. This sweep takes, per environment, teachers of
every quality from one learner's own training, and trains TL-AC with its defaults beside SB3 PPO
alone:

1. **Reference** (``--phase reference``): the environment's reference learner (:data:`SWEEP`:
   SB3 PPO; DQN with rl-zoo's settings on MountainCar, where PPO never leaves the random policy's
   level; SAC on Pendulum; on DoorKey PPO on MiniGrid's partial view, as ``tlac teacher train
   doorkey`` trains the paper's teacher) is trained once with seed 0, a checkpoint every
   ``every`` steps and one of the untrained network, and each checkpoint is scored greedily
   (``CHOICE_EPISODES``).
2. **PPO alone** (``--phase ppo``): SB3 PPO's defaults, no teachers, every seed, the student's
   curve (greedy, ``--episodes`` episodes every ``--eval-every`` steps) and its final score
   over user_envs.EVAL_EPISODES episodes.
3. **Teachers** (``--phase teachers``): quality ``q`` is the share of the way from the random
   policy to ``top``: PPO alone's final score at the sweep's budget (seed mean), or the reference
   learner's best checkpoint where that is higher and the reference is not PPO (MountainCar,
   Pendulum: PPO alone stays near the random policy there, and ``q = 1`` must be a teacher worth
   having). The teacher of ``q = 0`` is the untrained network; of 0.25 ... 1.0 the checkpoint
   whose return is nearest ``random + q (top - random)``; the adversarial one (``q < 0``) plays
   the action the ``q = 1`` network ranks worst (:class:`Adversarial`). Each is saved (its
   acting weights only) and scored alone over user_envs.EVAL_EPISODES.
4. **Students** (``--phase students``): TL-AC's defaults, ``TLAC(env, teachers=...)`` (DoorKey:
   ``TLAC("doorkey", ...)``, the domain's preset), for every case of :data:`CASES` (each teacher
   beside a random one; q = 0 and 0.5 also alone), every seed, scored as PPO alone.

Runs are 1e5 steps (DoorKey: 5e5, its curve evaluated five times as far apart).

``--phase all`` runs the four in order; every finished piece is a file under ``--out`` (a rerun
skips it). ``--phase report`` writes ``report.md`` (the acceptance of issue 63 per environment
and case) and ``teacher_sweep.png`` (the student alone against teacher quality, one panel per
environment, PPO alone and the teacher as lines).

    .venv/bin/python benchmarks/teacher_sweep.py --envs Acrobot-v1 CartPole-v1 --seeds 0 1 2 3 4
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers  # (curves, the time to 90%)
import user_envs  # (evaluation episodes, random teachers)


@dataclass(frozen=True)
class Reference:
    """How an environment's reference learner is trained: SB3 ``algo`` with ``kwargs``,
    ``steps`` steps, a checkpoint every ``every`` steps."""

    algo: str
    steps: int
    every: int
    kwargs: dict[str, Any] = field(default_factory=dict)


SWEEP: dict[str, Reference] = {
    "CartPole-v1": Reference("ppo", 100_000, 2048),
    "Acrobot-v1": Reference("ppo", 100_000, 2048),
    "LunarLander-v3": Reference("ppo", 100_000, 2048),
    "MountainCar-v0": Reference(
        "dqn", 120_000, 4000, user_envs.WEAK_TEACHERS["MountainCar-v0"]["kwargs"]
    ),
    "Pendulum-v1": Reference("sac", 20_000, 500),
    # the paper's DoorKey teacher, trained as `tlac teacher train doorkey` trains it (SB3 PPO
    # on MiniGrid's partial view, 8 environments: 1,024 steps a rollout), checkpoints 20 rollouts
    # apart; its teachers advise the student, who sees the full grid, through the view
    "DoorKey": Reference("ppo-partial", 1_000_000, 20_480),
}
DOORKEY = "DoorKey"
"""tlac's DoorKey 7x7 domain (``TLAC("doorkey")``, its preset), at the issue's 5e5 steps."""
QUALITIES = (0.0, 0.25, 0.5, 0.75, 1.0)
TEACHERS = (*(f"q{q:g}" for q in QUALITIES), "adversarial")
CASES = (*(f"{t}+random" for t in TEACHERS), "q0", "q0.5")
"""Each teacher beside a random one; the q = 0 and 0.5 teachers also alone."""
CHOICE_EPISODES = 10
"""Episodes per checkpoint when choosing the teachers (the chosen ones are scored again over
user_envs.EVAL_EPISODES)."""
REFERENCE_SEED = 0
BUDGET = 100_000
BUDGETS = {DOORKEY: 500_000}
"""Steps of a run where not :data:`BUDGET`."""


def budget(env_id: str) -> int:
    return BUDGETS.get(env_id, BUDGET)


def make_env(env_id: str) -> Any:
    """A fresh environment (DoorKey: the domain's, with its time limit)."""
    return peers.make_env(env_id)


# ------------------------------------------------------------------ teachers
def reference_model(env_id: str) -> Any:
    """The untrained reference learner of ``env_id`` (seed REFERENCE_SEED)."""
    from tlac.teachers.sb3 import sb3_class

    spec = SWEEP[env_id]
    if env_id == DOORKEY:
        from stable_baselines3 import PPO
        from stable_baselines3.common.env_util import make_vec_env

        from tlac.domains import get_domain
        from tlac.teacher_training import PPO_ENVS, PPO_HYPERPARAMS

        domain, n_envs = PPO_ENVS["doorkey"]
        vec = make_vec_env(get_domain(domain).make_env, n_envs=n_envs, seed=REFERENCE_SEED)
        return PPO(
            "MlpPolicy", vec, seed=REFERENCE_SEED, device="cpu", **PPO_HYPERPARAMS["doorkey"]
        )
    return sb3_class(spec.algo)(
        "MlpPolicy", gym.make(env_id), seed=REFERENCE_SEED, device="cpu", **spec.kwargs
    )


def acting_state(model: Any) -> dict[str, Any]:
    """The part of an SB3 model's policy that acts (PPO: all of it; DQN: its Q-network, not
    the target; SAC: its actor): what a teacher file holds."""
    keep = {"ppo": "", "dqn": "q_net.", "sac": "actor."}[type(model).__name__.lower()]
    return {k: v for k, v in model.policy.state_dict().items() if k.startswith(keep)}


def load_teacher_model(env_id: str, path: Path) -> Any:
    """A reference learner with the acting weights saved at ``path`` (DoorKey: the PPO actor
    as tlac ships it, a batched greedy teacher that reads the full grid through the partial
    view it was trained on)."""
    import torch

    if env_id == DOORKEY:
        return doorkey_teacher(torch.load(path, weights_only=True))
    model = reference_model(env_id)
    model.policy.load_state_dict(torch.load(path, weights_only=True), strict=False)
    model.policy.set_training_mode(False)
    return model


def doorkey_teacher(policy_state: dict[str, Any]) -> Any:
    """tlac's PPO teacher (:class:`tlac.teachers.ppo.PPOActorTeacher`) from an SB3 PPO policy's
    weights, trained on the partial view."""
    from tlac.domains.doorkey.view import partial_view
    from tlac.teachers.ppo import PPOActor, PPOActorTeacher, ppo_actor_state_dict

    weights = ppo_actor_state_dict(policy_state)
    obs_dim = weights["policy_net.0.weight"].shape[1]
    widths = [
        w.shape[0] for k, w in weights.items() if k.startswith("policy_net.") and "weight" in k
    ]
    actor = PPOActor(obs_dim, weights["action_net.weight"].shape[0], widths)
    actor.load_state_dict(weights)
    return PPOActorTeacher(actor, transform=partial_view)


class Adversarial:
    """The action an SB3 network ranks worst (issue 63's ``q < 0`` teacher): PPO's least likely
    action, DQN's least valued one, and on a Box SAC's greedy action mirrored in the box
    (``low + high - a``)."""

    name = "adversarial"

    def __init__(self, model: Any):
        self.model = model

    def predict(self, obs: np.ndarray) -> np.ndarray:
        import torch

        model, algo = self.model, type(self.model).__name__.lower()
        if algo == "ppoactorteacher":  # DoorKey: the actor's scores on the view it reads
            view = torch.as_tensor(model.transform(np.asarray(obs)), dtype=torch.float32)
            with torch.no_grad():
                return model.actor(view.reshape(len(view), -1)).argmin(dim=1).numpy()
        if algo == "sac":
            space = model.action_space
            return space.low + space.high - model.predict(obs, deterministic=True)[0]
        x = model.policy.obs_to_tensor(np.asarray(obs))[0]
        with torch.no_grad():
            if algo == "dqn":
                scores = model.q_net(x)
            else:
                scores = model.policy.get_distribution(x).distribution.logits
        return scores.argmin(dim=1).numpy()


def greedy_act(model: Any) -> Any:
    """A batch of observations -> the greedy actions of an SB3 model or of a tlac teacher."""
    if type(model).__name__ == "PPOActorTeacher":
        return model.predict
    return lambda batch: model.predict(batch, deterministic=True)[0]


SAMPLED_TOO = frozenset({DOORKEY})
"""Where the student alone may also be deployed sampling its actions (``predict``'s default, as
in SB3): on MiniGrid's partial view a greedy policy walks in loops where a sampled one gets out
(q 0.25 + random, seed 1, 5e5 steps: greedy 0.453, sampled 0.896 on the same 30 episodes;
NOTES.md, "DoorKey: the sampled student"). Elsewhere the sweep deploys the greedy student only,
as its committed runs were scored."""


def deployed_alone(model: Any, env_id: str) -> dict[str, Any]:
    """The student alone as deployed (:func:`peers.deployed_alone`): greedy, or where
    :data:`SAMPLED_TOO` the better of greedy and sampled on the selection episodes."""
    modes = {"greedy": greedy_act(model)}
    if env_id in SAMPLED_TOO:
        modes["sampled"] = peers.sampled(model)
    return peers.deployed_alone(modes, env_id, user_envs.EVAL_EPISODES)


def score(act_batch: Any, env_id: str, episodes: int) -> float:
    return float(peers.evaluate(act_batch, env_id, episodes).mean())


def train_reference(env_id: str, out: Path) -> dict[str, Any]:
    """Train the reference learner with checkpoints under out/checkpoints/ENV (step 0: the
    untrained network) and score each; returns (and writes) reference/ENV.json."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    torch.set_num_threads(1)
    spec = SWEEP[env_id]
    folder = out / "checkpoints" / env_id
    folder.mkdir(parents=True, exist_ok=True)
    model = reference_model(env_id)
    torch.save(acting_state(model), folder / "0.pt")

    class Checkpoints(BaseCallback):  # at a rollout's start: the weights its steps trained
        def _on_rollout_start(self) -> None:
            if self.num_timesteps and self.num_timesteps % spec.every == 0:
                torch.save(acting_state(self.model), folder / f"{self.num_timesteps}.pt")

        def _on_step(self) -> bool:
            return True

    start = time.perf_counter()
    model.learn(spec.steps, callback=Checkpoints())
    torch.save(acting_state(model), folder / f"{model.num_timesteps}.pt")
    seconds = time.perf_counter() - start
    checkpoints = []
    for path in sorted(folder.glob("*.pt"), key=lambda p: int(p.stem)):
        saved = load_teacher_model(env_id, path)
        checkpoints.append([int(path.stem), score(greedy_act(saved), env_id, CHOICE_EPISODES)])
    space = make_env(env_id).action_space
    random_policy = score(
        user_envs.one_by_one(user_envs.random_teacher(space, 12345)),
        env_id,
        user_envs.EVAL_EPISODES,
    )
    record = {
        "env": env_id,
        "algo": spec.algo,
        "seed": REFERENCE_SEED,
        "steps": spec.steps,
        "every": spec.every,
        "kwargs": spec.kwargs,
        "train_seconds": round(seconds, 1),
        "random_policy": random_policy,
        "checkpoints": checkpoints,
    }
    (out / "reference" / f"{env_id}.json").write_text(json.dumps(record, indent=1))
    return record


def needs_reference(out: Path, env_id: str) -> bool:
    """Whether the reference learner must be trained (again): its teachers are not chosen yet
    and its record or its checkpoints are missing (the checkpoints are not committed, so a
    fresh checkout trains it again, on its own CPU, before choosing teachers)."""
    if (out / "teachers" / f"{env_id}.json").exists():
        return False
    folder = out / "checkpoints" / env_id
    has_checkpoints = folder.is_dir() and any(folder.glob("*.pt"))
    return not ((out / "reference" / f"{env_id}.json").exists() and has_checkpoints)


def nearest_checkpoint(checkpoints: list[list[float]], target: float) -> list[float]:
    """The ``[steps, return]`` checkpoint whose return is nearest ``target`` (the earliest on a
    tie).

    >>> nearest_checkpoint([[0, -500.0], [2048, -300.0], [4096, -290.0]], -295.0)
    [2048, -300.0]
    """
    return min(checkpoints, key=lambda c: (abs(c[1] - target), c[0]))


def quality(value: float, random_policy: float, top: float) -> float:
    """How far ``value`` is from the random policy towards ``top`` (0: random, 1: top; NaN
    if ``top`` is no better than random).

    >>> quality(-300.0, -500.0, -100.0)
    0.5
    """
    if top <= random_policy:
        return float("nan")
    return (value - random_policy) / (top - random_policy)


def sweep_top(reference: dict[str, Any], ppo_alone: float) -> float:
    """The score of ``q = 1``: PPO alone's, or the reference learner's best checkpoint where
    the reference is not PPO and does better (see the module docstring).

    >>> sweep_top({"algo": "dqn", "checkpoints": [[0, -200.0], [4000, -120.0]]}, -200.0)
    -120.0
    >>> sweep_top({"algo": "ppo", "checkpoints": [[0, -500.0], [2048, -70.0]]}, -80.0)
    -80.0
    """
    if reference["algo"] == "ppo":
        return ppo_alone
    return max(ppo_alone, max(c[1] for c in reference["checkpoints"]))


def choose_teachers(env_id: str, out: Path, ppo_alone: float) -> dict[str, Any]:
    """Pick and save the sweep's teachers of ``env_id`` (teachers/ENV/NAME.pt) and score each
    alone; returns (and writes) teachers/ENV.json."""
    import shutil

    import torch

    torch.set_num_threads(1)
    if needs_reference(out, env_id):
        raise SystemExit(
            f"{env_id}: the reference learner's checkpoints are missing from "
            f"{out / 'checkpoints' / env_id}; run --phase reference first"
        )
    reference = json.loads((out / "reference" / f"{env_id}.json").read_text())
    random_policy, top = reference["random_policy"], sweep_top(reference, ppo_alone)
    folder = out / "teachers" / env_id
    folder.mkdir(parents=True, exist_ok=True)
    chosen: dict[str, Any] = {}
    for q in QUALITIES:
        target = random_policy + q * (top - random_policy)
        steps = 0 if q == 0 else int(nearest_checkpoint(reference["checkpoints"], target)[0])
        name = f"q{q:g}"
        shutil.copyfile(out / "checkpoints" / env_id / f"{steps}.pt", folder / f"{name}.pt")
        model = load_teacher_model(env_id, folder / f"{name}.pt")
        alone = score(greedy_act(model), env_id, user_envs.EVAL_EPISODES)
        chosen[name] = {"target_q": q, "steps": steps, "alone": alone}
    adversary = Adversarial(load_teacher_model(env_id, folder / "q1.pt"))
    alone = score(adversary.predict, env_id, user_envs.EVAL_EPISODES)
    chosen["adversarial"] = {"target_q": None, "steps": chosen["q1"]["steps"], "alone": alone}
    for info in chosen.values():
        info["q"] = quality(info["alone"], random_policy, top)
    record = {
        "env": env_id,
        "random_policy": random_policy,
        "ppo_alone": ppo_alone,
        "top": top,
        "teachers": chosen,
    }
    (out / "teachers" / f"{env_id}.json").write_text(json.dumps(record, indent=1))
    return record


def case_teachers(env_id: str, case: str, out: Path, seed: int) -> list[Any]:
    """The teachers of a case: the named sweep teacher, with a random one after it if the case
    says ``+random``."""
    name, _, extra = case.partition("+")
    folder = out / "teachers" / env_id
    if name == "adversarial":
        teacher: Any = Adversarial(load_teacher_model(env_id, folder / "q1.pt"))
    else:
        teacher = load_teacher_model(env_id, folder / f"{name}.pt")
    space = make_env(env_id).action_space
    return [teacher, user_envs.random_teacher(space, seed)] if extra == "random" else [teacher]


# ------------------------------------------------------------------ runs
def run_path(out: Path, env_id: str, case: str, seed: int) -> Path:
    return out / "runs" / f"{env_id}__{case}__seed{seed}.json"


def make_learner(env_id: str, case: str, seed: int, out: Path) -> Any:
    """The learner of a run, untrained: ``ppo``, SB3 PPO's defaults (DoorKey: its ``ppo``
    preset, as every DoorKey PPO of this project), or TL-AC's default with the case's teachers
    (DoorKey by its name: the domain's preset, as a user of that domain gets it)."""
    env = make_env(env_id)
    if case == "ppo":
        return peers.make_ppo(env_id, env, seed)
    from tlac import TLAC

    teachers = case_teachers(env_id, case, out, seed)
    return TLAC("doorkey" if env_id == DOORKEY else env, teachers=teachers, seed=seed)


def train_run(
    env_id: str, case: str, seed: int, out: Path, every: int, episodes: int
) -> dict[str, Any]:
    """One run: ``case`` ``ppo`` (SB3 PPO alone) or a teacher case (TL-AC's defaults), with
    its curve and its final student alone over user_envs.EVAL_EPISODES."""
    import torch

    torch.set_num_threads(1)
    torch.manual_seed(seed)
    steps = budget(env_id)
    curve = peers.Curve(env_id, every * steps // BUDGET, episodes)
    model = make_learner(env_id, case, seed, out)
    if case == "ppo":
        model.learn(steps, callback=peers.sb3_milestone_callback(curve))
        training = [info["r"] for info in model.ep_info_buffer]
    else:
        from tlac.recording import find_episode_recorder

        def after_update(m: Any) -> bool:
            if curve.due(m.num_timesteps):
                returns = find_episode_recorder(m.env).episode_returns
                curve.record(m.num_timesteps, peers.greedy(m), returns)
            return True

        model.learn(steps, callback=after_update)
        training = list(find_episode_recorder(model.env).episode_returns)
    return {
        "env": env_id,
        "case": case,
        "seed": seed,
        "steps": steps,
        "curve": curve.points,
        **deployed_alone(model, env_id),
        "training_return": peers.recent_mean(training),
    }


def run_all(todo: list[tuple[str, str, int]], args: argparse.Namespace) -> None:
    """Every ``(env, case, seed)`` of ``todo`` not done yet, ``--workers`` at a time."""
    todo = [t for t in todo if not run_path(args.out, *t).exists()]
    print(f"{len(todo)} runs to do with {args.workers} worker(s) -> {args.out}", flush=True)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    with ProcessPoolExecutor(max_workers=args.workers, initializer=peers.warm_up) as pool:
        futures = {
            pool.submit(train_run, *t, args.out, args.eval_every, args.episodes): t for t in todo
        }
        for done, future in enumerate(as_completed(futures), 1):
            result = future.result()
            run_path(args.out, *futures[future]).write_text(json.dumps(result, indent=1))
            env_id, case, seed = futures[future]
            print(
                f"[{done}/{len(todo)}] {env_id} {case} seed {seed}: student alone "
                f"{result['student_alone']:.1f}",
                flush=True,
            )


def load_run(out: Path, env_id: str, case: str, seeds: list[int]) -> list[dict[str, Any]]:
    paths = [run_path(out, env_id, case, s) for s in seeds]
    return [json.loads(p.read_text()) for p in paths if p.exists()]


def ppo_alone(out: Path, env_id: str, seeds: list[int]) -> float | None:
    """PPO alone's final score (seed mean), None until every seed has run."""
    runs = load_run(out, env_id, "ppo", seeds)
    return float(np.mean([r["student_alone"] for r in runs])) if len(runs) == len(seeds) else None


# ------------------------------------------------------------------ the report
MARGIN = 0.05
"""The acceptance's slack: 5% of PPO alone's margin over the random policy."""
TIME_FACTOR = 1.3
"""With a teacher of q <= 0.25 or an adversarial one, the steps and the seconds to 90% of PPO
alone's final score each at most this many times PPO alone's."""


def floor_of(teacher: float, ppo: float, random_policy: float) -> float:
    """What the student alone must reach: ``max(teacher, PPO alone)`` less 5% of PPO alone's
    margin over random (no slack where PPO alone stays at random, as on MountainCar: the
    teacher, or PPO alone's level if the teacher is below it).

    >>> floor_of(-300.0, -80.0, -500.0), floor_of(-120.0, -200.0, -200.0)
    (-101.0, -120.0)
    """
    return max(teacher, ppo) - MARGIN * max(ppo - random_policy, 0.0)


CURVE_COLUMNS = {"steps": 0, "seconds": 2, "CPU seconds": 4}
"""Where a curve point (benchmarks/peers.py's :class:`peers.Curve`) holds each time measure."""


def reach_time(runs: list[dict], threshold: float, unit: str) -> tuple[int, float]:
    """(seeds that never reach ``threshold``, mean ``unit`` -- :data:`CURVE_COLUMNS`: "steps",
    "seconds" or "CPU seconds" of training -- at which the others first do; inf if none)."""
    column = CURVE_COLUMNS[unit]
    points = (peers.first_reach_point(r["curve"], threshold) for r in runs)
    hits = [p[column] for p in points if p is not None]
    return len(runs) - len(hits), float(np.mean(hits)) if hits else float("inf")


def time_unit(runs: list[dict]) -> str:
    """The seconds the verdict reads: the training process's CPU seconds where every run
    recorded them (runs from 2026-11-29 on: they leave out the other work that shared the
    machine), else the wall clock's."""
    return "CPU seconds" if all(len(p) > 4 for r in runs for p in r["curve"]) else "seconds"


def time_ratio(ours: tuple[int, float], theirs: tuple[int, float]) -> float:
    """TL-AC's mean time to 90% over PPO alone's (:func:`reach_time` pairs): inf if the
    student's seeds reach it less often; 0 if PPO alone's never do and some of TL-AC's do; 1 if
    neither ever does.

    >>> time_ratio((0, 12.0), (0, 10.0)), time_ratio((1, 8.0), (0, 10.0))
    (1.2, inf)
    >>> time_ratio((1, float("inf")), (1, float("inf"))), time_ratio((0, 30.0), (1, float("inf")))
    (1.0, 0.0)
    """
    if ours[0] > theirs[0]:
        return float("inf")
    if not np.isfinite(ours[1]):  # neither reaches it
        return 1.0
    return ours[1] / theirs[1] if np.isfinite(theirs[1]) else 0.0


def time_cell(ours: tuple[int, float], theirs: tuple[int, float], unit: str) -> str:
    """``TL-AC / PPO: ratio`` in ``unit`` as the report shows it.

    >>> time_cell((0, 12.3), (0, 10.0), "s"), time_cell((2, 20.0), (0, 10.0), "steps")
    ('12 s / 10 s: 1.23x', '20 steps (2 never) / 10 steps')
    >>> time_cell((0, float("inf")), (5, float("inf")), "s")
    'never / never'
    """

    def shown(key: tuple[int, float]) -> str:
        if not np.isfinite(key[1]):
            return "never"
        return f"{key[1]:.0f} {unit}" + (f" ({key[0]} never)" if key[0] else "")

    ratio = time_ratio(ours, theirs)
    tail = f": {ratio:.2f}x" if np.isfinite(ratio) and ratio > 0 and np.isfinite(ours[1]) else ""
    return f"{shown(ours)} / {shown(theirs)}{tail}"


def decimals(env_id: str) -> int:
    """The decimals the report gives a return: DoorKey's lie in [0, 1], the others' span
    hundreds.

    >>> decimals("DoorKey"), decimals("Pendulum-v1")
    (3, 1)
    """
    return 3 if env_id == DOORKEY else 1


def env_rows(out: Path, env_id: str, seeds: list[int]) -> tuple[list[str], list[dict]]:
    """The report's rows of one environment and the points of its figure."""
    teachers = json.loads((out / "teachers" / f"{env_id}.json").read_text())
    random_policy, ppo = teachers["random_policy"], teachers["ppo_alone"]
    ppo_runs = load_run(out, env_id, "ppo", seeds)
    threshold = random_policy + 0.9 * (ppo - random_policy)
    rows, points = [], []
    for case in CASES:
        runs = load_run(out, env_id, case, seeds)
        if not runs:
            continue
        name = case.partition("+")[0]
        teacher = teachers["teachers"][name]
        student = [r["student_alone"] for r in runs]
        mean = float(np.mean(student))
        floor = floor_of(teacher["alone"], ppo, random_policy)
        same_seeds = [r for r in ppo_runs if r["seed"] in {run["seed"] for run in runs}]
        timed = name in ("q0", "q0.25", "adversarial")
        reaches = threshold > random_policy + 1e-9
        # judged in steps AND in seconds: the steps leave out TL-AC's cost per step; wall
        # seconds of runs made side by side with other work depend on the load each met, so
        # CPU seconds where every run has them
        seconds = time_unit(runs + same_seeds)
        times = {
            unit: (reach_time(runs, threshold, unit), reach_time(same_seeds, threshold, unit))
            for unit in ("steps", seconds)
        }
        shown = {"seconds": "s", "CPU seconds": "CPU s"}[seconds]
        cell = (
            "-"
            if not reaches
            else time_cell(*times["steps"], "steps") + "; " + time_cell(*times[seconds], shown)
        )
        ratios = [time_ratio(ours, theirs) for ours, theirs in times.values()]
        time_ok = not timed or not reaches or max(ratios) <= TIME_FACTOR
        d = decimals(env_id)
        rows.append(
            f"| {env_id} | {case} | {teacher['q']:.2f} | {teacher['alone']:.{d}f} "
            f"| {len(runs)} | {peers._mean_std(student, d)}{peers.deployed_note(runs)} "
            f"| {peers._mean_std([r['training_return'] for r in runs], d)} "
            f"| {ppo:.{d}f} | {floor:.{d}f} | {'yes' if mean >= floor else 'NO'} "
            f"| {cell} | {('yes' if time_ok else 'NO') if timed else ''} |"
        )
        points.append(
            {
                "case": case,
                "q": teacher["q"],
                "teacher": teacher["alone"],
                "mean": mean,
                "std": float(np.std(student)),
            }
        )
    return rows, points


def plot(out: Path, figures: dict[str, tuple[dict, list[dict]]]) -> None:
    """One panel per environment: the student alone (seed mean +- std) against its teacher's
    measured quality, beside a random teacher (line), alone (open squares) or adversarial (x),
    with PPO alone and the teacher's own return."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(figures), figsize=(4 * len(figures), 3.6), squeeze=False)
    for ax, (env_id, (teachers, points)) in zip(axes[0], figures.items(), strict=True):
        kinds = {  # which points, how drawn, their label
            "teacher + random": (lambda c: "+" in c and not c.startswith("adv"), "o-", None),
            "its one teacher": (lambda c: "+" not in c, "s", "white"),
            "adversarial + random": (lambda c: c.startswith("adv"), "x", None),
        }
        for label, (member, fmt, face) in kinds.items():
            pts = sorted((p for p in points if member(p["case"])), key=lambda p: p["q"])
            if pts:
                ax.errorbar(
                    [p["q"] for p in pts],
                    [p["mean"] for p in pts],
                    yerr=[p["std"] for p in pts],
                    fmt=fmt,
                    mfc=face,
                    capsize=3,
                    label=f"student alone: {label}",
                )
        qs = sorted(t["q"] for t in teachers["teachers"].values())
        ax.plot(
            qs,
            [
                teachers["random_policy"] + q * (teachers["top"] - teachers["random_policy"])
                for q in qs
            ],
            ":",
            color="grey",
            label="the teacher alone",
        )
        ax.axhline(teachers["ppo_alone"], color="black", linestyle="--", label="PPO alone")
        ax.set_title(env_id)
        ax.set_xlabel("teacher quality q (0: random policy, 1: top)")
        ax.set_ylabel(f"return at {budget(env_id):.0e} steps (greedy)".replace("e+0", "e"))
    axes[0][0].legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(out / "teacher_sweep.png", dpi=90)
    plt.close(fig)


def report(out: Path, envs: list[str], seeds: list[int]) -> str:
    header = [
        "| environment | case | teacher q | teacher alone | seeds | student alone "
        "| training return | PPO alone | must reach | student >= | steps; seconds (CPU s: the "
        "training process's CPU seconds, where every run has them) to 90% of "
        f"PPO alone, TL-AC / PPO (same seeds) | <= {TIME_FACTOR}x (q <= 0.25, adversarial) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    rows, figures = [], {}
    for env_id in envs:
        if not (out / "teachers" / f"{env_id}.json").exists():
            continue
        env_lines, points = env_rows(out, env_id, seeds)
        rows += env_lines
        if points:
            figures[env_id] = (
                json.loads((out / "teachers" / f"{env_id}.json").read_text()),
                points,
            )
    if figures:
        plot(out, figures)
    return "\n".join(header + rows) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=list(SWEEP), choices=list(SWEEP))
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument(
        "--phase",
        choices=["all", "reference", "ppo", "teachers", "students", "report"],
        default="all",
    )
    parser.add_argument("--eval-every", type=int, default=4096)
    parser.add_argument(
        "--episodes", type=int, default=10, help="episodes of each point of a curve"
    )
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("results/teacher-sweep"))
    args = parser.parse_args()
    for sub in ("reference", "teachers", "runs"):
        (args.out / sub).mkdir(parents=True, exist_ok=True)
    phases = (
        ["reference", "ppo", "teachers", "students", "report"]
        if args.phase == "all"
        else [args.phase]
    )
    for phase in phases:
        if phase == "reference":
            for env_id in args.envs:
                if needs_reference(args.out, env_id):
                    record = train_reference(env_id, args.out)
                    print(f"{env_id}: reference {record['checkpoints']}", flush=True)
        elif phase == "ppo":
            run_all([(e, "ppo", s) for e in args.envs for s in args.seeds], args)
        elif phase == "teachers":
            for env_id in args.envs:
                if (args.out / "teachers" / f"{env_id}.json").exists():
                    continue
                ppo = ppo_alone(args.out, env_id, args.seeds)
                if ppo is None:  # the teachers' qualities are measured against its mean
                    print(
                        f"{env_id}: no teachers yet: PPO alone has not run every seed "
                        f"{args.seeds} (--phase ppo)",
                        flush=True,
                    )
                    continue
                record = choose_teachers(env_id, args.out, ppo)
                print(f"{env_id}: teachers {record['teachers']}", flush=True)
        elif phase == "students":
            ready = [e for e in args.envs if (args.out / "teachers" / f"{e}.json").exists()]
            for env_id in sorted(set(args.envs) - set(ready)):
                print(f"{env_id}: no students yet: its teachers are not chosen (--phase teachers)")
            run_all([(e, c, s) for s in args.seeds for e in ready for c in args.cases], args)
        else:
            table = report(args.out, args.envs, args.seeds)
            command = shlex.join(["python", "benchmarks/teacher_sweep.py", *sys.argv[1:]])
            (args.out / "report.md").write_text(f"Made by `{command}`\n\n{table}")
            print(table)


if __name__ == "__main__":
    main()
