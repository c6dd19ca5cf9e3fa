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
O="$B/vm/out"
printf '#!/bin/sh\nexec %s %s %s\n' "$HERE/guest.sh" "$GUEST" "$G2" > "$B/vm/cmd.sh"; chmod +x "$B/vm/cmd.sh"
# One boot runs every guest test. The guests run real kernel drivers on real clocks inside a TCG VM on a
# shared host: a scheduling spike of seconds can fail a timing bound or stall the boot. A failed attempt is
# therefore run once more (VMTEST_ATTEMPTS, default 2) with its reason logged; a failure that repeats fails.
attempts="${VMTEST_ATTEMPTS:-2}"
rc=1
for attempt in $(seq 1 "$attempts"); do
  rm -rf "$O"; mkdir -p "$O"
  timeout "${VMTEST_TIMEOUT:-600}" qemu-system-x86_64 -nographic -no-reboot -m "${VMTEST_MEM:-1024}" -smp 1 \
    -kernel "$B/vm/vmlinuz" -initrd "$B/vm/initrd.gz" \
    -append "console=ttyS0 panic=-1 quiet loglevel=3 vmtest_cmd=$B/vm/cmd.sh" \
    -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap \
    -virtfs local,path="$O",mount_tag=out,security_model=none > "$O/console.txt" 2>&1
  if [ ! -f "$O/rc" ]; then
    reason="the VM did not finish (timeout or crash); console tail:"
    echo "run_vm: attempt $attempt of $attempts: $reason"; tail -40 "$O/console.txt"
    rc=1
  else
    cat "$O/devices.txt" "$O/log.txt"
    rc="$(cat "$O/rc")"
    [ "$rc" = 0 ] && break
    reason="guest tests failed (rc $rc): $(grep -E '^\[  FAILED  \] [A-Za-z]' "$O/log.txt" | sed 's/^\[  FAILED  \] //' | sort -u | tr '\n' ' ')"
  fi
  if [ "$attempt" -lt "$attempts" ]; then
    echo "##########################################################################################"
    echo "## run_vm: RETRY after attempt $attempt: $reason"
    echo "##########################################################################################"
    echo "VMRESULT retry_reason $reason"
  fi
done
T2=$(date +%s.%N)
printf 'VMRESULT vm_build_s %.1f vm_boot_and_tests_s %.1f attempts %d\n' "$(echo "$T1 - $T0" | bc)" "$(echo "$T2 - $T1" | bc)" "$attempt"
exit "$rc"
