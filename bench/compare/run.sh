#!/usr/bin/env bash
# The comparison with Mitsuba 3 and Embree 4 (bench/compare/compare.py; docs/compare.md).
# Not a test: it prints measured ratios. Arguments go to compare.py (e.g. --quick).
#
# Makes a virtual environment with the pinned packages of requirements.txt under
# target/compare-venv (reused while the pins are unchanged), finds Debian's libllvm19 for
# Mitsuba's llvm_ad_rgb variant (installing it with apt-get when missing) and points
# DRJIT_LIBLLVM_PATH at it, builds the binaries, and runs the comparison.
set -euo pipefail
cd "$(dirname "$0")/../.."

REQ=bench/compare/requirements.txt
VENV=target/compare-venv
PINS="$(grep -v '^#' "$REQ" | tr -s '\n' ' ')"
if [[ ! -x $VENV/bin/python || "$(cat "$VENV/pins" 2>/dev/null)" != "$PINS" ]]; then
    rm -rf "$VENV"
    python3 -m venv "$VENV"
    if ! "$VENV/bin/pip" install --quiet --disable-pip-version-check --retries 2 --timeout 30 \
        -r "$REQ"; then
        rm -rf "$VENV"
        echo "bench/compare: could not install $REQ from PyPI" >&2
        exit 1
    fi
    echo "$PINS" >"$VENV/pins"
fi

find_llvm() {
    local f
    for f in /usr/lib/*/libLLVM-19.so /usr/lib/*/libLLVM.so.19* \
        /usr/lib/llvm-19/lib/libLLVM*.so*; do
        [[ -e $f ]] && { echo "$f"; return 0; }
    done
    return 1
}
if [[ -z "${DRJIT_LIBLLVM_PATH:-}" ]]; then
    if ! LLVM="$(find_llvm)"; then
        echo "bench/compare: installing libllvm19 (Mitsuba's llvm_ad_rgb variant needs it)" >&2
        SUDO=()
        [[ $(id -u) -ne 0 ]] && SUDO=(sudo)
        "${SUDO[@]}" apt-get update -qq
        "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >&2
        if ! LLVM="$(find_llvm)"; then
            echo "bench/compare: libllvm19 installed, but no libLLVM-19.so found" >&2
            exit 1
        fi
    fi
    export DRJIT_LIBLLVM_PATH="$LLVM"
fi

cargo build --release --quiet -p prt-cli --bin bake --bin relight --bin reference \
    -p prt-bench --bin bench
exec "$VENV/bin/python" bench/compare/compare.py "$@"
