#!/usr/bin/env bash
# Installs the Debian packages a task needs, only those missing (apt-get; sudo when not root).
#   tools/deps.sh base        compiler, CMake, Eigen, libjpeg-turbo, libpng, Catch2
#   tools/deps.sh bench       + OpenCV (the optional benchmark comparison)
#   tools/deps.sh cross-aarch64 | cross-armhf   cross compiler, target libraries (multiarch), qemu-user
#   tools/deps.sh cross-aarch64-tools | cross-armhf-tools   the cross compiler and qemu-user only
#   tools/deps.sh fuzz        clang and its sanitizer runtimes (libFuzzer)
#   tools/deps.sh tidy        clang, clang-tidy (with run-clang-tidy), clang-format (.ci/tidy.sh)
#   tools/deps.sh video       ffmpeg (ffprobe checks of written videos)
#   tools/deps.sh browser     chromium (report rendering check)
#   tools/deps.sh colmap      COLMAP (the reference solves of tools/figures/colmap_reference.sh)
#   tools/deps.sh clients     Blender and COLMAP (the exports loaded by the real programs, tests/export)
#   tools/deps.sh vm          qemu-system-aarch64 and busybox-static:arm64 (tools/vm/vm.sh)
set -euo pipefail

want=()
add_arch=""
for group in "${@:-base}"; do
  case "$group" in
    base) want+=(g++ make cmake pkg-config libeigen3-dev libturbojpeg0-dev libpng-dev catch2) ;;
    bench) want+=(libopencv-dev) ;;
    cross-aarch64) add_arch=arm64; want+=(g++-aarch64-linux-gnu qemu-user libturbojpeg0-dev:arm64 libpng-dev:arm64) ;;
    cross-armhf) add_arch=armhf; want+=(g++-arm-linux-gnueabihf qemu-user libturbojpeg0-dev:armhf libpng-dev:armhf) ;;
    cross-aarch64-tools) want+=(g++-aarch64-linux-gnu qemu-user) ;;
    cross-armhf-tools) want+=(g++-arm-linux-gnueabihf qemu-user) ;;
    fuzz) want+=(clang libclang-rt-dev) ;;
    tidy) want+=(clang clang-tidy clang-format python3) ;;
    video) want+=(ffmpeg) ;;
    browser) want+=(chromium) ;;
    colmap) want+=(colmap) ;;
    clients) want+=(blender colmap) ;;
    vm) add_arch=arm64; want+=(qemu-system-arm busybox-static:arm64 python3) ;;
    *) echo "deps.sh: unknown group '$group'" >&2; exit 2 ;;
  esac
done

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then sudo_cmd=(sudo); else
    echo "deps.sh: not root and no sudo; install manually: ${want[*]}" >&2; exit 1
  fi
fi

if [ -n "$add_arch" ] && ! dpkg --print-foreign-architectures | grep -qx "$add_arch"; then
  "${sudo_cmd[@]}" dpkg --add-architecture "$add_arch"
  need_update=1
fi

missing=()
for p in "${want[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then missing+=("$p"); fi
done
if [ ${#missing[@]} -eq 0 ] && [ -z "${need_update:-}" ]; then exit 0; fi
if [ ${#missing[@]} -eq 0 ]; then exit 0; fi
echo "deps.sh: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
# Wait for another apt or dpkg run (a parallel build, an unattended upgrade) instead of failing.
lock_wait=(-o DPkg::Lock::Timeout=900)
# A mirror in the middle of a sync serves index files of the wrong size ("File has unexpected
# size ... Mirror sync in progress?", CI 2026-12-06): apt-get update fails for minutes, often
# for an index these packages do not need. So after a failed update, install at once when the
# indexes that did download can provide them (a simulated install succeeds); otherwise retry,
# then install from what did download, which fails clearly if a package or a matching multiarch
# version is missing.
installable() {
  apt-get "${lock_wait[@]}" install -s -qq --no-install-recommends "${missing[@]}" >/dev/null 2>&1
}
for wait_s in 30 60 120 0; do
  if "${sudo_cmd[@]}" apt-get "${lock_wait[@]}" update -qq >&2; then break; fi
  if installable; then
    echo "deps.sh: apt-get update failed in part; the indexes it fetched have the packages" >&2
    break
  fi
  if [ "$wait_s" -eq 0 ]; then
    echo "deps.sh: apt-get update kept failing: installing from the indexes it did fetch" >&2
    break
  fi
  echo "deps.sh: apt-get update failed; retrying in $wait_s s" >&2
  sleep "$wait_s"
done
"${sudo_cmd[@]}" apt-get "${lock_wait[@]}" install -y -qq --no-install-recommends "${missing[@]}" >&2
