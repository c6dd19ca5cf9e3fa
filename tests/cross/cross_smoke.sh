#!/usr/bin/env bash
# ctest `cross_<arch>_qemu` (label cross): cross-builds the firmware for the board (aarch64 or armhf; cached,
# incremental: facetscan-fw and facetscan-fw-hil), runs both under qemu-user (--version), then a full simulated
# scan of the cube scene on the sim twins with facetscan-fw-hil (virtual time, --record), runs the native
# facetscan-fw-hil with the same arguments and compares the two .fscan files with fs_fscan_compare (same
# stripes/points/rows; columns within 0.01 px). Skips (exit 77) only when the cross packages cannot be installed.
#   cross_smoke.sh ARCH SOURCE_DIR CROSS_BUILD_DIR NATIVE_FW_HIL COMPARE_TOOL WORK_DIR      (ARCH: aarch64 | armhf)
set -uo pipefail
arch="$1"; src="$2"; cross="$3"; native_fw="$4"; compare="$5"; work="$6"
source "$(dirname "$0")/cross_common.sh"
cross_arch "$arch"
steps="${FS_CROSS_STEPS:-100}"
scene="$src/hw-sim/scenes/cube.json"
mkdir -p "$work"
t0=$(date +%s)

cross_build_or_skip "$arch" "$src" "$cross" "$work/cross-build" "the $arch cross build"
t1=$(date +%s)
echo "cross build ready: $fw ($((t1 - t0)) s)"

hil="$(dirname "$fw")/facetscan-fw-hil"
for b in "$fw" "$hil"; do
  if ! file -b "$b" | grep -q "$elf"; then
    echo "FAIL: $b is not an $arch executable: $(file -b "$b")" >&2; exit 1
  fi
done
# qemu-run (written by cross-build): qemu-user with -E LD_LIBRARY_PATH=/usr/<triplet>/lib: the cross toolchain's
# ld.so (libc6-<arch>-cross, 2.36-8cross1) must load its own libc, not the multiarch libc6:<arch> (a newer 2.36
# point release) that it finds through qemu's path fallback; mixing the two hangs the first pthread_create. The
# other libraries come from multiarch (or the private sysroot cross-build unpacked).
qemu=("$cross/qemu-run")
for b in "$fw" "$hil"; do
  name="$(basename "$b")"
  native_ver="$("$(dirname "$native_fw")/$name" --version 2>&1)"
  ver="$("${qemu[@]}" "$b" --version 2>&1)" || { echo "FAIL: $name --version under qemu: $ver" >&2; exit 1; }
  echo "qemu ($arch): $name: $ver"
  if [ "$ver" != "$native_ver" ] || [[ "$ver" != "$name "* ]]; then
    echo "FAIL: version '$ver' ($arch $(basename "$b")) vs '$native_ver' (native)" >&2; exit 1
  fi
done

args=(--galvo sim --camera sim --scene "$scene" --steps "$steps" --virtual-time)
rm -f "$work/cross.fscan" "$work/native.fscan"
if ! "${qemu[@]}" "$hil" "${args[@]}" --record "$work/cross.fscan" >"$work/cross.log" 2>&1; then
  cat "$work/cross.log" >&2; echo "FAIL: simulated scan under qemu ($arch)" >&2; exit 1
fi
t2=$(date +%s)
if ! "$native_fw" "${args[@]}" --record "$work/native.fscan" >"$work/native.log" 2>&1; then
  cat "$work/native.log" >&2; echo "FAIL: native simulated scan" >&2; exit 1
fi
t3=$(date +%s)
echo "--- $arch (qemu) run: $((t2 - t1)) s"; cat "$work/cross.log"
echo "--- native run: $((t3 - t2)) s"; cat "$work/native.log"
"$compare" "$work/native.fscan" "$work/cross.fscan" || { echo "FAIL: the $arch scan differs from the native one" >&2; exit 1; }
echo "cross smoke test passed in $(( $(date +%s) - t0 )) s"
