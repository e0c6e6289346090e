#!/usr/bin/env bash
# Interleaved A/B of two `relight` builds on the same bake files (docs/compare.md): each round
# runs A then B on every file (`relight --repeat FRAMES --json`), and the medians over rounds
# of each build's median frame time are printed with their ratio, and whether the two builds
# wrote the same image (byte for byte) of each file.
#
#   bench/relight-ab.sh [--rounds N] [--frames N] RELIGHT_A RELIGHT_B BAKE...
set -euo pipefail
ROUNDS=5
FRAMES=200
while [[ $# -gt 0 && $1 == --* ]]; do
    case $1 in
    --rounds) ROUNDS=$2; shift 2 ;;
    --frames) FRAMES=$2; shift 2 ;;
    *) echo "relight-ab: unknown option $1" >&2; exit 2 ;;
    esac
done
if [[ $# -lt 3 ]]; then
    echo "usage: bench/relight-ab.sh [--rounds N] [--frames N] RELIGHT_A RELIGHT_B BAKE..." >&2
    exit 2
fi
A=$1 B=$2
shift 2
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
for ((r = 0; r < ROUNDS; r++)); do
    for f in "$@"; do
        for side in A B; do
            bin=$A
            [[ $side == B ]] && bin=$B
            name=$(basename "$f")
            ms=$("$bin" "$f" --repeat "$FRAMES" --json --out "$WORK/$side-$name.exr" |
                python3 -c 'import json,sys; print(json.loads(sys.stdin.read().strip().splitlines()[-1])["seconds_per_frame_median"] * 1e3)')
            echo "$side $name $ms" >>"$WORK/times"
        done
    done
done
python3 - "$WORK" "$@" <<'PY'
import os, statistics, sys
work, files = sys.argv[1], [os.path.basename(f) for f in sys.argv[2:]]
t = {}
for line in open(os.path.join(work, "times")):
    side, name, ms = line.split()
    t.setdefault((side, name), []).append(float(ms))
print("| bake | A (ms, median of rounds) | B (ms) | B / A | same image |")
print("|---|---|---|---|---|")
for n in files:
    a, b = statistics.median(t[("A", n)]), statistics.median(t[("B", n)])
    same = open(os.path.join(work, "A-%s.exr" % n), "rb").read() == \
        open(os.path.join(work, "B-%s.exr" % n), "rb").read()
    print("| %s | %.3f | %.3f | %.3f | %s |" % (n, a, b, b / a, "yes" if same else "NO"))
PY
