#!/usr/bin/env bash
# GPU check (issue 17, reference/gpu-notes.md §4): every built-in scene rendered on
# cuda_ad_rgb and on llvm_ad_rgb at a small size (replay and reconnection, a homodyne and
# a heterodyne camera), compared within noise, every moving body seen on the CPU also seen
# on the GPU, no Dr.Jit warning on either; then the throughput rows of
# benchmarks/throughput.py (--quick) on both. Under 8 minutes on one GPU.
#
#   scripts/gpu-check.sh                      # set up, then the check
#   scripts/gpu-check.sh --dry-run            # no GPU: the LLVM half, compared with itself
#                                             # at another seed (CI; also DOPPLERTOF_GPU_CHECK_DRY=1)
#   scripts/gpu-check.sh --no-setup --resolution 8 --spp 16 --no-throughput
#
# --no-setup runs on what is installed: .venv's Python, else $PYTHON, else python3, with this
# checkout's src/ first on the path (a GPU machine with no network: carry the mitsuba and
# drjit wheels, install them with pip --target, and put that folder on PYTHONPATH).
# Each variant's renders stop after --half-timeout s (default 240); the scenes they finished
# are compared, and the check fails naming the rest.
#
# Exit status 0 when every comparison holds, 1 otherwise (the failures are listed).
set -euo pipefail
cd "$(dirname "$0")/.."
setup=1
args=()
for a in "$@"; do
    if [ "$a" = "--no-setup" ]; then setup=0; else args+=("$a"); fi
done
if [ "${DOPPLERTOF_GPU_CHECK_DRY:-0}" = 1 ]; then args+=("--dry-run"); fi
if [ "$setup" = 1 ]; then bash scripts/setup.sh; fi
py=.venv/bin/python
[ -x "$py" ] || py=${PYTHON:-python3}
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}"
exec "$py" scripts/gpu_check.py ${args[@]+"${args[@]}"}
