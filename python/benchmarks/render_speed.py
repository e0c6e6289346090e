"""render() from Python against the same frame from Rust (the `relight` tool's --repeat timing),
interleaved: each round times the tool's median frame, then Python's median render() into a
new array and into a caller's array (`out=`), in this order, so drifts in the shared machine's
load fall on both. Prints each round and the median ratios (Python / Rust).

The Rust figure is the runtime's own time per frame (inside render_into); the Python figure
is the wall time of the whole call (argument parsing, the array's allocation, releasing and
taking the interpreter's lock), so the ratio is the binding's whole cost.

    python python/benchmarks/render_speed.py BAKE [--rounds 9] [--frames 60]

BAKE: a per-pixel bake, e.g. `bake scenes/cornell --width 512 --height 512 --spp 1`.
"""

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import prt

ROOT = Path(__file__).resolve().parents[2]


def rust_median(relight, bake, frames):
    with tempfile.TemporaryDirectory() as tmp:
        done = subprocess.run(
            [relight, bake, "--repeat", str(frames), "--json", "--out", f"{tmp}/frame.exr"],
            capture_output=True, text=True, check=True,
        )
    return json.loads(done.stdout)["seconds_per_frame_median"]


def python_median(r, frames, out=None):
    times = []
    for _ in range(frames):
        t = time.perf_counter()
        r.render(out=out)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bake", type=Path)
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--frames", type=int, default=60)
    args = parser.parse_args()
    subprocess.run(["cargo", "build", "--release", "--quiet", "-p", "prt-cli", "--bin", "relight"],
                   cwd=ROOT, check=True)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    relight = target / "release" / "relight"
    r = prt.open(args.bake)
    if not isinstance(r, prt.PixelRelighter):
        parser.error(f"{args.bake} is not a per-pixel bake")
    w, h = r.size
    out = np.empty((h, w, 3), np.float32)
    r.render(out=out)  # warm: pages of the bake file and of the array
    ratios_new, ratios_out = [], []
    print(f"{args.bake}: {w}x{h}, {args.frames} frames a measurement")
    print("round  rust ms  python ms (new)  python ms (out=)  ratio new  ratio out=")
    for k in range(args.rounds):
        rust = rust_median(relight, args.bake, args.frames)
        new = python_median(r, args.frames)
        into = python_median(r, args.frames, out)
        ratios_new.append(new / rust)
        ratios_out.append(into / rust)
        print(f"{k:5}  {rust * 1e3:7.2f}  {new * 1e3:15.2f}  {into * 1e3:16.2f}"
              f"  {new / rust:9.3f}  {into / rust:10.3f}")
    print(f"median ratio Python / Rust: {statistics.median(ratios_new):.3f} (new array), "
          f"{statistics.median(ratios_out):.3f} (out=)")


if __name__ == "__main__":
    main()
