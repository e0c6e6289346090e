#!/usr/bin/env bash
# The GPU backend's figures against the goals of docs/gpu.md ("Measured"): prints the adapter
# and, per vertex (scenes/gallery, 46K vertices, 512x512), view / view + BRDF / view + BRDF +
# light frame times; per pixel (scenes/cornell at 512x512, f32 and f16, full and low-rank) the
# frame against the device's bandwidth bound plus its fixed overhead; each beside the same
# frames on the fallback adapter (lavapipe, where installed) and on the CPU runtime.
#
#   bench/gpu.sh --prepare   build here: `bake` and `bench` (with the GPU feature), stripped,
#                            and the Vulkan loader, into target/gpu-carry/ (about 25 MB)
#   bench/gpu.sh             bake the two scenes (under target/gpu-bench/, reused when
#                            present), run `bench gpu` on them, then check their GPU frames
#                            against the CPU runtime's (`bench gpu --agreement`)
#
# On a machine without network or cargo (a lent GPU machine), carry target/gpu-carry/ there
# and run `PRT_BIN=target/gpu-carry bench/gpu.sh`: it needs nothing else but the working tree
# (scenes/) and the machine's GPU driver. PRT_GPU_FRAMES sets the frames per measurement.
set -euo pipefail
cd "$(dirname "$0")/.."

CARRY=target/gpu-carry
if [[ "${1:-}" == --prepare ]]; then
    cargo build --release -p prt-cli --bin bake
    cargo build --release -p prt-bench --features gpu --bin bench
    mkdir -p "$CARRY/lib"
    strip -o "$CARRY/bake" target/release/bake
    strip -o "$CARRY/bench" target/release/bench
    # The Vulkan loader, for a machine whose driver came without it. (awk reads all of
    # ldconfig's output: an early exit would kill ldconfig with SIGPIPE, which pipefail and
    # set -e turn into a silent exit of this script.)
    loader=$(ldconfig -p | awk '/libvulkan\.so\.1 / && !found {print $NF; found = 1}')
    if [[ -n "$loader" ]]; then cp -L "$loader" "$CARRY/lib/libvulkan.so.1"; fi
    du -sh "$CARRY"
    exit 0
fi

BIN=${PRT_BIN:-target/release}
OUT=target/gpu-bench
FRAMES=${PRT_GPU_FRAMES:-60}
if [[ ! -x $BIN/bake || ! -x $BIN/bench ]]; then
    echo "bench/gpu.sh: $BIN/bake or $BIN/bench missing: run bench/gpu.sh --prepare first" >&2
    exit 1
fi
mkdir -p "$OUT"

# Vulkan: the machine's loader, else the carried one; the machine's ICD files, else an NVIDIA
# one written here when the NVIDIA driver's library is present.
if ! ldconfig -p | grep 'libvulkan\.so\.1 ' >/dev/null && [[ -f $BIN/lib/libvulkan.so.1 ]]; then
    export LD_LIBRARY_PATH="$PWD/$BIN/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    echo "using the carried Vulkan loader"
fi
icds=$(ls /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json 2>/dev/null || true)
if ! grep -qi nvidia <<<"$icds" && ldconfig -p | grep libGLX_nvidia.so.0 >/dev/null; then
    cat >"$OUT/nvidia_icd.json" <<'EOF'
{"file_format_version": "1.0.0", "ICD": {"library_path": "libGLX_nvidia.so.0", "api_version": "1.3"}}
EOF
    export VK_ADD_DRIVER_FILES="$PWD/$OUT/nvidia_icd.json"
    echo "wrote an NVIDIA Vulkan ICD file (none was installed)"
fi
echo "Vulkan ICD files: ${icds:-none}"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null || true

# The bakes (reused when present): gallery per vertex with its committed config; cornell per
# pixel at 512x512 (few samples: the frame's cost does not depend on them).
[[ -f $OUT/gallery.prtbake ]] ||
    "$BIN/bake" scenes/gallery/bake.toml --out "$OUT/gallery.prtbake" --quiet --no-checkpoint
for p in f32 f16; do
    [[ -f $OUT/cornell-$p.prtbake ]] ||
        "$BIN/bake" scenes/cornell/bake.toml --width 512 --height 512 --spp 8 --precision "$p" \
            --compress-rank 8 --out "$OUT/cornell-$p.prtbake" --quiet
done

"$BIN/bench" gpu --vertex "$OUT/gallery.prtbake" --pixel "$OUT/cornell-f32.prtbake" \
    --pixel "$OUT/cornell-f16.prtbake" --frames "$FRAMES" "${@}"
# The same bakes' GPU frames against the CPU runtime's (docs/gpu.md, "Agreement on the example
# scenes").
"$BIN/bench" gpu --agreement "$OUT/gallery.prtbake" "$OUT/cornell-f32.prtbake" \
    "$OUT/cornell-f16.prtbake"
