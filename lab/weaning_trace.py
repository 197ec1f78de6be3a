"""Why the student beside CartPole's untrained network (q 0.86: it balances for 434 steps) is slow
to 90% of PPO alone's score (results/teacher-sweep/NOTES.md, "The time to 90% on one machine").
Trains the sweep's case (`teacher_sweep.make_learner`: the default with that teacher alone) and
prints, every 4,096 steps: the greedy student's return (10 episodes), the mean of the recent
sampled solo returns, and the weaning (the weight the copy has lost: competence of the sampled
solo returns against the best teacher's led return).

    .venv/bin/python lab/weaning_trace.py [SEED] [CASE]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import peers  # noqa: E402
import teacher_sweep  # noqa: E402

ENV_ID = "CartPole-v1"


def main() -> None:
    seed = int(sys.argv[1]) if len(sys.argv) > 1 else 0
    case = sys.argv[2] if len(sys.argv) > 2 else "q0"
    torch.set_num_threads(1)
    torch.manual_seed(seed)
    model = teacher_sweep.make_learner(ENV_ID, case, seed, ROOT / "results/teacher-sweep")

    def trace(m) -> bool:
        if m.num_timesteps % 4096 < 2048:
            solo = m.solo
            greedy = peers.evaluate(peers.greedy(m), ENV_ID, 10).mean()
            recent = np.mean(solo.solo_returns) if len(solo.solo_returns) else float("nan")
            print(
                f"{m.num_timesteps} steps: greedy student {greedy:.0f}, sampled solo {recent:.1f}, "
                f"weaning {solo.weaning:.3f}",
                flush=True,
            )
        return True

    model.learn(40_960, callback=trace)


if __name__ == "__main__":
    main()
