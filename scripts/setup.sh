#!/usr/bin/env bash
# Bootstrap a working dopplertof environment in ./.venv (idempotent).
# Installs, where missing: python3-venv and libLLVM >= 16 (Debian's libllvm19, for
# Dr.Jit's CPU backend), a virtual environment, and the package with its test extras.
set -euo pipefail
cd "$(dirname "$0")/.."

have_llvm() {
    ls /usr/lib/*/libLLVM.so.1[6-9]* /usr/lib/*/libLLVM-1[6-9].so* /usr/lib/*/libLLVM.so.2[0-9]* \
       /usr/lib/llvm-1[6-9]/lib/libLLVM*.so* /usr/lib/llvm-2[0-9]/lib/libLLVM*.so* >/dev/null 2>&1
}

apt_install() {
    if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
        [ -n "$(ls -A /var/lib/apt/lists 2>/dev/null | grep -v lock)" ] || apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null || {
            apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null; }
    else
        echo "setup: please install $* (needs root and apt-get)" >&2
        return 1
    fi
}

if ! have_llvm; then
    echo "setup: installing libllvm19 (Dr.Jit's CPU backend needs libLLVM >= 16)"
    apt_install libllvm19
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    if ! "$PY" -m venv .venv 2>/dev/null; then
        apt_install python3-venv
        "$PY" -m venv .venv
    fi
fi
if ! .venv/bin/python -c "import dopplertof, pytest" 2>/dev/null; then
    echo "setup: installing dopplertof and its dependencies into .venv"
    .venv/bin/python -m pip install -q --upgrade pip
    .venv/bin/python -m pip install -q -e '.[test]'
fi
