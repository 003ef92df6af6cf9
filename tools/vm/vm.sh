#!/usr/bin/env bash
# Boots an emulated aarch64 board (qemu-system-aarch64 -M virt -cpu cortex-a72, no KVM) on
# Debian's arm64 kernel with its vivid V4L2 test driver, and runs tools/vm/checks.sh inside it
# against the real driver with the cross-built epitrack-device. Everything comes from Debian
# packages: the kernel (the exact linux-image-*-arm64 that linux-image-arm64 depends on, fetched
# with `apt-get download` and unpacked with `dpkg -x`), busybox-static:arm64 for the initramfs,
# the aarch64 cross compiler and multiarch libraries (tools/cross.sh). Downloads are cached in
# BUILD_DIR/cache. Results come back on the serial console (lines starting with VM); the log is
# BUILD_DIR/console.log.
#   tools/vm/vm.sh [--build-dir DIR] [--induce NAME] [--timeout S] [--no-clip]
#     --build-dir DIR  work directory (default: build/vm)
#     --induce NAME    make one check fail on purpose (wrong-format, lost-frame, alloc, pixels,
#                      live-pose, ate): the run must then fail, which shows that it can fail
#     --timeout S      give up on the VM after S seconds (default 1800)
#     --no-clip        leave out the clip-through-the-kernel check (vivid's video loop)
# Exit: 0 every check passed, 1 a check failed or was missing, 2 bad usage or a missing package.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build=$root/build/vm
induce=""
clip=1
timeout_s=1800
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build=$(realpath -m "$2"); shift 2 ;;
    --induce) induce=$2; shift 2 ;;
    --timeout) timeout_s=$2; shift 2 ;;
    --no-clip) clip=0; shift ;;
    -h | --help) sed -n '2,16p' "${BASH_SOURCE[0]}"; exit 0 ;;
    *) echo "vm.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
t_start=$SECONDS
die() { echo "vm.sh: $*" >&2; exit 2; }

# ---- host tools ----
"$root/tools/deps.sh" cross-aarch64 vm >/dev/null
command -v qemu-system-aarch64 >/dev/null ||
  die "qemu-system-aarch64 is missing: apt-get install qemu-system-arm"
for tool in apt-get apt-cache dpkg python3 gzip timeout aarch64-linux-gnu-gcc aarch64-linux-gnu-readelf; do
  command -v "$tool" >/dev/null || die "'$tool' is missing"
done

# ---- packages: cached .deb files, unpacked once ----
cache=$build/cache
mkdir -p "$cache"
# fetch PACKAGE: BUILD_DIR/cache/PACKAGE_*.deb, downloaded when absent.
fetch() {
  local pkg=$1 name=${1%%:*} deb
  deb=$(ls "$cache/${name}"_*_arm64.deb 2>/dev/null | head -n 1 || true)
  if [ -z "$deb" ]; then
    (cd "$cache" && apt-get download "$pkg" >/dev/null 2>"$cache/apt.err") || die \
      "cannot download the Debian package '$pkg' ($(tail -n 1 "$cache/apt.err")); it needs the arm64 architecture in apt (dpkg --add-architecture arm64 && apt-get update)"
    deb=$(ls "$cache/${name}"_*_arm64.deb | head -n 1)
  fi
  echo "$deb"
}
# The kernel: the exact package the metapackage points to (a glob would fetch every version).
kernel_pkg=$(apt-cache depends linux-image-arm64:arm64 2>/dev/null |
  sed -n 's/^ *Depends: \(linux-image-[0-9][^:]*-arm64\).*/\1/p' | head -n 1)
[ -n "$kernel_pkg" ] || die "apt knows no linux-image-arm64:arm64 (dpkg --add-architecture arm64 && apt-get update)"
kernel_deb=$(fetch "$kernel_pkg:arm64")
busybox_deb=$(fetch busybox-static:arm64)
kdir=$cache/${kernel_pkg}
if [ ! -d "$kdir/boot" ]; then
  rm -rf "$kdir.tmp" && dpkg -x "$kernel_deb" "$kdir.tmp" && mv "$kdir.tmp" "$kdir"
fi
bdir=$cache/busybox
if [ ! -x "$bdir/bin/busybox" ]; then
  rm -rf "$bdir.tmp" && dpkg -x "$busybox_deb" "$bdir.tmp" && mv "$bdir.tmp" "$bdir"
fi
kver=$(ls "$kdir/lib/modules" | head -n 1)
vmlinuz=$kdir/boot/vmlinuz-$kver
[ -f "$vmlinuz" ] || die "no kernel image in $kernel_deb"

