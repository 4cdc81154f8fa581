#!/usr/bin/env bash
# Set up convsss in ./.venv; safe to run again (it only does what is missing).
#  1. a virtual environment with the package, its dependencies and the dev tools at the versions pinned in
#     constraints.txt (pyproject.toml states compatible ranges), and the pinned build tools (setuptools, wheel), so
#     `.venv/bin/pip wheel --no-build-isolation .` works as well as the default isolated build;
#  2. a libLLVM >= 17 for Dr.Jit's CPU backend: `apt-get install libllvm19` when the package finds none;
#  3. with --browser (what `make test` asks): Debian's `chromium` for the editor's browser test, when missing
#     (Playwright drives it; no browser is downloaded).
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    echo "convsss setup: creating .venv with $($PYTHON --version)"
    "$PYTHON" -m venv .venv
fi
if ! .venv/bin/python -c "import convsss, pytest" 2>/dev/null \
   || [ pyproject.toml -nt .venv/.convsss-installed ] || [ constraints.txt -nt .venv/.convsss-installed ]; then
    echo "convsss setup: installing the package and its pinned dependencies (a few minutes the first time)"
    .venv/bin/python -m pip install --quiet --upgrade pip
    .venv/bin/python -m pip install --quiet -c constraints.txt setuptools wheel
    .venv/bin/python -m pip install --quiet -c constraints.txt --no-build-isolation -e ".[dev]"
    touch .venv/.convsss-installed
fi

if ! .venv/bin/python -c "from convsss.llvm import find_libllvm; find_libllvm()" 2>/dev/null; then
    echo "convsss setup: no libLLVM >= 17 found; installing libllvm19 with apt"
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libllvm19 >/dev/null
    .venv/bin/python -c "from convsss.llvm import find_libllvm; print('convsss setup: using', find_libllvm())"
fi

if [ "${1:-}" = "--browser" ] && ! command -v chromium >/dev/null 2>&1; then
    echo "convsss setup: installing Debian's chromium with apt (the editor's browser test)"
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
fi
