#!/usr/bin/env bash
# Set up, then run the test suite (about 10 minutes on 2 CPU cores; learning tests included).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python -m pytest -q "$@"
