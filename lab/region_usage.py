"""The high level's choices per region, pooled over the run folders of one glob, in windows of
environment steps: issue 9's C9 check (which teacher each room reuses, and when the agent
takes over).

    python lab/region_usage.py 'results/doorkey-r2/runs/*teacher-l__tlac*' --windows 0:5e4 2e5:3e5 4e5:5e5

For each window (steps ``a < t <= b`` of the rows of teacher_usage.csv) and region: the share
of each choice among all choices made in that region, pooled over the runs (count-weighted),
and the share of the steps spent in each region.
"""

from __future__ import annotations

import argparse
import glob
import sys
from pathlib import Path

import pandas as pd

from tlac.experiments.metrics import reuse_frequency


def parse_window(text: str) -> tuple[float, float]:
    """``"a:b"`` -> (a, b), numbers in any float notation (``0:5e4``)."""
    try:
        low, high = (float(part) for part in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"window {text!r}: expected START:END, e.g. 0:5e4"
        ) from None
    if not low < high:
        raise argparse.ArgumentTypeError(f"window {text!r}: START must be below END")
    return low, high


def pooled_usage(runs: list[Path]) -> pd.DataFrame:
    """Every per-region row (region != "all") of the runs' teacher_usage.csv, in one table."""
    tables = [pd.read_csv(run / "teacher_usage.csv") for run in runs]
    usage = pd.concat(tables, ignore_index=True)
    return usage[usage.region != "all"]


def window_shares(usage: pd.DataFrame, low: float, high: float) -> tuple[pd.DataFrame, pd.Series]:
    """(choice shares per region, share of steps per region) over ``low < timestep <= high``:
    the reports' reuse frequency (tlac.experiments.metrics.reuse_frequency) with one bin, as
    every row of the window ends in (0, high]."""
    rows = usage[(usage.timestep > low) & (usage.timestep <= high)]
    shares = reuse_frequency(rows, bin_width=high)
    per_region = shares.groupby("region")["count"].sum()
    table = shares.pivot(index="region", columns="choice", values="fraction").fillna(0.0)
    return table, per_region / per_region.sum()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", help="a glob of run folders (quote it)")
    parser.add_argument("--windows", nargs="+", type=parse_window, default=[(0, 5e4)])
    args = parser.parse_args()
    runs = sorted(
        Path(p) for p in glob.glob(args.runs) if (Path(p) / "teacher_usage.csv").is_file()
    )
    if not runs:
        sys.exit(f"region_usage.py: no run folder with a teacher_usage.csv matches {args.runs!r}")
    usage = pooled_usage(runs)
    print(f"{len(runs)} runs: {', '.join(run.name for run in runs)}")
    for low, high in args.windows:
        shares, steps = window_shares(usage, low, high)
        print(f"steps {low:,.0f} - {high:,.0f}")
        for region, row in shares.iterrows():
            choices = ", ".join(f"{choice} {share:.2f}" for choice, share in row.items())
            print(f"  {region:>12s} ({steps[region]:.2f} of steps): {choices}")


if __name__ == "__main__":
    main()
