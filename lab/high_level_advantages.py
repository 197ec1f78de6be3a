"""Why the high level collapses with partial teachers: its advantages per room and choice.

Trains TL-AC on DoorKey with Teachers L and R and, for every rollout, records each row's room
(left / right), the high level's choice (L, R, agent) and its advantage, raw (GAE) and as the
update sees it (normalised per 16-row minibatch). Prints, per window of ``--window`` steps and
per room and choice: the share of the steps, the mean raw advantage and the mean normalised
advantage. results/graduation-notes.md ("Why the high level collapses with partial teachers") reads the output.

    python lab/high_level_advantages.py --variant paper --steps 16000 --seed 0
"""

from __future__ import annotations

import argparse

import numpy as np
import torch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="paper", choices=("paper", "graduate"))
    parser.add_argument("--steps", type=int, default=16_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--window", type=int, default=2_000)
    parser.add_argument("--set", nargs="*", default=[], help="KEY=NUMBER settings")
    args = parser.parse_args()
    torch.set_num_threads(1)
    from tlac import TLAC
    from tlac.domains.doorkey.env import region_of
    from tlac.two_level import losses

    settings = {k: float(v) for k, v in (s.split("=", 1) for s in args.set)}
    model = TLAC("doorkey", teachers=["L", "R"], seed=args.seed, variant=args.variant, **settings)
    records = []
    update = model.update

    def recording_update(rollout, progress_remaining):
        data = rollout.flat()
        adv = data["advantages"]
        batch = model.config.batch_size
        normalised = torch.cat(
            [losses.normalize(adv[i : i + batch]) for i in range(0, len(adv), batch)]
        )
        records.append(
            (
                model.num_timesteps,
                region_of(data["obs"].numpy()),
                data["choices"].numpy(),
                adv.numpy(),
                normalised.numpy(),
            )
        )
        return update(rollout, progress_remaining)

    model.update = recording_update
    model.learn(args.steps, progress_bar=False)
    print("window end: room+choice: share / mean raw advantage / mean normalised advantage")
    for end in range(args.window, args.steps + 1, args.window):
        rows = [r for r in records if end - args.window < r[0] <= end]
        room, choice, raw, norm = (np.concatenate([r[i] for r in rows]) for i in range(1, 5))
        cells = []
        for g, gname in enumerate(("left", "right")):
            for c, cname in enumerate(("L", "R", "agent")):
                sel = (room == g) & (choice == c)
                mean_raw = raw[sel].mean() if sel.any() else 0.0
                mean_norm = norm[sel].mean() if sel.any() else 0.0
                cells.append(f"{gname}/{cname} {sel.mean():.2f}/{mean_raw:+.3f}/{mean_norm:+.2f}")
        print(end, " | ".join(cells), flush=True)


if __name__ == "__main__":
    main()
