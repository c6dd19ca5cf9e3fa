#!/usr/bin/env bash
# ctest `fw_board_has_no_simulator` (label firmware): the board binary (facetscan-fw) links no simulator. Fails
# when `nm -C` finds in it any fs::sim:: symbol or a symbol of the scene renderer, sim-frame, the device twins or
# the sim-can pairing; checks that the HIL binary (facetscan-fw-hil) does have them (so the check can fail), and
# prints both binaries' sizes.
#   board_no_sim_check.sh FACETSCAN_FW FACETSCAN_FW_HIL
set -uo pipefail
board="$1"; hil="$2"
fail() { echo "FAIL: $*" >&2; exit 1; }
command -v nm >/dev/null || fail "nm (binutils) not found"
pattern='fs::sim::|SceneFrameRenderer|StripeRenderer|StripeTracer|add_sim_frame_command|Cia402Twin|SimCanGalvo|SimRig|SimCamera|SimStepperLines'
board_syms="$(nm -C "$board")" || fail "nm $board"
hil_syms="$(nm -C "$hil")" || fail "nm $hil"
[ -n "$board_syms" ] || fail "$board has no symbols (stripped?): nothing to check"
hits="$(echo "$board_syms" | grep -E "$pattern")"
if [ -n "$hits" ]; then
  echo "$hits" | head -n 40 >&2
  fail "$board (the board binary) contains $(echo "$hits" | wc -l) simulator symbols (above)"
fi
for s in 'fs::sim::SceneFrameRenderer::' 'fs::sim::add_sim_frame_command' 'fs::sim::Cia402Twin::' \
         'fs::sim::SimCanGalvo::' 'fs::sim::SimRig::' 'fs::sim::SimCamera::'; do
  grep -qF "$s" <<<"$hil_syms" || fail "$hil (the HIL binary) lacks $s: the check would not see a simulator"
done
echo "$(basename "$board"): no simulator symbols; $(basename "$hil"): $(echo "$hil_syms" | grep -cE "$pattern") of them"
size "$board" "$hil"
