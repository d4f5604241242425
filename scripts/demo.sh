#!/usr/bin/env bash
# Render the demo: the D-ToF Cornell box (homodyne and heterodyne at 0° and 90°) into
# out/cornell-box/, then reconstruct its radial velocity from the four measurements and
# put it next to the ground truth. About 30 s of rendering on 2 cores (1024 spp, 256²).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
out=out/cornell-box
.venv/bin/dopplertof render cornell-box --spp 1024 -o "$out" --overwrite \
    --camera h=0,psi=0 --camera h=0,psi=90deg --camera h=1,psi=0 --camera h=1,psi=90deg "$@"
.venv/bin/dopplertof reconstruct "$out"
echo
echo "ground truth | reconstructed velocity: $(pwd)/$out/velocity_comparison.png"
