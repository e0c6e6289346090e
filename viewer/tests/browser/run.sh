#!/usr/bin/env bash
# The viewer in a real browser (viewer/tests/browser/check.py; docs/viewer.md, "Tests"):
# headless Chromium loads the page of `view` over a small per-pixel bake (cornell at 64x64) and
# a small per-vertex bake (vitrine at one sample), moves sliders and orbits the camera, and
# checks the canvas against `relight`'s PNG of the page's own command. Screenshots go to
# target/viewer-browser/. Arguments go to check.py.
#
# Needs Debian's chromium and chromium-driver: installed with apt-get when missing (no
# browser download). PRT_SKIP_BROWSER=1 skips the check (a machine without them), loudly;
# without it a failed install is an error, so CI cannot pass by silently not checking.
set -euo pipefail
cd "$(dirname "$0")/../../.."

if [[ "${PRT_SKIP_BROWSER:-}" == 1 ]]; then
    echo "viewer browser check: SKIPPED (PRT_SKIP_BROWSER=1): the viewer's page was NOT tested in a browser" >&2
    exit 0
fi

mkdir -p target
if ! command -v chromium >/dev/null || ! command -v chromedriver >/dev/null; then
    echo "viewer browser check: installing chromium and chromium-driver from Debian"
    if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
        chromium chromium-driver; } >target/viewer-browser-apt.log 2>&1; then
        echo "viewer browser check: could not install chromium and chromium-driver (see" \
             "target/viewer-browser-apt.log). On a machine without them set PRT_SKIP_BROWSER=1" \
             "to skip the check." >&2
        exit 1
    fi
fi

cargo build --release --quiet -p prt-cli --bin bake --bin relight -p prt-viewer --bin view
OUT=target/viewer-browser
mkdir -p "$OUT"
target/release/bake scenes/cornell --width 64 --height 64 --spp 4 --out "$OUT/cornell.prtbake" --quiet
target/release/bake scenes/vitrine --spp 1 --out "$OUT/vitrine.prtbake" --quiet --no-checkpoint
exec python3 viewer/tests/browser/check.py --view target/release/view --relight target/release/relight \
    --pixel "$OUT/cornell.prtbake" --pixel-config scenes/cornell \
    --vertex "$OUT/vitrine.prtbake" --vertex-config scenes/vitrine --envs scenes/envmaps \
    --screenshots "$OUT" "$@"
