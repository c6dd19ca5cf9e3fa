# Sourced by cross_smoke.sh and deb_check.sh (bash).
#   cross_arch ARCH: sets deb_arch (Debian architecture) and elf (what `file` says of its executables); exit 2 on
#     an unknown ARCH.
#   cross_build_or_skip ARCH SRC CROSS_DIR LOG_PREFIX WHAT: runs toolchain/cross-build (FS_CROSS_JOBS default 2),
#     stdout to LOG_PREFIX.out, stderr to LOG_PREFIX.err; sets fw to the built binary. Exits 77 (ctest SKIP, with
#     a banner naming WHAT was not tested) when the cross packages are not installable (1 under CI=true), 1 when
#     the build failed.
cross_arch() {
  case "$1" in
    aarch64) deb_arch=arm64; elf='ARM aarch64' ;;
    armhf) deb_arch=armhf; elf='ARM, EABI5' ;;
    *) echo "$(basename "$0"): unknown architecture '$1' (aarch64 or armhf)" >&2; exit 2 ;;
  esac
}

cross_build_or_skip() {
  local arch="$1" src="$2" dir="$3" log="$4" what="$5" rc=0
  FS_CROSS_JOBS="${FS_CROSS_JOBS:-2}" "$src/toolchain/cross-build" "$arch" "$dir" >"$log.out" 2>"$log.err" || rc=$?
  if [ $rc -eq 3 ]; then
    cat "$log.err" >&2
    echo "################################################################################" >&2
    echo "SKIPPED: the $arch cross packages (crossbuild-essential-$deb_arch, qemu-user, the :$deb_arch -dev" >&2
    echo "libraries) are not installed and could not be installed here: $what was NOT tested." >&2
    echo "################################################################################" >&2
    # Under CI (CI=true) a skip would pass unnoticed: fail instead.
    if [ "${CI:-}" = true ]; then echo "FAIL: CI=true and the $arch cross packages are missing" >&2; exit 1; fi
    exit 77
  fi
  if [ $rc -ne 0 ]; then
    tail -n 60 "$log.err" >&2
    echo "FAIL: toolchain/cross-build $arch failed (exit $rc)" >&2
    exit 1
  fi
  fw="$(tail -n 1 "$log.out")"
}
