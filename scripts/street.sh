#!/usr/bin/env bash
# Render the built-in street scene: a D-ToF camera with its light on a car driving at
# 15 m/s through traffic (23 moving bodies), homodyne and heterodyne at 0° and 90° with
# automotive modulation (150 MHz, 1 ms exposure), into out/street/; then reconstruct the
# radial velocity (relative to the moving camera) and put it next to the ground truth.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
out=out/street
cam=f=150e6,T=1e-3
.venv/bin/dopplertof render street --spp 256 -o "$out" --overwrite \
    --camera "$cam,h=0,psi=0" --camera "$cam,h=0,psi=90deg" --camera "$cam,h=1,psi=0" --camera "$cam,h=1,psi=90deg" "$@"
.venv/bin/dopplertof reconstruct "$out"
echo
echo "ground truth | reconstructed velocity: $(pwd)/$out/velocity_comparison.png"
