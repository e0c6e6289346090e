#!/usr/bin/env bash
# Compares the project's relit images with Mitsuba 3 renders (tests/mitsuba/compare.py; what
# it checks: docs/conventions.md, "Checked against Mitsuba 3"). Makes a virtual environment
# with pinned versions under target/mitsuba-venv (reused while the pins are unchanged), builds
# the binaries (a no-op after `cargo test --release --workspace`), and runs the comparisons
# (compare.py: relit images; background.py: the environment seen directly).
# Arguments go to compare.py (e.g. --plant all, --scenes cornell).
#
# Needs PyPI the first time. PRT_SKIP_MITSUBA=1 skips the check (offline machines); without
# it a failed install is an error, so CI cannot pass by silently not comparing.
set -euo pipefail
cd "$(dirname "$0")/../.."

if [[ "${PRT_SKIP_MITSUBA:-}" == 1 ]]; then
    echo "tests/mitsuba: skipped (PRT_SKIP_MITSUBA=1)"
    exit 0
fi

# Exact versions: a new Mitsuba may change its sampling or plugin defaults, and the bounds in
# compare.py were measured with these.
PINS="mitsuba==3.9.1 drjit==1.5.0 numpy==2.4.6"
VENV=target/mitsuba-venv
if [[ ! -x $VENV/bin/python || "$(cat "$VENV/pins" 2>/dev/null)" != "$PINS" ]]; then
    rm -rf "$VENV"
    python3 -m venv "$VENV"
    # shellcheck disable=SC2086  # PINS is a list of words
    if ! "$VENV/bin/pip" install --quiet --disable-pip-version-check --retries 2 --timeout 30 \
        $PINS; then
        rm -rf "$VENV"
        echo "tests/mitsuba: could not install $PINS from PyPI. On a machine without network" \
             "access set PRT_SKIP_MITSUBA=1 to skip the Mitsuba comparison." >&2
        exit 1
    fi
    echo "$PINS" >"$VENV/pins"
fi

cargo build --release --quiet -p prt-cli --bin bake --bin relight --bin reference
"$VENV/bin/python" tests/mitsuba/compare.py "$@"
# The environment seen directly (bilinear lookups), a few seconds.
exec "$VENV/bin/python" tests/mitsuba/background.py
