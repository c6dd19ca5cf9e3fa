# Cross build for 64-bit ARM scanner boards (Debian crossbuild-essential-arm64 + multiarch :arm64 libraries).
set(FS_TRIPLET aarch64-linux-gnu)
set(FS_PROCESSOR aarch64)
set(FS_QEMU qemu-aarch64)
include(${CMAKE_CURRENT_LIST_DIR}/cross-common.cmake)
