"""How the paper variant's low level collapses: pi_low's entropy and greedy actions over training.

Algorithm 1 trains pi_low with Eq. 3 on every executed action, most of them the teachers'. This
probe trains the paper variant on DoorKey and, every ``--every`` steps, reads pi_low on a fixed
set of probe states (those the reference teacher visits in 20 episodes): its mean entropy, the
share of probe states where its greedy action is each of the actions (the argmax histogram), its
agreement with the reference, the student alone (greedy, 20 episodes) and the training return of
the last 20 episodes.

    python lab/eq3_collapse.py --teachers ppo-noisy20,ppo-noisy20,ppo-noisy20 --seed 1

docs/reproduction.md ("Claims and verdicts") and results/eq3-collapse quote its output.
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from tlac import TLAC
from tlac.domains import get_domain, make_teachers
from tlac.evaluation import evaluate_policy
from tlac.recording import find_episode_recorder


def probe_states(reference, env, episodes: int) -> np.ndarray:
    """The observations the reference teacher visits, acting alone, in ``episodes`` episodes."""
    states = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=50_000 + episode)
        done = False
        while not done:
            states.append(obs)
            action = int(np.asarray(reference.predict(obs[None]))[0])
            obs, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
    return np.stack(states)


def low_level_reading(model: TLAC, states: np.ndarray, reference_actions: np.ndarray) -> dict:
    """pi_low on the probe states: mean entropy (nats), argmax histogram, agreement."""
    with torch.no_grad():
        logits = model.policy(torch.as_tensor(states))
    probs = torch.softmax(logits, -1).numpy()
    entropy = -(probs * np.log(probs + 1e-12)).sum(-1)
    greedy = probs.argmax(-1)
    histogram = np.bincount(greedy, minlength=probs.shape[1]) / len(greedy)
    return {
        "entropy": float(entropy.mean()),
        "histogram": histogram,
        "agreement": float((greedy == reference_actions).mean()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--teachers", default="ppo-noisy20,ppo-noisy20,ppo-noisy20")
    parser.add_argument("--reference", default="ppo", help="the teachers' base (probe states)")
    parser.add_argument("--steps", type=int, default=500_000)
    parser.add_argument("--every", type=int, default=25_000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--variant", default="paper")
    args = parser.parse_args()
    torch.set_num_threads(1)
    domain = get_domain("doorkey")
    env = domain.make_env()
    reference = make_teachers(domain, [args.reference], env, 0)[0]
    states = probe_states(reference, env, 20)
    reference_actions = np.array([int(np.asarray(reference.predict(s[None]))[0]) for s in states])
    model = TLAC("doorkey", teachers=args.teachers.split(","), seed=args.seed, variant=args.variant)
    n_actions = env.action_space.n
    labels = [a.name for a in env.unwrapped.actions][:n_actions]
    print(f"{len(states)} probe states; actions: {' '.join(labels)}", flush=True)
    print("steps | training return | student alone | pi_low entropy | agreement | argmax histogram")
    next_row = args.every

    def greedy(obs: np.ndarray) -> np.ndarray:
        return model.predict(obs, deterministic=True)[0]

    def row(m: TLAC) -> bool:
        nonlocal next_row
        if m.num_timesteps < next_row:
            return True
        next_row += args.every
        recent = list(find_episode_recorder(m.env).episode_returns)  # the last 20 episodes
        reading = low_level_reading(m, states, reference_actions)
        alone = evaluate_policy(greedy, domain, episodes=20, seed=10_000)
        histogram = " ".join(f"{share:.2f}" for share in reading["histogram"])
        print(
            f"{m.num_timesteps} | {np.mean(recent) if recent else float('nan'):.3f} | "
            f"{np.mean(alone):.3f} | {reading['entropy']:.3f} | {reading['agreement']:.2f} | "
            f"{histogram}",
            flush=True,
        )
        return True

    model.learn(args.steps, callback=row)


if __name__ == "__main__":
    main()
