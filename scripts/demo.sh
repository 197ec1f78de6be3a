#!/usr/bin/env bash
# Set up, then run the main job on its built-in default: TL-AC on MiniGrid DoorKey 7x7 with
# one optimal and two random teachers for 100,000 steps, keeping the best-evaluated student;
# then evaluate it alone (no teachers) and with its teachers over 100 episodes.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/tlac train --out runs/demo --force --steps 100000 --eval-every 10000 --eval-episodes 100 "$@"
.venv/bin/tlac eval runs/demo --episodes 100 --with-teachers
