#!/bin/sh
# Debian packages the build needs. One list, used by `make deps` and by the
# automatic check that `make`, `make test`, `make sim` and `make bench` run.
#   tools/deps.sh check    exit 1 (listing what is missing) if anything is
#   tools/deps.sh ensure   install what is missing when root, else print the
#                          exact apt-get command and exit 1
#   tools/deps.sh install  same as ensure
#   tools/deps.sh list     print the package list
# An optional second argument selects another list instead of the build's:
#   mrpt   MRPT's SLAM library, only for `make bench-mrpt` (large: kept out
#          of the default list so that CI stays fast)
#   cross  the aarch64 cross build (`make robot`, `make cross`, `make package`):
#          Debian's cross compilers, qemu-user, and the robot's libraries as
#          arm64 multiarch packages (adds the arm64 architecture to dpkg;
#          docs/packaging.md). idlc stays the host's (cyclonedds-tools above).
#   chroot debootstrap, for tools/package_check.sh
set -eu

PACKAGES="
build-essential
cmake
pkg-config
binutils
libcmocka-dev
gcc-arm-none-eabi
libnewlib-arm-none-eabi
binutils-arm-none-eabi
python3
python3-numpy
python3-matplotlib
libeigen3-dev
libgtest-dev
libtomlplusplus-dev
libinih-dev
nlohmann-json3-dev
libcli11-dev
libnlopt-dev
libopenmpi-dev
openmpi-bin
libgpiod-dev
libturbojpeg0-dev
cyclonedds-dev
cyclonedds-tools
libsodium-dev
clang-14
libclang-rt-14-dev
libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libopencv-videoio-dev
"

PACKAGES_MRPT="
libmrpt-slam-dev
"
PACKAGES_CROSS="
gcc-aarch64-linux-gnu
g++-aarch64-linux-gnu
qemu-user
file
dpkg-dev
libcmocka-dev:arm64
libinih-dev:arm64
libgpiod-dev:arm64
libsodium-dev:arm64
cyclonedds-dev:arm64
libturbojpeg0-dev:arm64
libopencv-core-dev:arm64
libopencv-imgproc-dev:arm64
"
PACKAGES_CHROOT="
debootstrap
"
case "${2:-}" in
  "") ;;
  mrpt) PACKAGES=$PACKAGES_MRPT ;;
  cross) PACKAGES=$PACKAGES_CROSS ;;
  chroot) PACKAGES=$PACKAGES_CHROOT ;;
  *) echo "deps: unknown package set '$2' (known: mrpt cross chroot)" >&2; exit 2 ;;
esac

missing() {
  for p in $PACKAGES; do
    if ! dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q 'install ok installed'; then
      printf '%s ' "$p"
    fi
  done
}

cmd=${1:-ensure}
case "$cmd" in
  list) echo $PACKAGES; exit 0 ;;
  check)
    m=$(missing)
    if [ -n "$m" ]; then echo "missing Debian packages: $m" >&2; exit 1; fi
    exit 0 ;;
  ensure|install)
    if ! command -v dpkg-query >/dev/null 2>&1; then
      echo "deps: not a Debian system; install the equivalents of: $PACKAGES" >&2
      exit 1
    fi
    m=$(missing)
    [ -z "$m" ] && exit 0
    # ":arm64" packages need the architecture known to dpkg first
    foreign=$(printf '%s\n' $m | sed -n 's/.*:\([a-z0-9]*\)$/\1/p' | sort -u)
    if [ "$(id -u)" -eq 0 ]; then
      for a in $foreign; do
        dpkg --print-foreign-architectures | grep -qx "$a" || dpkg --add-architecture "$a"
      done
      echo "deps: installing $m"
      export DEBIAN_FRONTEND=noninteractive
      apt-get update
      apt-get install -y --no-install-recommends $m
    else
      echo "deps: missing Debian packages. Run as root:" >&2
      for a in $foreign; do
        echo "  dpkg --add-architecture $a && apt-get update" >&2
      done
      echo "  apt-get install -y --no-install-recommends $m" >&2
      exit 1
    fi ;;
  *) echo "usage: $0 check|ensure|install|list [mrpt|cross|chroot]" >&2; exit 2 ;;
esac