# ---- the programs, cross-built ----
# The cross stage's build directory: in CI the programs are already built there.
cross=${EPITRACK_CROSS_BUILD_DIR:-$root/build/cross-aarch64}
EPITRACK_BUILD_TARGETS="epitrack-device epitrack-record" EPITRACK_JOBS=${EPITRACK_JOBS:-2} \
  "$root/tools/cross.sh" aarch64 "$cross" >"$build/cross.log" 2>&1 ||
  { tail -n 30 "$build/cross.log" >&2; echo "vm.sh: the cross-build failed ($build/cross.log)" >&2; exit 1; }
aarch64-linux-gnu-gcc -O2 -Wall -Wextra -Werror -shared -fPIC -o "$build/alloc_count.so" \
  "$root/tools/vm/alloc_count.c"
aarch64-linux-gnu-gcc -O2 -Wall -Wextra -Werror -static -o "$build/vivid-loop" \
  "$root/tools/vm/vivid_loop.c"
# The clip for the loop check: rendered natively (seeded), as raw gray frames plus each frame's md5.
native=${EPITRACK_BUILD_DIR:-$root/build/test}
[ -f "$native/CMakeCache.txt" ] || cmake -S "$root" -B "$native" -DCMAKE_BUILD_TYPE=Release \
  -DEPITRACK_WERROR=ON -DEPITRACK_BUILD_TESTS=ON >/dev/null
cmake --build "$native" -j "${EPITRACK_JOBS:-2}" --target epitrack-synth epitrack-eval epitrack-record \
  >"$build/synth.log" 2>&1 ||
  { tail -n 20 "$build/synth.log" >&2; echo "vm.sh: building epitrack-synth/eval/record failed" >&2; exit 1; }
clip_src=$build/clip-src
if [ ! -f "$clip_src/groundtruth.txt" ]; then
  rm -rf "$clip_src"
  "$native/tools/synth/epitrack-synth" --size 720x576 --frames 40 --seed 1 --threads 2 --quiet \
    --out "$clip_src"
fi

# ---- the initramfs ----
rootfs=$build/rootfs
rm -rf "$rootfs"
mkdir -p "$rootfs"/{bin,sbin,lib,modules,proc,sys,dev,tmp,etc}
cp "$bdir/bin/busybox" "$rootfs/bin/busybox"
install -m 755 "$root/tools/vm/init.sh" "$rootfs/init"
install -m 755 "$root/tools/vm/checks.sh" "$rootfs/checks.sh"
for m in rc-core cec mc videodev videobuf2-common videobuf2-v4l2 videobuf2-memops \
  videobuf2-vmalloc videobuf2-dma-contig v4l2-tpg v4l2-dv-timings vivid; do
  ko=$(find "$kdir/lib/modules/$kver" -name "$m.ko" | head -n 1)
  [ -n "$ko" ] || die "module $m.ko is not in $kernel_pkg"
  cp "$ko" "$rootfs/modules/"
done
install -m 755 "$cross/firmware_like/epitrack-device" "$cross/tools/record/epitrack-record" "$rootfs/bin/"
cp "$build/alloc_count.so" "$rootfs/lib/"
cp "$build/vivid-loop" "$rootfs/bin/"
mkdir -p "$rootfs/clip"
cp "$clip_src/groundtruth.txt" "$clip_src/intrinsics.txt" "$rootfs/clip/"
# clip_frames SRC_DIR DST_DIR CROP_X PAD_Y: the PGM frames of SRC_DIR as one raw 720x576 gray file
# (clip.gray) and each frame's md5 (clip.md5): columns CROP_X.. of each frame, placed at row PAD_Y
# of a black 720x576 frame (vivid's S-Video size, the loop's only size here).
clip_frames() {
  python3 - "$@" <<'EOF'
import hashlib, os, sys
src, dst, crop_x, pad_y = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
W, H = 720, 576
with open(os.path.join(dst, "clip.gray"), "wb") as raw, open(os.path.join(dst, "clip.md5"), "w") as sums:
    for name in sorted(n for n in os.listdir(src) if n.endswith(".pgm")):
        data = open(os.path.join(src, name), "rb").read()
        # binary PGM: "P5", width, height, maxval, one whitespace byte, then the pixels
        fields, pos = [], 0
        while len(fields) < 4:
            while data[pos:pos + 1].isspace(): pos += 1
            start = pos
            while not data[pos:pos + 1].isspace(): pos += 1
            fields.append(data[start:pos])
        w, h = int(fields[1]), int(fields[2])
        pixels = data[pos + 1:]
        assert fields[0] == b"P5" and len(pixels) == w * h, name
        assert crop_x + W <= w and pad_y + h <= H, name
        frame = bytearray(W * H)
        for y in range(h):
            frame[(pad_y + y) * W:(pad_y + y + 1) * W] = pixels[y * w + crop_x:y * w + crop_x + W]
        raw.write(frame)
        sums.write(hashlib.md5(frame).hexdigest() + "\n")
EOF
}
clip_frames "$clip_src/frames" "$rootfs/clip" 0 0
# The KITTI excerpt for the live check, when the shared data is there: the centre 720 columns of
# its 1226x370 frames at rows 103-472, the principal point moved with them.
kitti=0
data=${EPITRACK_SHARED_DATA:-$root/../shared/data}
kitti_src=$data/kitti_seq06_excerpt
if [ "$clip" = 1 ] && [ -d "$kitti_src/frames" ]; then
  kitti=1
  kitti_pgm=$build/kitti-pgm
  if [ ! -f "$kitti_pgm.done" ]; then
    rm -rf "$kitti_pgm"
    "$native/tools/record/epitrack-record" "$kitti_src/frames" --out "$kitti_pgm" --quiet
    touch "$kitti_pgm.done"
  fi
  mkdir -p "$rootfs/kitti"
  clip_frames "$kitti_pgm" "$rootfs/kitti" 253 103
  awk '!/^#/ && NF >= 6 { printf "%s %s %.6f %.6f 720 576\n", $1, $2, $3 - 253, $4 + 103; exit }' \
    "$kitti_src/intrinsics.txt" >"$rootfs/kitti/intrinsics.txt"
