#!/usr/bin/env bash
# CI stage: the live path on a real Linux kernel. Boots Debian's arm64 kernel under
# qemu-system-aarch64 (tools/vm/vm.sh) and runs tools/vm/checks.sh inside it against the kernel's
# vivid V4L2 driver with the cross-built epitrack-device: capture in GREY and YUYV at two sizes and
# rates, MJPEG and an unoffered size refused, SIGINT, zero allocations per frame, a camera faster
# than the processing, a rendered clip through vivid's video loop matched pixel for pixel, the
# rendered clip and (with ../shared/data) the KITTI excerpt tracked live through the loop and
# compared with the same binary's replay of the same frames from file, ATE against their ground
# truth on the host, the device removed mid-stream. About 8 min on a clean clone on 2 loaded cores
# (the two live clips wait for the emulated tracker on every frame); see docs/device.md, "Testing
# on a real kernel".
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$root/tools/vm/vm.sh" --build-dir "$root/build/vm"
