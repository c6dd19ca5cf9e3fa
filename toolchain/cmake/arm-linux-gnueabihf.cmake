# Cross build for 32-bit ARM (armhf: ARMv7, hard-float) scanner boards (Debian crossbuild-essential-armhf +
# multiarch :armhf libraries).
set(FS_TRIPLET arm-linux-gnueabihf)
set(FS_PROCESSOR armv7l)
set(FS_QEMU qemu-arm)
include(${CMAKE_CURRENT_LIST_DIR}/cross-common.cmake)
