"""Writes report.md of this folder: the first evaluation at or above 90% of the best final score
of results/peers-user (its threshold per case), per learner, on the 2,048-step grid of this
folder's runs beside the 1e4-step grid of results/peers-user. Run from the repository root:

    python results/peers-fine-grid/make_report.py
"""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, "benchmarks")
import peers

FINE, COARSE = Path("results/peers-fine-grid"), Path("results/peers-user")
ROWS = {  # case -> (label, folder, learner)
    "Acrobot-v1": [
        ("TL-AC, 2,048-step grid", FINE, "tlac"),
        ("DAgger, 2,048-step grid", FINE, "dagger"),
        ("BC then PPO, 2,048 demonstrations", FINE / "bc-2048-demos", "bc-ppo"),
        ("BC then PPO, 1e4 demonstrations (results/peers-user)", COARSE, "bc-ppo"),
        ("PPO alone, 1e4-step grid (results/peers-user)", COARSE, "ppo"),
    ],
    "Acrobot-v1+weak": [
        ("TL-AC, 2,048-step grid", FINE, "tlac"),
        ("PPO alone, 2,048-step grid", FINE, "ppo"),
    ],
}
ROWS["CartPole-v1"] = ROWS["Acrobot-v1"]
for case in ("MountainCar-v0", "Pendulum-v1"):  # the other scripted cases (commit 7e85de4)
    ROWS[case] = [
        ("TL-AC, 2,048-step grid", FINE, "tlac"),
        ("DAgger, 2,048-step grid", FINE, "dagger"),
        ("BC then PPO, 1e4 demonstrations (results/peers-user)", COARSE, "bc-ppo"),
        ("PPO alone, 1e4-step grid (results/peers-user)", COARSE, "ppo"),
    ]
ROWS["CartPole-v1+weak"] = [  # the closest weak case on the 1e4 grid (commit 7e85de4)
    ("TL-AC, 2,048-step grid", FINE, "tlac"),
    ("PPO alone, 2,048-step grid", FINE, "ppo"),
    ("BC then PPO, 1e4 demonstrations (results/peers-user)", COARSE, "bc-ppo"),
    ("DAgger, 1e4-step grid (results/peers-user)", COARSE, "dagger"),
]


def main() -> None:
    lines = [
        "Made by `python results/peers-fine-grid/make_report.py` (NOTES.md: the runs' commands)",
        "",
        "| case | learner | seeds that reach 90% | student alone there | steps | training seconds |",
        "|---|---|---|---|---|---|",
    ]
    for case, rows in ROWS.items():
        reference = json.loads((COARSE / "reference" / f"{case}.json").read_text())
        coarse = peers.load_runs(COARSE, case)
        _, threshold = peers.finals_and_threshold(coarse, reference["random_policy"])
        for label, folder, learner in rows:
            runs = peers.load_runs(folder, case)[learner]
            hits = [peers.first_reach(r["curve"], threshold) for r in runs]
            scores = [
                next(p[1] for p in r["curve"] if p[1] >= threshold)
                for r, hit in zip(runs, hits, strict=True)
                if hit is not None
            ]
            reached = [h for h in hits if h is not None]
            cells = ["-", "never", "never"]
            if reached:
                cells = [
                    f"{np.mean(scores):.1f}",
                    f"{np.mean([h[0] for h in reached]):.0f}",
                    f"{np.mean([h[1] for h in reached]):.2f}",
                ]
            lines.append(
                f"| {case} | {label} | {len(reached)} of {len(runs)} | " + " | ".join(cells) + " |"
            )
        lines.append(
            f"| {case} | (90% of the way from random to results/peers-user's best final: {threshold:.1f}) | | | | |"
        )
    (FINE / "report.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
