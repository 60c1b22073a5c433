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
libgpiod-dev
"

PACKAGES_MRPT="
libmrpt-slam-dev
"
case "${2:-}" in
  "") ;;
  mrpt) PACKAGES=$PACKAGES_MRPT ;;
  *) echo "deps: unknown package set '$2' (known: mrpt)" >&2; exit 2 ;;
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
    if [ "$(id -u)" -eq 0 ]; then
      echo "deps: installing $m"
      export DEBIAN_FRONTEND=noninteractive
      apt-get update
      apt-get install -y --no-install-recommends $m
    else
      echo "deps: missing Debian packages. Run as root:" >&2
      echo "  apt-get install -y --no-install-recommends $m" >&2
      exit 1
    fi ;;
  *) echo "usage: $0 check|ensure|install|list [mrpt]" >&2; exit 2 ;;
esac
