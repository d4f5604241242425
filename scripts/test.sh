#!/usr/bin/env bash
# Run the whole test suite (set-up included). Extra arguments go to pytest,
# e.g. scripts/test.sh -m "not slow" for the fast subset.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/python -m pytest "$@"
