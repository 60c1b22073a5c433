# Cross-compiling coslam for 64-bit Arm Linux (aarch64, e.g. a Robotino or a
# Raspberry Pi 4/5 running Debian bookworm arm64) on a Debian amd64 host:
#   cmake -S . -B build-aarch64 -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-aarch64.cmake -DCOSLAM_ROBOT_ONLY=ON
# (tools/cross_aarch64.sh does this; docs/packaging.md explains it.)
#
# Packages (tools/deps.sh install cross): Debian's cross compilers
# gcc-aarch64-linux-gnu / g++-aarch64-linux-gnu, qemu-user, and the target's
# libraries as arm64 multiarch packages (dpkg --add-architecture arm64, then
# libinih-dev:arm64 ...). Multiarch puts the target's libraries next to the
# host's (/usr/lib/aarch64-linux-gnu) under the same root, so there is no
# sysroot: the cross compiler searches the multiarch directories itself,
# CMake finds libraries and CMake packages through CMAKE_LIBRARY_ARCHITECTURE,
# and pkg-config is pointed at the arm64 .pc files only.
#
# Cyclone DDS: its IDL compiler idlc runs on the build machine (amd64
# cyclonedds-tools, /usr/bin/idlc) while libddsc is linked for the target
# (cyclonedds-dev:arm64). The arm64 CycloneDDSConfig.cmake defines no idlc
# target (Debian ships idlc in -tools), and its idlc_generate() looks idlc
# up with find_program(... NO_CMAKE_FIND_ROOT_PATH) when CMAKE_CROSSCOMPILING;
# programs are searched on the host here (CMAKE_FIND_ROOT_PATH_MODE_PROGRAM
# NEVER), so both that lookup and hal/linux/dds's find_program(idlc) get the
# host binary. idlc's output is portable C (offsetof-based type descriptors),
# compiled for the target like any other source. Its version must match
# libddsc's (both 0.10.2 in bookworm; apt keeps cyclonedds-tools and
# cyclonedds-dev:arm64 at the same version).
#
# Tests: CMAKE_CROSSCOMPILING_EMULATOR makes CTest run every test that is a
# target binary under qemu-aarch64 (user-mode emulation). The runtime is the
# arm64 multiarch one under "/" (libc6:arm64, which every :arm64 library
# package pulls in): loader /lib/ld-linux-aarch64.so.1, libraries from
# /usr/lib/aarch64-linux-gnu, so "-L /". Not "-L /usr/aarch64-linux-gnu":
# that takes the loader of the cross toolchain's libc (libc6-arm64-cross)
# while the libraries, libc.so.6 included, still resolve from the multiarch
# directories (qemu falls back to the real path), and a loader and libc of
# two different glibc builds hang in pthread_create (Cyclone DDS's first
# thread never starts). Linking against the cross libc and running on the
# multiarch one is the normal case of an older build-time libc.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)

set(COSLAM_CROSS_TRIPLET aarch64-linux-gnu)
set(CMAKE_C_COMPILER ${COSLAM_CROSS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${COSLAM_CROSS_TRIPLET}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${COSLAM_CROSS_TRIPLET})

# Target libraries, headers and CMake packages: target only (the multiarch
# tree); programs (idlc, arm-none-eabi-gcc, python3): host only.
set(CMAKE_FIND_ROOT_PATH /usr/${COSLAM_CROSS_TRIPLET})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)

# pkg-config: only the arm64 .pc files (and the architecture-independent
# ones), never the host's. PKG_CONFIG_LIBDIR replaces the default path.
set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/${COSLAM_CROSS_TRIPLET}/pkgconfig:/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")
set(ENV{PKG_CONFIG_SYSROOT_DIR} "")

# qemu-user runs the cross-built tests (CTest) and the robot smoke test.
find_program(COSLAM_QEMU_AARCH64 qemu-aarch64)
if(COSLAM_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${COSLAM_QEMU_AARCH64} -L /
      CACHE STRING "runs target binaries on the build machine (CTest)")
endif()
