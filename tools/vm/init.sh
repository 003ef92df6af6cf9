#!/bin/busybox sh
# /init of the VM's initramfs (built by tools/vm/vm.sh): mounts the kernel file systems, loads the
# media modules vivid needs in dependency order, runs /checks.sh and powers off. Every line for
# the host starts with "VM" (VMBOOT, VMCHECK, VMDATA, VMDONE) on the serial console.
/bin/busybox --install -s /bin
export PATH=/bin:/sbin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev
mount -t tmpfs -o size=85% tmpfs /tmp # clip-loop records about 300 MB, a live clip 100 MB
echo "VMBOOT kernel $(uname -r), up $(cut -d' ' -f1 /proc/uptime) s"

# No depmod on the build host: the order is each module's "depends=" (strings X.ko) resolved by
# hand. vivid: one instance with a video capture node (bit 0) and a video output node (bit 8):
# /dev/video0 and /dev/video1.
for m in rc-core cec mc videodev videobuf2-common videobuf2-v4l2 videobuf2-memops \
  videobuf2-vmalloc videobuf2-dma-contig v4l2-tpg v4l2-dv-timings; do
  insmod "/modules/$m.ko" || echo "VMCHECK modules FAIL insmod $m"
done
insmod /modules/vivid.ko n_devs=1 node_types=0x101 || echo "VMCHECK modules FAIL insmod vivid"
i=0
while [ ! -e /dev/video1 ] && [ $i -lt 50 ]; do
  sleep 0.1
  i=$((i + 1))
done
echo "VMBOOT video devices ready, up $(cut -d' ' -f1 /proc/uptime) s: $(ls /dev/video*)"

sh /checks.sh
echo "VMDONE up $(cut -d' ' -f1 /proc/uptime) s"
sync
poweroff -f
