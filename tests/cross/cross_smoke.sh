#!/usr/bin/env bash
# ctest `cross_aarch64_qemu` (label cross): cross-builds facetscan-fw for aarch64 (cached, incremental), runs it
# under qemu-user (--version, then a full simulated scan of the cube scene on the sim twins, virtual time,
# --record), runs the native facetscan-fw with the same arguments and compares the two .fscan files with
# fs_fscan_compare (same stripes/points/rows; columns within 0.01 px). Skips (exit 77) only when the cross
# packages cannot be installed.
#   cross_smoke.sh SOURCE_DIR CROSS_BUILD_DIR NATIVE_FW COMPARE_TOOL WORK_DIR
set -uo pipefail
src="$1"; cross="$2"; native_fw="$3"; compare="$4"; work="$5"
steps="${FS_CROSS_STEPS:-100}"
scene="$src/hw-sim/scenes/cube.json"
mkdir -p "$work"
t0=$(date +%s)

FS_CROSS_JOBS="${FS_CROSS_JOBS:-2}" "$src/toolchain/cross-build" aarch64 "$cross" >"$work/cross-build.out" 2>"$work/cross-build.err"
rc=$?
if [ $rc -eq 3 ]; then
  cat "$work/cross-build.err" >&2
  echo "################################################################################" >&2
  echo "SKIPPED: the aarch64 cross packages (crossbuild-essential-arm64, qemu-user, :arm64 -dev) are not" >&2
  echo "installed and could not be installed here. The cross build was NOT tested." >&2
  echo "################################################################################" >&2
  exit 77
fi
if [ $rc -ne 0 ]; then
  tail -n 60 "$work/cross-build.err" >&2
  echo "FAIL: toolchain/cross-build aarch64 failed (exit $rc)" >&2; exit 1
fi
fw="$(tail -n 1 "$work/cross-build.out")"
t1=$(date +%s)
echo "cross build ready: $fw ($((t1 - t0)) s)"

if ! file -b "$fw" | grep -q 'ARM aarch64'; then
  echo "FAIL: $fw is not an aarch64 executable: $(file -b "$fw")" >&2; exit 1
fi
# -E LD_LIBRARY_PATH: the sysroot's ld.so (libc6-arm64-cross, 2.36-8cross1) must load the sysroot's libc, not the
# multiarch libc6:arm64 (a newer 2.36 point release) from /usr/lib/aarch64-linux-gnu, which it finds through
# qemu's path fallback; mixing the two hangs the first pthread_create. The other libraries come from multiarch.
qemu=(qemu-aarch64 -L /usr/aarch64-linux-gnu -E LD_LIBRARY_PATH=/usr/aarch64-linux-gnu/lib)
ver="$("${qemu[@]}" "$fw" --version 2>&1)" || { echo "FAIL: --version under qemu: $ver" >&2; exit 1; }
native_ver="$("$native_fw" --version 2>&1)"
echo "qemu-aarch64: $ver"
if [ "$ver" != "$native_ver" ] || [[ "$ver" != facetscan-fw\ * ]]; then
  echo "FAIL: version '$ver' (aarch64) vs '$native_ver' (native)" >&2; exit 1
fi

args=(--galvo sim --camera sim --scene "$scene" --steps "$steps" --virtual-time)
rm -f "$work/arm64.fscan" "$work/native.fscan"
if ! "${qemu[@]}" "$fw" "${args[@]}" --record "$work/arm64.fscan" >"$work/arm64.log" 2>&1; then
  cat "$work/arm64.log" >&2; echo "FAIL: simulated scan under qemu-aarch64" >&2; exit 1
fi
t2=$(date +%s)
if ! "$native_fw" "${args[@]}" --record "$work/native.fscan" >"$work/native.log" 2>&1; then
  cat "$work/native.log" >&2; echo "FAIL: native simulated scan" >&2; exit 1
fi
t3=$(date +%s)
echo "--- aarch64 (qemu) run: $((t2 - t1)) s"; cat "$work/arm64.log"
echo "--- native run: $((t3 - t2)) s"; cat "$work/native.log"
"$compare" "$work/native.fscan" "$work/arm64.fscan" || { echo "FAIL: the aarch64 scan differs from the native one" >&2; exit 1; }
echo "cross smoke test passed in $(( $(date +%s) - t0 )) s"
