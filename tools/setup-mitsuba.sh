#!/usr/bin/env bash
# Sets up Mitsuba 3 (developer tool, not needed by CI) in /work/main/.venv-mitsuba
# (or $SNELL_MITSUBA_VENV) and makes sure LLVM 19 is installed for the
# llvm_ad_rgb variant.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${SNELL_MITSUBA_VENV:-$ROOT/.venv-mitsuba}"
LLVM_LIB=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1

if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install --upgrade pip >/dev/null
"$VENV/bin/python" -m pip install -r "$ROOT/tools/requirements.txt"

if [ ! -e "$LLVM_LIB" ]; then
    SUDO=""
    if [ "$(id -u)" != "0" ]; then SUDO=sudo; fi
    $SUDO apt-get update
    $SUDO apt-get install -y libllvm19
fi

echo
echo "Mitsuba installed in $VENV. Before using the llvm_ad_rgb variant run:"
echo "  export DRJIT_LIBLLVM_PATH=$LLVM_LIB"
echo "and use $VENV/bin/python (or: source $VENV/bin/activate)."
