#!/usr/bin/env bash
# Set up, then run the default test suite (about 7 minutes on one CPU core; the slow tests,
# learning, fault injection and the Ray runner, are `.venv/bin/pytest -m slow`).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python -m pytest -q "$@"
