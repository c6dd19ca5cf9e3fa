#!/bin/bash
# Builds the real-kernel test VM into CACHE (kept between runs): Debian's kernel (apt-get download, never
# installed), vcan/can-raw/vivid/9p modules from it, gpio-sim + irq_sim and v4l2loopback built out of tree against
# its headers, and a busybox initramfs whose init is tests/vm/init.
# Usage: build_vm.sh CACHE      Needs: qemu-system-x86 busybox-static cpio kmod gcc make (toolchain/setup --vm)
set -euo pipefail
W=$(realpath -m "$1"); HERE=$(dirname "$(realpath "$0")")
mkdir -p "$W/debs" && cd "$W"
KPKG=$(apt-cache depends linux-image-amd64 | awk '/Depends: linux-image-/{print $2; exit}')
[ -n "$KPKG" ] || { echo "build_vm: apt-cache knows no linux-image-amd64 (run apt-get update)"; exit 2; }
KVER=${KPKG#linux-image-}
HCOMMON=$(apt-cache depends "linux-headers-$KVER" | awk '/Depends: linux-headers-.*-common/{print $2; exit}')
KBUILD=$(apt-cache depends "linux-headers-$KVER" | awk '/Depends: linux-kbuild-/{print $2; exit}')
SRCPKG=linux-source-${KBUILD#linux-kbuild-}
STAMP="$KVER-$(cat "$HERE/init" "$0" | md5sum | cut -c1-12)"
if [ -f "ready-$STAMP" ] && [ -f vmlinuz ] && [ -f initrd.gz ]; then echo "build_vm: cached ($STAMP)"; exit 0; fi
echo "build_vm: kernel=$KVER headers=$HCOMMON kbuild=$KBUILD source=$SRCPKG"
if [ ! -f "debs/.ok-$KVER" ]; then
  (cd debs && apt-get download "$KPKG" "linux-headers-$KVER" "$HCOMMON" "$KBUILD" "$SRCPKG" v4l2loopback-dkms)
  touch "debs/.ok-$KVER"
fi
rm -rf k hdr src gpiomod lb initrd; mkdir -p k hdr src gpiomod lb
dpkg-deb --fsys-tarfile debs/${KPKG}_*.deb | tar x -C k --wildcards ./boot/vmlinuz-* \
  './lib/modules/*/kernel/drivers/net/can/*' './lib/modules/*/kernel/net/can/*' './lib/modules/*/kernel/drivers/media/*' \
  './lib/modules/*/kernel/fs/configfs/*' './lib/modules/*/kernel/net/9p/*' './lib/modules/*/kernel/fs/9p/*' \
  './lib/modules/*/kernel/fs/netfs/*' './lib/modules/*/kernel/fs/fscache/*' './lib/modules/*/kernel/drivers/virtio/*' \
  './lib/modules/*/modules.*'
depmod -b "$W/k" "$KVER"
for d in debs/linux-headers-${KVER}_*.deb debs/${HCOMMON}_*.deb debs/${KBUILD}_*.deb; do dpkg -x "$d" hdr; done
H=$W/hdr/usr/src/linux-headers-$KVER
echo "include $W/hdr/usr/src/$HCOMMON/Makefile" > "$H/Makefile"
S=$SRCPKG
dpkg-deb --fsys-tarfile debs/${SRCPKG}_*.deb | tar xO ./usr/src/$S.tar.xz | \
  tar xJ -C src $S/drivers/gpio/gpio-sim.c $S/drivers/gpio/gpiolib.h $S/kernel/irq/irq_sim.c
cp src/$S/drivers/gpio/{gpio-sim.c,gpiolib.h} gpiomod/
# Debian's kernel has CONFIG_IRQ_SIM unset: build irq_sim as a module; irq_to_desc is not exported.
sed 's/handle_simple_irq(irq_to_desc(irqnum));/generic_handle_irq(irqnum);/' src/$S/kernel/irq/irq_sim.c > gpiomod/irqsim.c
printf '\n#include <linux/module.h>\nMODULE_LICENSE("GPL");\n' >> gpiomod/irqsim.c
printf 'obj-m += irqsim.o gpio-sim.o\n' > gpiomod/Makefile
make -s -C "$H" M="$W/gpiomod" modules
dpkg -x debs/v4l2loopback-dkms_*.deb lb; LBS=$(echo "$W"/lb/usr/src/v4l2loopback-*)
make -s -C "$H" M="$LBS" modules
MD=k/lib/modules/$KVER
mkdir -p initrd/{bin,proc,sys,dev,tmp,host,out,lib/modules}
cp /bin/busybox initrd/bin/
order() { local line rev=""; line=$(grep -E "(^|/)$1.ko:" "$MD/modules.dep"); for d in ${line#*:}; do rev="$d $rev"; done; for d in $rev; do echo "$d"; done; echo "${line%%:*}"; }
for m in vcan can-raw configfs vivid virtio_pci 9pnet_virtio 9p; do order $m; done | awk '!s[$0]++' | \
  while read -r f; do cp "$MD/$f" initrd/lib/modules/; basename "$f"; done > initrd/lib/modules/order
cp gpiomod/irqsim.ko gpiomod/gpio-sim.ko "$LBS/v4l2loopback.ko" initrd/lib/modules/
printf 'irqsim.ko\ngpio-sim.ko\nv4l2loopback.ko video_nr=10 card_label=facetscan-loop exclusive_caps=0 max_buffers=8\n' >> initrd/lib/modules/order
cp "$HERE/init" initrd/init; chmod +x initrd/init
(cd initrd && find . | cpio -o -H newc 2>/dev/null | gzip -1 > ../initrd.gz)
cp "k/boot/vmlinuz-$KVER" vmlinuz
rm -rf k hdr src lb/usr/src/*/.tmp* ; rm -f ready-*; touch "ready-$STAMP"
echo "build_vm: built $W/vmlinuz $W/initrd.gz"
