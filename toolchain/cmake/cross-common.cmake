# Shared part of the cross toolchain files (aarch64-linux-gnu.cmake, arm-linux-gnueabihf.cmake), which set
# FS_TRIPLET (GNU triplet), FS_PROCESSOR (CMAKE_SYSTEM_PROCESSOR) and FS_QEMU (qemu-user binary) and include this.
#
# Libraries come from Debian's multiarch packages (:arm64 / :armhf, installed by toolchain/cross-build) and, when
# FS_CROSS_SYSROOT is set, first from that private sysroot: .debs extracted with dpkg -x, which cross-build uses
# when the multiarch packages cannot be installed next to the host's (version skew between the archive of the
# foreign architecture and the host's installed Multi-Arch: same libraries).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR ${FS_PROCESSOR})
set(CMAKE_C_COMPILER ${FS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${FS_TRIPLET}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${FS_TRIPLET})

set(FS_CROSS_SYSROOT "" CACHE PATH "Private sysroot of extracted ${FS_TRIPLET} library packages (empty: multiarch only)")
# try_compile projects re-read this file: hand them the sysroot too.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES FS_CROSS_SYSROOT)

set(CMAKE_FIND_ROOT_PATH ${FS_CROSS_SYSROOT} /usr/${FS_TRIPLET} /usr/lib/${FS_TRIPLET})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)

# The loader search path of the cross-built programs: the cross toolchain's libc/libstdc++ first (its ld.so must
# load its own libc, not the multiarch one), then the private sysroot's libraries; multiarch via qemu's -L fallback.
set(FS_CROSS_LD_LIBRARY_PATH /usr/${FS_TRIPLET}/lib)
if(FS_CROSS_SYSROOT)
  string(APPEND FS_CROSS_LD_LIBRARY_PATH ":${FS_CROSS_SYSROOT}/usr/lib/${FS_TRIPLET}:${FS_CROSS_SYSROOT}/lib/${FS_TRIPLET}")
  # The linker resolves the libraries' own dependencies (libpng16 -> libz) inside the sysroot too.
  # (zlib1g keeps libz.so.1 in /lib/<triplet>, the others are in /usr/lib/<triplet>).
  set(FS_CROSS_RPATH_LINK "-Wl,-rpath-link,${FS_CROSS_SYSROOT}/usr/lib/${FS_TRIPLET}:${FS_CROSS_SYSROOT}/lib/${FS_TRIPLET}")
  set(CMAKE_EXE_LINKER_FLAGS_INIT ${FS_CROSS_RPATH_LINK})
  set(CMAKE_SHARED_LINKER_FLAGS_INIT ${FS_CROSS_RPATH_LINK})
  # Only the sysroot's .pc files, with their /usr prefix re-rooted into it.
  set(ENV{PKG_CONFIG_LIBDIR} ${FS_CROSS_SYSROOT}/usr/lib/${FS_TRIPLET}/pkgconfig)
  set(ENV{PKG_CONFIG_SYSROOT_DIR} ${FS_CROSS_SYSROOT})
else()
  # No ${FS_TRIPLET}-pkg-config in Debian: point pkg-config at the multiarch .pc files.
  set(ENV{PKG_CONFIG_LIBDIR} /usr/lib/${FS_TRIPLET}/pkgconfig:/usr/share/pkgconfig)
endif()
set(CMAKE_CROSSCOMPILING_EMULATOR ${FS_QEMU};-L;/usr/${FS_TRIPLET};-E;LD_LIBRARY_PATH=${FS_CROSS_LD_LIBRARY_PATH})
