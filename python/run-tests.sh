#!/usr/bin/env bash
# Builds the prt Python package from source into a virtual environment (target/python-venv,
# made on first use) and runs its tests (python/tests, pytest): what .ci/run runs and the
# README's command. Arguments go to pytest (e.g. -k threads, -x).
#
# Needs PyPI the first time (maturin, numpy, pytest). PRT_SKIP_PYTHON=1 skips the check
# (offline machines); without it a failed install is an error, so CI cannot pass by silently
# not testing.
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ "${PRT_SKIP_PYTHON:-}" == 1 ]]; then
    echo "python: SKIPPED (PRT_SKIP_PYTHON=1): the Python package was not built or tested" >&2
    exit 0
fi

VENV=target/python-venv
# maturin builds the extension with cargo into the workspace's target/ (no isolated build
# environment, so a CI run reuses the libraries `cargo test --release --workspace` built).
PINS="maturin==1.16.0 numpy==2.4.6 pytest==9.2.0"
if [[ ! -x $VENV/bin/python || "$(cat "$VENV/pins" 2>/dev/null)" != "$PINS" ]]; then
    rm -rf "$VENV"
    python3 -m venv "$VENV"
    # shellcheck disable=SC2086  # PINS is a list of words
    if ! "$VENV/bin/pip" install --quiet --disable-pip-version-check --retries 2 --timeout 30 \
        $PINS; then
        rm -rf "$VENV"
        echo "python: could not install $PINS from PyPI. On a machine without network access" \
             "set PRT_SKIP_PYTHON=1 to skip the Python package's tests." >&2
        exit 1
    fi
    echo "$PINS" >"$VENV/pins"
fi

# maturin's build backend runs the maturin program from PATH.
export PATH="$PWD/$VENV/bin:$PATH"
# The package as a user installs it (`pip install ./python`), built from source.
"$VENV/bin/pip" install --quiet --disable-pip-version-check --no-build-isolation \
    --no-deps --force-reinstall ./python
# From outside the source folder, so the tests import the installed package.
cd python/tests
exec "../../$VENV/bin/python" -m pytest -q -p no:cacheprovider "$@"