elif [ "$clip" = 1 ]; then
  echo "vm.sh: SKIP kitti-live: $kitti_src not found (the KITTI excerpt of ../shared/data; EPITRACK_SHARED_DATA)"
fi
# Shared libraries: the NEEDED entries, recursively, from the cross toolchain's and the multiarch
# directories; all in /lib, with the loader at the path the binaries name.
libdirs=(/usr/aarch64-linux-gnu/lib /usr/lib/aarch64-linux-gnu /lib/aarch64-linux-gnu)
pending=("$rootfs/bin/epitrack-device" "$rootfs/bin/epitrack-record")
while [ ${#pending[@]} -gt 0 ]; do
  elf=${pending[0]}
  pending=("${pending[@]:1}")
  for lib in $(aarch64-linux-gnu-readelf -d "$elf" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p'); do
    [ -e "$rootfs/lib/$lib" ] && continue
    found=""
    for d in "${libdirs[@]}"; do
      if [ -e "$d/$lib" ]; then found=$d/$lib; break; fi
    done
    [ -n "$found" ] || die "the aarch64 library $lib is missing (tools/deps.sh cross-aarch64)"
    cp -L "$found" "$rootfs/lib/$lib"
    pending+=("$rootfs/lib/$lib")
  done
done
cp -L /usr/aarch64-linux-gnu/lib/ld-linux-aarch64.so.1 "$rootfs/lib/"
initrd=$build/initramfs.cpio.gz
# newc cpio archive (the kernel's initramfs format), written here: no cpio on the build host.
python3 - "$rootfs" "$initrd.tmp" <<'EOF'
import gzip, os, stat, sys
root, out = sys.argv[1], sys.argv[2]
def entry(f, ino, name, mode, data=b"", nlink=1):
    name_b = name.encode() + b"\0"
    hdr = "070701" + "".join("%08X" % v for v in (ino, mode, 0, 0, nlink, 0, len(data), 0, 0, 0, 0, len(name_b), 0))
    f.write(hdr.encode() + name_b)
    f.write(b"\0" * ((4 - (110 + len(name_b)) % 4) % 4))
    f.write(data)
    f.write(b"\0" * ((4 - len(data) % 4) % 4))
with gzip.open(out, "wb", compresslevel=6) as f:
    ino = 1
    for d, dirs, files in os.walk(root):
        dirs.sort()
        rel = os.path.relpath(d, root)
        if rel != ".":
            entry(f, ino, rel, stat.S_IFDIR | 0o755, nlink=2); ino += 1
        for n in sorted(files):
            p = os.path.join(d, n)
            data = open(p, "rb").read()
            mode = stat.S_IFREG | (0o755 if os.access(p, os.X_OK) else 0o644)
            entry(f, ino, os.path.normpath(os.path.join(rel, n)), mode, data); ino += 1
    entry(f, 0, "TRAILER!!!", 0)
EOF
mv "$initrd.tmp" "$initrd"
echo "vm.sh: kernel $kver, initramfs $(du -k "$initrd" | cut -f1) KiB, prepared in $((SECONDS - t_start)) s"

# ---- boot and run the checks ----
# Two virtual CPUs: with one, vivid's kernel threads (the 720x576 output->capture loop at 25 fps)
# took most of it and the tracker ran 1.4-1.9 s a frame instead of 0.2-0.3 s (EPITRACK_VM_SMP).
log=$build/console.log
append="console=ttyAMA0 rdinit=/init quiet loglevel=3 panic=-1"
[ -z "$induce" ] || append+=" vmcheck.induce=$induce"
[ "$clip" = 0 ] || append+=" vmcheck.clip=1"
t_boot=$SECONDS
set +e
timeout "$timeout_s" qemu-system-aarch64 -M virt -cpu cortex-a72 -smp "${EPITRACK_VM_SMP:-2}" -m 1024 -nographic \
  -no-reboot -nic none -kernel "$vmlinuz" -initrd "$initrd" -append "$append" </dev/null \
  >"$log" 2>&1
qrc=$?
set -e
tr -d '\r' <"$log" >"$log.txt"
grep '^VM' "$log.txt" || true
echo "vm.sh: VM ran $((SECONDS - t_boot)) s wall (qemu exit $qrc), whole run $((SECONDS - t_start)) s"
if [ $qrc -ne 0 ] || ! grep -q '^VMDONE' "$log.txt"; then
  tail -n 20 "$log.txt" >&2
  echo "vm.sh: the VM did not finish its checks (qemu exit $qrc; log $log.txt)" >&2
  exit 1
fi
expected="capture-grey-320x180-30 capture-grey-640x480-15 capture-yuyv-320x180-30
  capture-yuyv-640x480-15 mjpeg-refused size-refused sigint zero-alloc slow-consumer device-removed"
[ "$clip" = 0 ] || expected+=" clip-loop clip-live"
[ "$kitti" = 0 ] || expected+=" kitti-live"
failed=0
for name in $expected; do
  line=$(grep "^VMCHECK $name " "$log.txt" | head -n 1)
  case "$line" in
    *" PASS"*) ;;
    "") echo "vm.sh: check $name did not run" >&2; failed=1 ;;
    *) echo "vm.sh: check $name failed" >&2; failed=1 ;;
  esac
