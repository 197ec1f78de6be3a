"""Per 1e4-step window of each run folder given: training return, the high level's share of
agent choices, the low level's entropy, the share of updates stopped by the target-KL rule and
the low level's approximate KL.

    python results/kl-rule-probe/summarize.py results/kl-rule-probe/kl_* > results/kl-rule-probe/summary.txt
"""

import sys

import pandas as pd

WINDOW = 10_000
KEYS = ["train/entropy_low", "train/stopped_early", "train/approx_kl_low"]

for run in sys.argv[1:]:
    episodes = pd.read_csv(f"{run}/episodes.csv")
    progress = pd.read_csv(f"{run}/progress.csv")
    returns = episodes.groupby(episodes.timestep // WINDOW)["return"].mean().round(2).tolist()
    logged = {}
    for key in KEYS:
        rows = progress[progress.key == key]
        windows = rows.groupby(rows.timestep // WINDOW)["value"].mean().round(3).tolist()
        logged[key.split("/")[1]] = windows
    usage = pd.read_csv(f"{run}/teacher_usage.csv")
    if "all" in set(usage.region):
        usage = usage[usage.region == "all"]
    else:
        usage = usage.groupby(["timestep", "choice"], as_index=False)["count"].sum()
    total = usage.groupby("timestep")["count"].transform("sum")
    usage = usage.assign(frac=usage["count"] / total)
    agent = usage[usage.choice == "agent"]
    share = agent.groupby(agent.timestep // WINDOW)["frac"].mean().round(2).tolist()
    print(run.split("/")[-1])
    print("  return ", returns)
    print("  agent_share", share)
    for key, values in logged.items():
        print(" ", key, values)
