"""TL-AC with no teachers at all on a user's environment: its own learning, beside SB3 PPO alone.

With teachers that cannot help, the default's student learns from its own returns only, so
where it ends below SB3 PPO alone (issue 63's sweep), this tells whether the teachers cost it or
TL-AC's own learning does. Trains ``TLAC(env, teachers=[], seed=S, **SETTINGS)`` for ``--steps``
and prints the greedy student over the user suite's 30 evaluation episodes
(benchmarks/user_envs.py) and the CPU seconds of training.

    .venv/bin/python lab/no_teachers.py Pendulum-v1 0 --settings '{"normalize_obs": false}'
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import gymnasium as gym
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import peers
import user_envs

from tlac import TLAC


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env")
    parser.add_argument("seed", type=int)
    parser.add_argument("--settings", default="{}", help="JSON: TLAC keywords on top")
    parser.add_argument("--steps", type=int, default=100_000)
    args = parser.parse_args()
    torch.set_num_threads(1)
    settings = json.loads(args.settings)
    model = TLAC(gym.make(args.env), teachers=[], seed=args.seed, **settings)
    start = time.process_time()
    model.learn(args.steps)
    cpu = time.process_time() - start
    alone = user_envs.evaluate(peers.greedy(model), args.env, user_envs.EVAL_EPISODES)
    print(
        f"{args.env} seed {args.seed} {settings}: student alone {alone.mean():.1f} "
        f"({args.steps} steps, {cpu:.0f} CPU s)",
        flush=True,
    )


if __name__ == "__main__":
    main()
