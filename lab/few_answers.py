"""How far do N answers of DoorKey's optimal teacher go? (the advice budget's 1e3-answer target)

Two measurements that need no TL-AC, to read the budgeted runs against:

* ``clone N --seed S``: N answers spent as demonstrations (the optimal teacher plays whole
  episodes, every state it meets labelled with its action), then behaviour cloning alone
  (cross-entropy, Adam 1e-3, 1,500 full-batch steps) into TL-AC's student network (64-64
  tanh on the one-hot grid). Prints the greedy student's mean return and success share over
  100 episodes (seeds 10,000...): the best an asking rule could hope for from the labels
  alone, with every answer on the one teacher that knows the way.
* ``clone-then-ppo N --seed S --steps T``: the same clone as the initial policy of SB3 PPO
  (8 environments, 128 steps each, batch 256, 4 epochs, Adam 1e-3, entropy 0.01, GAE 0.95),
  then T steps of PPO, the greedy student scored every 25,000 steps (50 episodes) and at the
  end (100). ``N = 0`` is PPO alone with those settings.

    .venv/bin/python lab/few_answers.py clone 1000 --seed 0
    .venv/bin/python lab/few_answers.py clone-then-ppo 1000 --seed 0 --steps 300000
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from tlac.algorithms.encoding import make_encoder
from tlac.domains.doorkey.env import MAX_STEPS, N_ACTIONS, make_doorkey_env
from tlac.domains.doorkey.planner import DoorKeyOptimalTeacher

EVAL_SEED = 10_000
CLONE_STEPS = 1_500


def demonstrations(teacher: DoorKeyOptimalTeacher, n_answers: int, seed: int) -> np.ndarray:
    """The first ``n_answers`` states of the teacher's own episodes (reset seeds 1000 * seed,
    1000 * seed + 1, ...): every state it is asked in, each one answer."""
    env, states, episode = make_doorkey_env(), [], 0
    while len(states) < n_answers:
        obs, _ = env.reset(seed=1000 * seed + episode)
        episode += 1
        for _ in range(MAX_STEPS):
            states.append(obs)
            obs, _, terminated, truncated, _ = env.step(int(teacher.predict(obs[None])[0]))
            if terminated or truncated or len(states) >= n_answers:
                break
    return np.stack(states[:n_answers])


def clone(log_prob: Callable, params: list, x: torch.Tensor, labels: torch.Tensor) -> None:
    """Behaviour cloning: maximise ``log_prob(x, labels)`` (full batch, Adam 1e-3)."""
    optimizer = torch.optim.Adam(params, 1e-3)
    for _ in range(CLONE_STEPS):
        loss = -log_prob(x, labels).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()


def greedy_score(act: Callable, episodes: int) -> tuple[float, float]:
    """The greedy policy ``act(obs) -> action``: mean return and share of episodes that reach
    the goal, on reset seeds EVAL_SEED..."""
    env, returns = make_doorkey_env(), []
    for i in range(episodes):
        obs, _ = env.reset(seed=EVAL_SEED + i)
        total = 0.0
        for _ in range(MAX_STEPS):
            obs, reward, terminated, truncated, _ = env.step(act(obs))
            total += reward
            if terminated or truncated:
                break
        returns.append(total)
    return float(np.mean(returns)), float(np.mean(np.asarray(returns) > 0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("mode", choices=["clone", "clone-then-ppo"])
    parser.add_argument("answers", type=int)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=300_000)
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    encoder = make_encoder("onehot", make_doorkey_env().observation_space)
    teacher = DoorKeyOptimalTeacher()

    def encode(obs: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(encoder.numpy(np.atleast_2d(obs)), dtype=torch.float32)

    states = demonstrations(teacher, args.answers, args.seed) if args.answers else None
    if args.mode == "clone":
        width = encode(make_doorkey_env().reset(seed=0)[0]).shape[1]
        student = nn.Sequential(
            nn.Linear(width, 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh(), nn.Linear(64, N_ACTIONS)
        )
        labels = torch.as_tensor(teacher.predict(states), dtype=torch.long)

        def log_prob(x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
            return -nn.functional.cross_entropy(student(x), y, reduction="none")

        clone(log_prob, list(student.parameters()), encode(states), labels)
        score = greedy_score(lambda o: int(student(encode(o)).argmax()), 100)
        print(
            f"clone {args.answers} answers, seed {args.seed}: return {score[0]:.3f}, "
            f"success {score[1]:.2f}"
        )
        return
    model = ppo_student(encoder, args.seed)

    def act(obs: np.ndarray) -> int:
        return int(model.predict(encode(obs).numpy(), deterministic=True)[0][0])

    if states is not None:
        labels = torch.as_tensor(teacher.predict(states))
        policy = model.policy
        clone(
            lambda x, y: policy.get_distribution(x).log_prob(y),
            list(policy.parameters()),
            encode(states),
            labels,
        )
    print(
        f"clone {args.answers} answers, seed {args.seed}, step 0: {greedy_score(act, 50)[0]:.3f}",
        flush=True,
    )
    model.learn(args.steps, callback=every_25k(lambda: greedy_score(act, 50)[0]))
    print(f"step {args.steps}, 100 episodes: {greedy_score(act, 100)[0]:.3f}")


def ppo_student(encoder, seed: int):
    """SB3 PPO on the one-hot grid with the settings of the module docstring."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    class OneHot(gym.ObservationWrapper):
        def __init__(self, env: gym.Env):
            super().__init__(env)
            width = encoder.numpy(env.observation_space.sample()[None]).shape[1]
            self.observation_space = gym.spaces.Box(0.0, 1.0, (width,), np.float32)

        def observation(self, obs: np.ndarray) -> np.ndarray:
            return encoder.numpy(obs[None])[0].astype(np.float32)

    envs = DummyVecEnv([lambda: OneHot(make_doorkey_env()) for _ in range(8)])
    return PPO(
        "MlpPolicy",
        envs,
        n_steps=128,
        batch_size=256,
        n_epochs=4,
        learning_rate=1e-3,
        ent_coef=0.01,
        gae_lambda=0.95,
        seed=seed,
        device="cpu",
        policy_kwargs={"net_arch": [64, 64]},
    )


def every_25k(score: Callable):
    """An SB3 callback printing ``score()`` every 25,000 steps."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Every(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.next = 25_000

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                self.next += 25_000
                print(f"step {self.num_timesteps}: {score():.3f}", flush=True)
            return True

    return Every()


if __name__ == "__main__":
    main()
