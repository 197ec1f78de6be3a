#!/usr/bin/env bash
# CI step (issue 43, point 8): `pip install .` WITHOUT extras in a fresh venv, then
# `from tlac import TLAC` and a 1,000-step DoorKey learn. The extras (experiments,
# tensorboard, control, ...) must not be needed to train.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3}"
VENV="$(mktemp -d)/bare"
trap 'rm -rf "$(dirname "$VENV")"' EXIT
"$PYTHON" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q "torch==2.13.0"   # the CPU build, as scripts/setup.sh
"$VENV/bin/python" -m pip install -q .
cd "$(dirname "$VENV")"   # away from the source tree: the installed package is what runs
"$VENV/bin/python" - <<'PY'
import importlib.util

from tlac import TLAC

extras = [m for m in ("pandas", "matplotlib", "rich", "tensorboard") if importlib.util.find_spec(m)]
assert not extras, f"installed without being asked for: {extras}"
model = TLAC("doorkey", teachers=["optimal", "random"], seed=0).learn(1000)
assert model.num_timesteps >= 1000
print(f"bare install: TLAC learned {model.num_timesteps} DoorKey steps without the extras")
PY
