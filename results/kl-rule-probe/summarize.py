"""Per 1e4-step window of each run folder given: training return, the high level's share of
agent choices, the low level's entropy, the share of updates stopped by the target-KL rule and
the low level's approximate KL.

    python results/kl-rule-probe/summarize.py results/kl-rule-probe/kl_* > results/kl-rule-probe/summary.txt
"""
import sys, pandas as pd, numpy as np
for run in sys.argv[1:]:
    ep = pd.read_csv(f"{run}/episodes.csv"); pr = pd.read_csv(f"{run}/progress.csv")
    ret = ep.groupby(ep.timestep // 10000)["return"].mean().round(2).tolist()
    out = {}
    for k in ["train/entropy_low", "train/stopped_early", "train/approx_kl_low"]:
        d = pr[pr.key == k]
        out[k.split("/")[1]] = d.groupby(d.timestep // 10000)["value"].mean().round(3).tolist()
    u = pd.read_csv(f"{run}/teacher_usage.csv")
    u = u[u.region == "all"] if "all" in set(u.region) else u.groupby(["timestep", "choice"], as_index=False)["count"].sum()
    tot = u.groupby("timestep")["count"].transform("sum")
    u = u.assign(frac=u["count"] / tot)
    agent = u[u.choice == "agent"]
    share = agent.groupby(agent.timestep // 10000)["frac"].mean().round(2).tolist()
    print(run.split("/")[-1]); print("  return ", ret); print("  agent_share", share)
    for k, v in out.items(): print(" ", k, v)
