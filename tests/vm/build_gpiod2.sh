#!/bin/bash
# Fetches libgpiod 2.1 (bookworm-backports; apt with a private source list and lists dir, nothing installed) into
# CACHE and builds gpiod2_check from firmware/backends/gpiod_lines_v2.cpp against it.
# Usage: build_gpiod2.sh CACHE SOURCE_DIR      exit 3 = libgpiod 2.x not obtainable (the v2 check is skipped)
set -eu
W=$(realpath -m "$1"); S=$(realpath "$2"); mkdir -p "$W/lists/partial" "$W/debs"; cd "$W"
APT=(-o Dir::Etc::sourcelist="$W/sources.list" -o Dir::Etc::sourceparts=/nonexistent -o Dir::State::Lists="$W/lists")
if [ ! -f root/usr/include/gpiod.h ]; then
  . /etc/os-release
  if [ "${VERSION_CODENAME:-}" = bookworm ]; then
    echo "deb http://deb.debian.org/debian bookworm-backports main" > sources.list
    apt-get -qq "${APT[@]}" update >/dev/null 2>&1 || exit 3
    (cd debs && apt-get -qq "${APT[@]}" download libgpiod-dev/bookworm-backports libgpiod3/bookworm-backports >/dev/null 2>&1) || exit 3
  else
    (cd debs && apt-get -qq download libgpiod-dev libgpiod3 >/dev/null 2>&1) || exit 3
  fi
  for d in debs/*.deb; do dpkg -x "$d" root; done
fi
grep -q "GPIOD_LINE_VALUE_ACTIVE" root/usr/include/gpiod.h || exit 3
LIB=$(dirname "$(find "$W/root" -name 'libgpiod.so.3*' | head -1)")
g++ -std=c++20 -O1 -g -Wall -Wextra -Werror -I"$S" -I"$W/root/usr/include" \
  "$S/firmware/backends/gpiod_lines_v2.cpp" "$S/tests/vm/gpiod2_check.cpp" \
  -L"$LIB" -l:libgpiod.so.3 -Wl,-rpath,"$LIB" -o "$W/gpiod2_check"
echo "build_gpiod2: built $W/gpiod2_check against $(basename "$(ls "$LIB"/libgpiod.so.3.*)")"
