#!/usr/bin/env bash
# Build the documentation site into docs/_build/html (open docs/_build/html/index.html):
# Sphinx + MyST, the tutorials executed, warnings as errors, no network. Set-up included.
# Extra arguments go to sphinx-build.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
rm -rf docs/_build
exec .venv/bin/python -m sphinx -W --keep-going -b html docs docs/_build/html "$@"
