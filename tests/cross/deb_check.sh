#!/usr/bin/env bash
# ctest `cross_<arch>_deb` (label cross): `cpack -G DEB` in the board's cross build dir (aarch64 or armhf), then
# checks the package with dpkg-deb -I / -c / -x: name, version, Debian architecture (arm64 / armhf), dependencies,
# postinst, the binary (an ELF of the board's architecture that runs `--version` under qemu), the systemd unit
# (restart on failure, RT scheduling, memlock, dedicated user; `systemd-analyze verify` when available) and the
# example board config; and that it carries no simulator (no facetscan-fw-hil, no hw-sim scenes).
#   deb_check.sh ARCH SOURCE_DIR CROSS_BUILD_DIR WORK_DIR      (ARCH: aarch64 | armhf)
set -uo pipefail
arch="$1"; src="$2"; cross="$3"; work="$4"
source "$(dirname "$0")/cross_common.sh"
cross_arch "$arch"
fail() { echo "FAIL: $*" >&2; exit 1; }
cross_build_or_skip "$arch" "$src" "$cross" "$work.cross-build" "the $arch .deb"

rm -rf "$work"; mkdir -p "$work"
(cd "$cross" && cpack -G DEB -B "$work" >"$work/cpack.log" 2>&1) || { cat "$work/cpack.log" >&2; fail "cpack -G DEB"; }
version="$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$cross/CMakeCache.txt")"
deb="$work/facetscan-fw_${version}_${deb_arch}.deb"
[ -f "$deb" ] || { ls -l "$work" >&2; fail "expected $deb"; }
echo "package: $deb ($(stat -c %s "$deb") bytes)"

info="$(dpkg-deb -I "$deb")" || fail "dpkg-deb -I"
echo "$info"
field() { dpkg-deb -f "$deb" "$1"; }
[ "$(field Package)" = facetscan-fw ] || fail "Package: $(field Package)"
[ "$(field Architecture)" = "$deb_arch" ] || fail "Architecture: $(field Architecture)"
[ "$(field Version)" = "$version" ] || fail "Version: $(field Version) (expected $version)"
for d in libgpiod2 libpng16-16 adduser; do field Depends | grep -q "$d" || fail "Depends lacks $d: $(field Depends)"; done
echo "$info" | grep -q ' postinst' || fail "no postinst in the control archive"

contents="$(dpkg-deb -c "$deb")" || fail "dpkg-deb -c"
echo "$contents"
for f in ./usr/bin/facetscan-fw ./usr/lib/systemd/system/facetscan-fw.service \
         ./usr/share/facetscan/board.example.json; do
  echo "$contents" | grep -q " $f\$" || fail "the package lacks $f"
done
echo "$contents" | grep -q ' \./usr/bin/facetscan$' && fail "the host program must not be in facetscan-fw"
echo "$contents" | grep -q 'facetscan-fw-hil' && fail "the HIL binary (facetscan-fw-hil) must not be in facetscan-fw"
scenes="$(echo "$contents" | grep -i 'scenes\|meshes\|\.json$\|\.stl$\|\.ply$' | grep -v '/board\.example\.json$')"
[ -z "$scenes" ] || fail "hw-sim scenes must not be in facetscan-fw: $scenes"

dpkg-deb -x "$deb" "$work/root" || fail "dpkg-deb -x"
dpkg-deb -e "$deb" "$work/control" || fail "dpkg-deb -e"
bin="$work/root/usr/bin/facetscan-fw"
file -b "$bin" | grep -q "$elf" || fail "packaged binary is not $arch: $(file -b "$bin")"
[ -x "$bin" ] || fail "packaged binary is not executable"
"$cross/qemu-run" "$bin" --version | grep -q "^facetscan-fw $version" || fail "packaged --version"
cmp -s "$work/root/usr/share/facetscan/board.example.json" "$src/toolchain/deploy/board.example.json" \
  || fail "packaged board.example.json differs from the source"
sh -n "$work/control/postinst" || fail "postinst: shell syntax"
[ -x "$work/control/postinst" ] || fail "postinst is not executable"
grep -q 'adduser --system' "$work/control/postinst" || fail "postinst creates no system user"
for g in gpio video; do grep -q "$g" "$work/control/postinst" || fail "postinst does not add the $g group"; done

unit="$work/root/usr/lib/systemd/system/facetscan-fw.service"
for kv in 'Restart=on-failure' 'User=facetscan' 'SupplementaryGroups=.*gpio' 'SupplementaryGroups=.*video' \
          'LimitMEMLOCK=infinity' 'LimitRTPRIO=' 'CPUSchedulingPolicy=fifo' 'ExecStart=/usr/bin/facetscan-fw --config'; do
  grep -q "^$kv" "$unit" || fail "unit lacks $kv"
done
if command -v systemd-analyze >/dev/null; then
  # Verify a copy whose ExecStart points at an existing binary (the ARM one is not runnable here).
  mkdir -p "$work/verify"
  sed "s#^ExecStart=/usr/bin/facetscan-fw#ExecStart=$bin#" "$unit" >"$work/verify/facetscan-fw.service"
  out="$(SYSTEMD_LOG_LEVEL=warning systemd-analyze verify --man=no "$work/verify/facetscan-fw.service" 2>&1)"
  # Only problems of this unit count (the container may lack the units it orders itself after).
  bad="$(echo "$out" | grep -i 'facetscan-fw.service' | grep -vi 'not found\|no such file\|Failed to prepare filename')"
  [ -z "$bad" ] || { echo "$out" >&2; fail "systemd-analyze verify"; }
  echo "systemd-analyze verify: ok${out:+ (other messages: $out)}"
else
  echo "NOTE: systemd-analyze not available: unit file not verified by systemd"
fi
echo "package checks passed"
