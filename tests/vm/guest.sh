#!/bin/sh
# Runs inside the VM, chrooted into the host's / (read-only): the guest tests against the real drivers.
# Usage: guest.sh VM_GUEST_TESTS [GPIOD2_CHECK|none]
export FACETSCAN_VM=1
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
echo "VMTEST kernel $(uname -r)"
ls -l /dev/gpiochip* /dev/video* 2>&1 | sed 's/^/VMTEST dev /'
"$1" --gtest_color=no; rc=$?
if [ -n "${2:-}" ] && [ "$2" != none ]; then
  "$2" || rc=1
else
  echo "VMTEST libgpiod 2.x backend NOT exercised (libgpiod 2.x could not be fetched)"
fi
exit $rc
