#!/usr/bin/env bash
# Render the demo: the D-ToF Cornell box (homodyne and heterodyne at 0° and 90°) into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/dopplertof render cornell-box --spp 256 -o out/cornell-box \
    --camera h=0,psi=0 --camera h=0,psi=90deg --camera h=1,psi=0 --camera h=1,psi=90deg "$@"
