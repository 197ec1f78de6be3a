"""A probe of the audition's judgement (issue 63, Pendulum): judge a teacher's help against the
untrained student's FIRST solo returns, not against the floor.

When this probe was written, the default (``SoloEpisodes.no_teacher_helps``) asked whether a
teacher's led episodes beat the student's floor, the lowest mean of a window of solo returns
seen so far, by 2 standard errors of the led mean. On a dense, noisy reward the floor keeps
falling as windows come and go, so a teacher about as good as the untrained student is judged
to help in the end. Here the reference is the mean of the first ``min_episodes`` solo returns,
and the test is two-sample: the led mean must beat it by 2 standard errors of the difference.
The default now judges against that same mean with the led mean's standard error alone
(commit 82f1e43c; results/teacher-sweep/NOTES.md). Trains one sweep case as the sweep builds
it (benchmarks/teacher_sweep.make_learner) and prints the student alone over the user suite's
30 evaluation episodes; ``--judgement default`` trains the default instead, and ``--trace``
prints the audition's state every 8,192 steps (its floor, the recent solo mean, each teacher's
led mean and count, and whether no teacher helps):

    .venv/bin/python lab/first_floor_probe.py Pendulum-v1 q0+random 1
    .venv/bin/python lab/first_floor_probe.py Pendulum-v1 q0+random 1 --judgement default --trace
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import peers
import teacher_sweep
import user_envs

from tlac.two_level import graduation

ROOT = Path(__file__).resolve().parents[1]


def judge_against_first_solo_returns() -> None:
    """Replace the judgement in ``SoloEpisodes`` (this process only)."""
    record_end = graduation.SoloEpisodes.end

    def end(self: graduation.SoloEpisodes, env_index: int, episode_return: float) -> bool:
        first = self.__dict__.setdefault("first_solo", [])
        if self.active[env_index] and len(first) < self.min_episodes:
            first.append(float(episode_return))
        return record_end(self, env_index, episode_return)

    def no_teacher_helps(self: graduation.SoloEpisodes) -> bool:
        here = ~self.gone & ~self.outside
        first = np.array(self.__dict__.get("first_solo", []))
        if (
            self.teacher_share <= 0
            or len(first) < self.min_episodes
            or not here.any()
            or (self.led_counts[here] < graduation.MIN_LED_EPISODES).any()
        ):
            return False
        first_variance = first.var() / len(first)
        for total, squares, count in zip(
            self.led_sums[here], self.led_squares[here], self.led_counts[here], strict=True
        ):
            mean = total / count
            se = np.sqrt(max(squares / count - mean * mean, 0.0) / count + first_variance)
            if mean - graduation.HELP_MARGIN * se > first.mean():
                return False
        return True

    graduation.SoloEpisodes.end = end
    graduation.SoloEpisodes.no_teacher_helps = property(no_teacher_helps)


def trace(model: Any) -> bool:
    """After an update: the audition's state, every 8,192 steps (reads only)."""
    solo = model.solo
    if model.num_timesteps % 8192 < model.config.n_steps:
        led = solo.led_sums / np.maximum(solo.led_counts, 1)
        recent = float(np.mean(solo.solo_returns)) if solo.solo_returns else float("nan")
        print(
            f"{model.num_timesteps}: floor {solo.floor:.1f}, solo {recent:.1f}, led "
            f"{led.round(1).tolist()} x {solo.led_counts.tolist()}, "
            f"no teacher helps: {solo.no_teacher_helps}",
            flush=True,
        )
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env")
    parser.add_argument("case")
    parser.add_argument("seed", type=int)
    parser.add_argument("--judgement", choices=["first", "default"], default="first")
    parser.add_argument("--trace", action="store_true")
    args = parser.parse_args()
    if args.judgement == "first":
        judge_against_first_solo_returns()
    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    out = ROOT / "results" / "teacher-sweep"
    model = teacher_sweep.make_learner(args.env, args.case, args.seed, out)
    model.learn(teacher_sweep.budget(args.env), callback=trace if args.trace else None)
    alone = peers.evaluate(peers.greedy(model), args.env, user_envs.EVAL_EPISODES)
    print(f"{args.env} {args.case} seed {args.seed}: student alone {alone.mean():.1f}", flush=True)


if __name__ == "__main__":
    main()
