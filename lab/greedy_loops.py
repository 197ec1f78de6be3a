"""Where a DoorKey student's GREEDY actions loop, and whom its high level trusts there.

DoorKey is deterministic, so a greedy student that comes back to a state it has seen in the
same episode loops until the time limit. For each evaluation episode (seeds 10000, ...) this
plays the deployed student greedily and, at the first repeated state, prints the room, the
student's action probabilities, the high level's probabilities (which weight each teacher's
advice in the imitation term) and a reference teacher's action there; then a summary.

    python lab/greedy_loops.py RUN_FOLDER --episodes 30 --reference ppo

RUN_FOLDER holds a TL-AC ``model.pt`` trained on ``doorkey`` (results/graduation-notes.md, "The
greedy and the sampled student on these teachers").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

EVAL_SEED = 10_000


def rounded(probabilities: np.ndarray) -> str:
    return "[" + ", ".join(f"{p:.2f}" for p in probabilities) + "]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a TL-AC run folder on doorkey (with model.pt)")
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--reference", default="ppo", help="a doorkey teacher to compare with")
    args = parser.parse_args()
    if not (args.run / "model.pt").is_file():
        sys.exit(f"greedy_loops.py: {str(args.run)!r} has no model.pt")
    from tlac import TLAC
    from tlac.algorithms.nets import np_log_softmax
    from tlac.domains import get_domain, make_teachers
    from tlac.domains.doorkey.env import REGION_NAMES, region_of

    torch.set_num_threads(1)
    domain = get_domain("doorkey")
    env = domain.make_env()
    model = TLAC.load(args.run / "model.pt")
    (reference,) = make_teachers(domain, [args.reference], env, 0)
    names = [*model.teacher_names, "agent"]
    returns, loops, agree = [], 0, 0
    most_trusted = dict.fromkeys(model.teacher_names, 0)  # at the loop states
    for episode in range(args.episodes):
        obs, _ = env.reset(seed=EVAL_SEED + episode)
        seen, done, total, looped = set(), False, 0.0, False
        while not done:
            action = int(model.predict(obs, deterministic=True)[0])
            if obs.tobytes() in seen and not looped:
                looped, loops = True, loops + 1
                low_out = model.nets.student_heads(obs[None], model.deployed)[0][0]
                high_logits = model.nets.act(obs[None])[0][0]
                advised = int(reference.predict(obs[None])[0])
                agree += int(advised == action)
                high = np.exp(np_log_softmax(high_logits))
                most_trusted[model.teacher_names[int(np.argmax(high[:-1]))]] += 1
                print(
                    f"episode {episode}: room {REGION_NAMES[int(region_of(obs[None])[0])]}, "
                    f"greedy {action}, {args.reference} {advised}, "
                    f"student {rounded(np.exp(np_log_softmax(low_out)))}, high level {rounded(high)}"
                    + f" ({', '.join(names)})"
                )
            seen.add(obs.tobytes())
            obs, reward, terminated, truncated, _ = env.step(action)
            total += float(reward)
            done = terminated or truncated
        returns.append(total)
    print(
        f"{args.episodes} greedy episodes: return {np.mean(returns):.3f}; {loops} come back to a "
        f"state (greedy action = {args.reference}'s there in {agree} of them); the teacher "
        f"the high level trusts most there: {most_trusted}"
    )


if __name__ == "__main__":
    main()
