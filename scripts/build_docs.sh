#!/usr/bin/env bash
# Build the documentation site (docs/*.md and the API reference from the docstrings) with
# `mkdocs build --strict`: any warning (a broken link or anchor, a docstring reference that
# does not resolve) fails it. Installs the `docs` extra into .venv (scripts/setup.sh makes it).
# The site goes to a temporary folder (or $1), never into the repository.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x .venv/bin/python ] || bash scripts/setup.sh
.venv/bin/python -m pip install -q -e ".[docs]"
SITE="${1:-$(mktemp -d /tmp/tlac-site.XXXXXX)}"
.venv/bin/python -m mkdocs build --strict --site-dir "$SITE"
echo "docs: built in $SITE"
