"""How firmly a DoorKey student holds its teachers' base action: greedy margins on their path.

Trains the default TL-AC on DoorKey with the given teachers, then plays the reference teacher
(the base the teachers are derived from) for 20 episodes and, in every state on its path,
compares the student's greedy action with the reference's and measures the margin
``pi(reference's action) - max of the other actions``. A student fitted to a flat label
(DoorKey's noisy teacher: 1/3 on the base's action, 2/15 on each other) agrees with its base
in most states but by a few hundredths, and its greedy path loops wherever one margin flips.

    python lab/label_margins.py --teachers ppo-noisy20,ppo-noisy20,ppo-noisy20 --steps 100000

results/graduation-notes.md, section 29, has its figures.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from tlac import TLAC
from tlac.domains import get_domain, make_teachers
from tlac.evaluation import evaluate_policy


def path_margins(model: TLAC, reference, env, episodes: int, seed: int) -> dict[str, float]:
    """Agreement, mean margin and mean entropy of the student's action probabilities on the
    states the reference teacher visits when it acts alone."""
    agree, margins, entropies = [], [], []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        done = False
        while not done:
            action = int(np.asarray(reference.predict(obs[None]))[0])
            logits = model.nets.student_heads(obs[None], model.deployed)[0][0]
            probs = np.exp(logits - logits.max())
            probs /= probs.sum()
            agree.append(int(np.argmax(probs)) == action)
            margins.append(probs[action] - np.max(np.delete(probs, action)))
            entropies.append(-(probs * np.log(probs + 1e-12)).sum())
            obs, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
    return {
        "agreement": float(np.mean(agree)),
        "margin": float(np.mean(margins)),
        "entropy": float(np.mean(entropies)),
        "states": len(agree),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--teachers", default="ppo-noisy20,ppo-noisy20,ppo-noisy20")
    parser.add_argument("--reference", default="ppo", help="the teachers' base")
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--episodes", type=int, default=50, help="student-alone episodes")
    args = parser.parse_args()
    torch.set_num_threads(1)
    domain = get_domain("doorkey")
    model = TLAC("doorkey", teachers=args.teachers.split(","), seed=args.seed)
    start = time.time()
    model.learn(args.steps)
    print(f"trained {args.steps} steps in {time.time() - start:.0f} s")
    for deterministic in (True, False):
        returns = evaluate_policy(
            lambda o, d=deterministic: model.predict(o, deterministic=d)[0],
            domain,
            args.episodes,
            1000,
        )
        kind = "greedy" if deterministic else "sampled"
        print(f"student alone, {kind}: {returns.mean():.3f} over {args.episodes} episodes")
    env = domain.make_env()
    reference = make_teachers(domain, [args.reference], env, seed=0)[0]
    stats = path_margins(model, reference, env, episodes=20, seed=2000)
    print(
        f"on {args.reference}'s path ({stats['states']} states): agreement "
        f"{stats['agreement']:.3f}, margin {stats['margin']:.3f}, entropy {stats['entropy']:.3f}"
    )


if __name__ == "__main__":
    main()
