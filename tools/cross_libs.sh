#!/usr/bin/env bash
# Downloads the target's libjpeg-turbo, libpng and zlib as Debian packages and unpacks them into a
# directory, for a cross build that links them there (toolchains/linux-cross-common.cmake,
# -DEPITRACK_TARGET_LIBS=DIR) instead of installing them through multiarch.
#   tools/cross_libs.sh aarch64|armhf DIR
# Why: multiarch installs a library of one version for every architecture ("Multi-Arch: same"), so
# libc6:armhf must be the build machine's own libc6 revision. When the mirror serves the native
# security update but not the target's (CI 2026-12-06: the armhf security index of the wrong size,
# "Mirror sync in progress?"), apt cannot install the target libraries at all. Unpacked beside the
# cross compiler's own C library (libc6-<arch>-cross) no version has to match. The packages are
# the candidates of the indexes that did download; apt-get download needs no root, adding the
# architecture and refreshing the indexes does (sudo when not root).
set -euo pipefail

usage() { echo "usage: tools/cross_libs.sh aarch64|armhf DIR" >&2; exit 2; }
[ $# -eq 2 ] || usage
case "$1" in
  aarch64) deb_arch=arm64 ;;
  armhf) deb_arch=armhf ;;
  *) echo "cross_libs.sh: unknown architecture '$1' (aarch64 or armhf)" >&2; exit 2 ;;
esac
dir=$(realpath -m "$2")

sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
if ! dpkg --print-foreign-architectures | grep -qx "$deb_arch"; then
  "${sudo_cmd[@]}" dpkg --add-architecture "$deb_arch"
  need_update=1
fi
packages=(libturbojpeg0 libturbojpeg0-dev libpng16-16 libpng-dev zlib1g zlib1g-dev)
if [ -n "${need_update:-}" ] || ! apt-cache show "libpng-dev:$deb_arch" >/dev/null 2>&1; then
  # One attempt: a partly failed update still leaves the indexes that downloaded, and the main
  # archive's are all this needs.
  "${sudo_cmd[@]}" apt-get -o DPkg::Lock::Timeout=900 update -qq >&2 ||
    echo "cross_libs.sh: apt-get update failed in part; using the indexes it fetched" >&2
fi

rm -rf "$dir"
mkdir -p "$dir/debs"
(cd "$dir/debs" && apt-get download -qq "${packages[@]/%/:$deb_arch}")
for deb in "$dir"/debs/*.deb; do
  dpkg -x "$deb" "$dir"
  echo "cross_libs.sh: unpacked $(basename "$deb")" >&2
done
# Absolute links (zlib's libz.so -> /lib/<triple>/libz.so.1...) would point into the build
# machine: point them inside DIR.
find "$dir" -type l -lname '/*' | while read -r link; do
  ln -sfn "$dir$(readlink "$link")" "$link"
done
for lib in libturbojpeg.so libpng16.so libz.so; do
  found=$(find "$dir/usr/lib" "$dir/lib" -name "$lib" | head -1)
  [ -e "$found" ] || { echo "cross_libs.sh: $lib missing after unpacking into $dir" >&2; exit 1; }
done
echo "cross_libs.sh: $deb_arch libraries in $dir"