done
if grep -q '^VMCHECK .* FAIL' "$log.txt"; then failed=1; fi
# The clips tracked live, scored on the host against their ground truth (epitrack-eval), next to
# the same binary's replay of the whole clip from file (each frame once). The live track sees each
# clip frame one to HOLD times, so it is not the file replay's track (checks.sh compares the live
# track exactly with a replay of the same frames); the bounds here are the measured ATEs with
# margin (docs/device.md, "Testing on a real kernel").
# score NAME GROUNDTRUTH MIN_MATCHED MAX_ATE_RMSE_REL KINDS
score() {
  local name=$1 gt=$2 min_matched=$3 max_rel=$4 kinds=$5 kind result verdict
  for kind in $kinds; do
    sed -n "s/^VMDATA $name-$kind-tum //p" "$log.txt" >"$build/$name-$kind.tum"
    if [ "$induce" = ate ] && [ "$kind" = live ]; then # one pose moved far off
      awk 'NR == 10 { $2 += 1000 } { print }' "$build/$name-$kind.tum" >"$build/$name-$kind.tum.x"
      mv "$build/$name-$kind.tum.x" "$build/$name-$kind.tum"
    fi
    # The JSON is stdout; stderr may carry a note (a thin path's alignment), kept apart.
    result=$("$native/tools/eval/epitrack-eval" --gt "$gt" --est "$build/$name-$kind.tum" \
      2>"$build/$name-$kind.eval.err") ||
      result="epitrack-eval failed: $result $(cat "$build/$name-$kind.eval.err")"
    echo "VMATE $name-$kind $result"
    verdict=$(echo "$result" | awk -v min_m="$min_matched" -v max_r="$max_rel" '{
        r = $0; sub(/.*"ate_rmse_rel": /, "", r); sub(/[,}].*/, "", r)
        m = $0; sub(/.*"matched_frames": /, "", m); sub(/[,}].*/, "", m)
        if (r == $0 || m == $0 || m + 0 < min_m + 0 || r + 0 > max_r + 0) {
          printf "FAIL ate_rmse_rel %s over %s frames (bounds: <= %s over >= %s)\n", r, m, max_r, min_m; exit }
        printf "PASS ate_rmse_rel %s over %s frames (bounds: <= %s over >= %s)\n", r, m, max_r, min_m }')
    echo "VMCHECK $name-$kind-ate $verdict"
    case "$verdict" in PASS*) ;; *) failed=1 ;; esac
  done
}
[ "$clip" = 0 ] || score clip "$clip_src/groundtruth.txt" 28 0.002 "live file"
[ "$kitti" = 0 ] || score kitti "$kitti_src/groundtruth.txt" 45 0.01 "live file"
if [ $failed -ne 0 ]; then
  echo "vm.sh: FAILED (log $log.txt)" >&2
  exit 1
fi
echo "vm.sh: all $(echo $expected | wc -w) checks passed"
