#!/bin/bash
# ctest entry of the real-kernel HIL tests (label vm): builds/caches the VM under BUILD/vm, boots it (QEMU TCG),
# runs GUEST_BIN inside (chroot into the host's read-only /), prints its output, exits with its status.
# Skips (exit 77) with a loud message only when qemu cannot be installed, and fails instead under CI=true.
# Usage: run_vm.sh BUILD_DIR GUEST_BIN
set -u
B=$(realpath "$1"); GUEST=$(realpath "$2"); HERE=$(dirname "$(realpath "$0")")
T0=$(date +%s.%N)
need() { command -v qemu-system-x86_64 >/dev/null && command -v busybox >/dev/null && command -v cpio >/dev/null && command -v depmod >/dev/null; }
if ! need; then
  echo "run_vm: installing the VM packages (toolchain/setup --vm)"
  "$HERE/../../toolchain/setup" --vm || true
fi
if ! need; then
  echo "##########################################################################################"
  echo "## SKIPPED: real-kernel VM tests: qemu-system-x86_64/busybox/cpio/kmod are not installed ##"
  echo "## and 'toolchain/setup --vm' could not install them. The backends were NOT exercised     ##"
  echo "## against real kernel drivers.                                                          ##"
  echo "##########################################################################################"
  # Under CI (CI=true, as .ci/run's caller sets it) a skip would pass unnoticed: fail instead.
  if [ "${CI:-}" = true ]; then echo "run_vm: FAIL: CI=true and the VM packages are missing"; exit 1; fi
  exit 77
fi
"$HERE/build_vm.sh" "$B/vm" || { echo "run_vm: building the VM failed"; exit 1; }
G2=none
"$HERE/build_gpiod2.sh" "$B/vm/gpiod2" "$HERE/../.." && G2="$B/vm/gpiod2/gpiod2_check" || {
  rc=$?; [ $rc -eq 3 ] || { echo "run_vm: building the libgpiod 2.x check failed"; exit 1; }
  echo "########## run_vm: libgpiod 2.x not obtainable: the v2 GPIO backend will NOT be exercised ##########"; }
T1=$(date +%s.%N)
O="$B/vm/out"; rm -rf "$O"; mkdir -p "$O"
printf '#!/bin/sh\nexec %s %s %s\n' "$HERE/guest.sh" "$GUEST" "$G2" > "$B/vm/cmd.sh"; chmod +x "$B/vm/cmd.sh"
timeout "${VMTEST_TIMEOUT:-600}" qemu-system-x86_64 -nographic -no-reboot -m "${VMTEST_MEM:-1024}" -smp 1 \
  -kernel "$B/vm/vmlinuz" -initrd "$B/vm/initrd.gz" \
  -append "console=ttyS0 panic=-1 quiet loglevel=3 vmtest_cmd=$B/vm/cmd.sh" \
  -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap \
  -virtfs local,path="$O",mount_tag=out,security_model=none > "$O/console.txt" 2>&1
T2=$(date +%s.%N)
if [ ! -f "$O/rc" ]; then echo "run_vm: the VM did not finish; console:"; tail -40 "$O/console.txt"; exit 1; fi
cat "$O/devices.txt" "$O/log.txt"
printf 'VMRESULT vm_build_s %.1f vm_boot_and_tests_s %.1f\n' "$(echo "$T1 - $T0" | bc)" "$(echo "$T2 - $T1" | bc)"
exit "$(cat "$O/rc")"
