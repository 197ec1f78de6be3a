#!/usr/bin/env bash
# Create .venv (if needed) and install tlac with every optional domain and the dev tools.
# Needs only Python >= 3.10. PyTorch is installed first and pinned to a CPU-capable build
# (torch==2.13.0); everything else comes from pyproject.toml.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  "$PYTHON" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
if ! .venv/bin/python -c "import torch" 2>/dev/null; then
  # On a machine with internet access and no GPU, add:
  #   --index-url https://download.pytorch.org/whl/cpu
  .venv/bin/python -m pip install -q "torch==2.13.0"
fi
.venv/bin/python -m pip install -q -e ".[all]"
