"""Soak test: one long TL-AC run on DoorKey, memory and numbers watched as it goes.

Trains the default TL-AC (three teachers: optimal, random, random) for ``--steps`` steps in
chunks of ``--every`` steps and, after each chunk, records the process's resident memory (RSS,
from /proc or ``resource``), steps per second, and whether every network parameter is finite.
Prints one line per chunk and, with ``--out``, writes the rows as CSV. A run that leaks memory
shows RSS growing chunk after chunk; one that diverges stops with TrainingError.

    python benchmarks/soak.py --steps 1000000 --every 100000 --out results/soak.csv
"""

from __future__ import annotations

import argparse
import csv
import resource
import time
from pathlib import Path

import torch


def rss_mb() -> float:
    """Resident memory of this process now, in MB (Linux: /proc; elsewhere: the peak)."""
    status = Path("/proc/self/status")
    if status.exists():
        for line in status.read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000)
    parser.add_argument("--every", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=None, help="CSV file for the rows")
    args = parser.parse_args()
    torch.set_num_threads(1)
    from tlac import TLAC

    model = TLAC("doorkey", teachers=["optimal", "random", "random"], seed=args.seed)
    rows = []
    start_rss = rss_mb()
    print(f"{'steps':>9} {'RSS MB':>8} {'steps/s':>8} {'finite':>6} {'train return':>12}")
    while model.num_timesteps < args.steps:
        t0 = time.perf_counter()
        model.learn(min(args.every, args.steps - model.num_timesteps), reset_num_timesteps=False)
        finite = all(bool(torch.isfinite(p).all()) for p in model.nets.net.parameters())
        returns = list(model.env.episode_returns)[-100:]
        row = {
            "steps": model.num_timesteps,
            "rss_mb": round(rss_mb(), 1),
            "steps_per_s": round(args.every / (time.perf_counter() - t0), 1),
            "finite": finite,
            "train_return": round(sum(returns) / max(1, len(returns)), 3),
        }
        rows.append(row)
        print(
            f"{row['steps']:>9} {row['rss_mb']:>8} {row['steps_per_s']:>8} "
            f"{finite!s:>6} {row['train_return']:>12}",
            flush=True,
        )
        if args.out:
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            with open(args.out, "w", newline="") as f:
                writer = csv.DictWriter(f, fieldnames=list(row))
                writer.writeheader()
                writer.writerows(rows)
    growth = rows[-1]["rss_mb"] - rows[0]["rss_mb"]
    print(
        f"RSS at start {start_rss:.0f} MB; growth from the first chunk to the last {growth:+.1f} MB"
    )


if __name__ == "__main__":
    main()
