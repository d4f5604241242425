#!/usr/bin/env bash
# Bootstrap a working dopplertof environment in ./.venv (idempotent).
# As root with apt-get it installs what is missing: python3 with venv, and libLLVM >= 16
# (Debian's libllvm19, for Dr.Jit's CPU backend). As anyone else it uses what is there and,
# where something is missing, says in one line what to install and stops. Then it makes
# the virtual environment and installs the package with its test and docs extras.
# PYTHON=/path/to/python3 picks the interpreter (default: python3 on PATH).
set -euo pipefail
cd "$(dirname "$0")/.."

PY=${PYTHON:-python3}

die() {
    echo "setup: $*" >&2
    exit 1
}

can_apt() {
    command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]
}

apt_install() {
    [ -n "$(ls -A /var/lib/apt/lists 2>/dev/null | grep -v lock)" ] || apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null || {
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null; }
}

# Python first: the libLLVM search below runs in it. pyproject.toml asks for >= 3.10.
python_ok() {
    command -v "$PY" >/dev/null 2>&1 &&
        "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 10))' 2>/dev/null
}
if ! python_ok; then
    if can_apt && [ -z "${PYTHON:-}" ]; then
        echo "setup: installing python3 and python3-venv"
        apt_install python3 python3-venv || die "apt-get install python3 python3-venv failed"
    fi
    python_ok || die "$PY (Python >= 3.10) not found; install it with" \
        "'sudo apt-get install python3 python3-venv' (Debian/Ubuntu) or set PYTHON=/path/to/python3"
fi

# The libLLVM search has one home, src/dopplertof/backend.py. Load that file alone:
# Dr.Jit, which the package imports, may not be installed yet. Prints the attribute's
# value (a function's result); a BackendError becomes one line and exit status 1.
backend() {
    "$PY" -c '
import importlib.util, sys
spec = importlib.util.spec_from_file_location("dopplertof_backend", "src/dopplertof/backend.py")
backend = importlib.util.module_from_spec(spec)
spec.loader.exec_module(backend)
value = getattr(backend, sys.argv[1])
try:
    value = value() if callable(value) else value
    print("" if value is None else value)
except backend.BackendError as exc:
    sys.exit(f"setup: {exc}")
' "$1"
}

llvm=$(backend find_libllvm)
if [ -z "$llvm" ]; then
    if can_apt; then
        echo "setup: installing libllvm19 (Dr.Jit's CPU backend needs libLLVM >= 16)"
        apt_install libllvm19 || die "$(backend LLVM_INSTALL_HINT)"
        [ -n "$(backend find_libllvm)" ] || die "$(backend LLVM_INSTALL_HINT)"
    elif [ "$(backend cuda_device_count)" -gt 0 ]; then
        echo "setup: no libLLVM >= 16, but a CUDA GPU works: dopplertof will run on it" \
            "(the CPU backend, which the tests use by default, needs libLLVM >= 16)"
    else
        die "$(backend LLVM_INSTALL_HINT)"
    fi
fi

# A .venv whose interpreter does not run here (the checkout was moved or copied, or another
# user made it: its links point elsewhere) is made again; `python3 -m venv` alone cannot.
if [ -e .venv ] && ! .venv/bin/python -c '' >/dev/null 2>&1; then
    echo "setup: .venv's Python does not run here (a moved or copied checkout?); making .venv again"
    "$PY" -m venv --clear .venv || die "cannot remake .venv; remove it ('rm -rf .venv') and run setup again"
fi
# `python3 -m venv` on an existing .venv completes it, so a half-made one (no pip) heals.
if ! .venv/bin/python -m pip --version >/dev/null 2>&1; then
    # Debian and Ubuntu ship venv's ensurepip apart, in python3-venv.
    if ! "$PY" -c 'import ensurepip, venv' 2>/dev/null; then
        can_apt || die "$PY cannot make a virtual environment (no ensurepip); install it with" \
            "'sudo apt-get install python3-venv' (Debian/Ubuntu) or set PYTHON=/path/to/python3"
        echo "setup: installing python3-venv"
        apt_install python3-venv || die "apt-get install python3-venv failed"
    fi
    "$PY" -m venv .venv
fi
if ! .venv/bin/python -c "import dopplertof, pytest, sphinx, myst_nb, furo, sphinx_click, ipykernel" 2>/dev/null; then
    echo "setup: installing dopplertof and its dependencies into .venv"
    .venv/bin/python -m pip install -q --upgrade pip
    .venv/bin/python -m pip install -q -e '.[test,docs]'
fi
