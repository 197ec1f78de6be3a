"""Trace one TL-AC run on a user environment of benchmarks/user_envs.py: after every chunk of
training, the student alone (greedy), the high level's mean probabilities on the first
teacher's own trajectory, and the student's greedy agreement with that teacher there.

    .venv/bin/python lab/graduation_trace.py CartPole-v1 --seed 2

It showed why the default's student can fall late in training (docs/graduation.md, "Users'
own environments"): the high level hands control to the agent, and the imitation term, which
weighs the teachers by the high level's probabilities renormalised over the teachers, then
follows trust that has drifted to the random teacher.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

from tlac import TLAC
from tlac.algorithms.nets import np_log_softmax

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from user_envs import SUITE, evaluate, parse_settings  # benchmarks/user_envs.py


def teacher_trajectory(env_id: str, teacher, n: int, seed: int = 123) -> np.ndarray:
    """``n`` states visited by ``teacher`` (episodes restart when they end)."""
    env = gym.make(env_id)
    obs, _ = env.reset(seed=seed)
    states = []
    for _ in range(n):
        states.append(obs)
        obs, _, terminated, truncated, _ = env.step(teacher(obs))
        if terminated or truncated:
            obs, _ = env.reset()
    return np.stack(states).astype(np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", choices=list(SUITE))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--chunks", type=int, default=10)
    parser.add_argument("--states", type=int, default=300)
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="a TL-AC setting"
    )
    args = parser.parse_args()
    if args.chunks < 1 or args.steps < args.chunks:
        parser.error(f"--steps ({args.steps}) must be at least --chunks ({args.chunks}) >= 1")
    torch.set_num_threads(1)
    env = gym.make(args.env)
    teachers = SUITE[args.env](args.seed, env.action_space)
    model = TLAC(env, teachers=teachers, seed=args.seed, **parse_settings(args.set))
    states = teacher_trajectory(args.env, teachers[0], args.states)
    discrete = isinstance(env.action_space, gym.spaces.Discrete)
    advice = np.array([teachers[0](s) for s in states])
    names = [*model.teacher_names, "agent"]
    header = "steps | student alone | competence | high level: " + " / ".join(names)
    print(header + (" | agreement" if discrete else ""), flush=True)
    # one learn call per chunk: with the default's constant schedules this is the same run
    for _ in range(args.chunks):
        model.learn(args.steps // args.chunks, reset_num_timesteps=False)
        high = np.exp(np_log_softmax(model.nets.act(states)[0])).mean(0)
        alone = evaluate(lambda b: model.predict(b, deterministic=True)[0], args.env, args.episodes)
        solo = model.solo.competence if model.solo is not None else float("nan")
        row = f"{model.num_timesteps} | {alone.mean():.1f} | {solo:.2f} | " + " / ".join(
            f"{p:.2f}" for p in high
        )
        if discrete:  # the greedy student's agreement with the first teacher on its states
            agreement = np.mean(model.predict(states, deterministic=True)[0] == advice)
            row += f" | {agreement:.2f}"
        print(row, flush=True)


if __name__ == "__main__":
    main()
