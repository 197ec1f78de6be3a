"""The kept student's renewal rule, old against new, on the same training (paired).

Old rule (to 2026-11-30): when the latest full window of 20 solo returns is not clearly below
the best window, deploy the live weights. New rule: the latest 5 solo returns must pass the
same test too, and the student deployed is the one that collected the last rollout (the
weights that played those episodes), not the live weights the last update left; never the
weights the model started from (while they collect, a renewal takes the live weights).

Training is the same under both (the kept student only changes what ``predict`` deploys), so
one run per seed serves both: the old rule's choice is shadowed beside the model's own. Each
kept student is scored greedy on the suite's 30 final episodes (seeds 10,000, ...).

    python lab/kept_student_rule.py --cases CartPole-v1 Acrobot-v1 --seeds 0 1 2 3 4 --out OUT.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import advice_budget
import peers
import user_envs

from tlac import TLAC
from tlac.two_level.graduation import worth_deploying

CASES = {
    # name: (environment, how TL-AC is built)
    "CartPole-v1": ("user", "CartPole-v1"),
    "Acrobot-v1": ("user", "Acrobot-v1"),
    "CartPole-v1+advice-inf": ("advice", "CartPole-v1"),
    "DoorKey+1optimal-2random+advice-inf": ("advice", "DoorKey+1optimal-2random"),
}


def build(case: str, seed: int) -> TLAC:
    kind, name = CASES[case]
    if kind == "user":
        env = peers.make_env(name)
        return TLAC(env, teachers=user_envs.SUITE[name](seed, env.action_space), seed=seed)
    settings = {**advice_budget.BENCH_SETTINGS, "ask": "learned", "advice_budget": None}
    env = "doorkey" if peers.is_doorkey(name) else peers.make_env(name)
    teachers = advice_budget.teacher_specs(name, seed, None if env == "doorkey" else env, 1.0)
    return TLAC(env, teachers=teachers, seed=seed, **settings)


def shadow_old_rule(model: TLAC) -> dict[str, Any]:
    """Record, beside the model's own renewals, the student the old rule would deploy."""
    solo = model.solo
    kept: dict[str, Any] = {"old": None}
    own = solo.latest_is_worth_deploying

    def both() -> bool:
        window = solo.solo_returns
        if len(window) >= window.maxlen:
            n_windows = solo.solo_episodes / len(window)
            if worth_deploying(window, solo.best_solo, n_windows, recent=len(window))[0]:
                kept["old"] = model.nets.snapshot_student(model.num_timesteps)
        return own()

    solo.latest_is_worth_deploying = both
    return kept


def score(model: TLAC, case: str, snapshot: Any) -> float:
    model.deployed = snapshot
    env_case = CASES[case][1]
    return float(peers.evaluate(peers.greedy(model), env_case, 30, user_envs.EVAL_SEED).mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    for case in args.cases:
        for seed in args.seeds:
            model = build(case, seed)
            kept = shadow_old_rule(model)
            model.learn(args.steps, progress_bar=False)
            new, old = model.deployed, kept["old"]
            row = {
                "case": case,
                "seed": seed,
                "new": score(model, case, new),
                "new_from": None if new is None else new.num_timesteps,
                "old": score(model, case, old),
                "old_from": None if old is None else old.num_timesteps,
                "live": score(model, case, None),
            }
            print(json.dumps(row), flush=True)
            with args.out.open("a") as f:
                f.write(json.dumps(row) + "\n")
    rows = [json.loads(line) for line in args.out.read_text().splitlines()]
    for case in dict.fromkeys(r["case"] for r in rows):
        mine = [r for r in rows if r["case"] == case]
        means = {k: np.mean([r[k] for r in mine]) for k in ("old", "new", "live")}
        print(case, len(mine), {k: round(float(v), 3) for k, v in means.items()})


if __name__ == "__main__":
    main()
