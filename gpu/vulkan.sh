#!/usr/bin/env bash
# Makes sure a Vulkan driver is installed for the GPU backend's tests (gpu/tests/frames.rs):
# on a machine with none (CI has no GPU), installs Mesa's software driver lavapipe (Debian:
# mesa-vulkan-drivers, libvulkan1). `.ci/run` calls it before the workspace's tests.
#
# PRT_SKIP_GPU=1 skips the install, and the GPU tests then skip themselves with a line on
# stderr (a machine without any Vulkan driver and without the package registry); without it a
# failed install is an error, so CI cannot pass by silently not comparing.
set -euo pipefail

if [[ "${PRT_SKIP_GPU:-}" == 1 ]]; then
    echo "gpu/vulkan.sh: skipped (PRT_SKIP_GPU=1): the GPU frame tests will not run" >&2
    exit 0
fi
# grep without -q reads all of ldconfig's output: -q would stop early, ldconfig would die of
# SIGPIPE and pipefail would report no driver where there is one.
has_driver() {
    ldconfig -p | grep 'libvulkan\.so\.1 ' >/dev/null || return 1
    # Either folder may be missing (ls of both would then fail though the other holds one).
    local icd
    for icd in /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json; do
        [[ -f $icd ]] && return 0
    done
    return 1
}
if has_driver; then
    exit 0
fi
echo "gpu/vulkan.sh: no Vulkan driver; installing lavapipe (mesa-vulkan-drivers libvulkan1)" >&2
SUDO=""
if [[ $(id -u) != 0 ]]; then SUDO=sudo; fi
if ! { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq \
    mesa-vulkan-drivers libvulkan1 >/dev/null; } || ! has_driver; then
    echo "gpu/vulkan.sh: could not install a Vulkan driver. Install mesa-vulkan-drivers and" \
         "libvulkan1, or set PRT_SKIP_GPU=1 to skip the GPU tests." >&2
    exit 1
fi
