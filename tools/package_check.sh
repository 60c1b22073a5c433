#!/bin/sh
# Install and removal check of the coslam-robot Debian package in a clean
# Debian root, without containers: debootstrap --variant=minbase (once,
# cached), a fresh copy of it per run, chroot (docs/packaging.md).
#   tools/package_check.sh [package.deb]     (root; default: the host-arch
#                                              package in out/package/)
# Steps: apt-get install ./package.deb (dependencies from the Debian mirror);
# the files, conffile, service user, groups and state directory are there;
# the binary's libraries resolve; `coslam-robot --dry-run` with the default
# configuration refuses to start without the fleet key (exit 2), and with a
# key starts as the service user, names every missing device and exits 0;
# reinstall keeps a locally edited conffile; remove keeps the conffile;
# purge (with autoremove) leaves nothing but the system users and groups
# (Debian policy keeps those): the file tree before install and after purge
# are compared.
# Environment: PKGCHECK_DIR (default /tmp/coslam-pkgcheck: base root cache
# and the run's root), SUITE (bookworm), MIRROR (http://deb.debian.org/debian),
# KEEP=1 keeps the run's root for inspection.
# Needs debootstrap (tools/deps.sh install chroot). Not in CI: it downloads
# a Debian base system (4.5 minutes the first time here, then 16 s).
set -eu
t0=$(date +%s)
here=$(cd "$(dirname "$0")/.." && pwd)
arch=$(dpkg --print-architecture)
deb=${1:-}
if [ -z "$deb" ]; then
  deb=$(ls "$here"/out/package/coslam-robot_*_"$arch".deb 2>/dev/null | tail -n 1 || true)
fi
if [ -z "$deb" ] || [ ! -f "$deb" ]; then
  echo "package_check: no package (make package, or give the .deb)" >&2; exit 2
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "package_check: needs root (debootstrap, chroot)" >&2; exit 2
fi
if [ "$(dpkg-deb -f "$deb" Architecture)" != "$arch" ]; then
  echo "package_check: $deb is not for $arch (a foreign package cannot run in this root)" >&2; exit 2
fi
command -v debootstrap >/dev/null || "$here"/tools/deps.sh install chroot

dir=${PKGCHECK_DIR:-/tmp/coslam-pkgcheck}
suite=${SUITE:-bookworm}
mirror=${MIRROR:-http://deb.debian.org/debian}
base=$dir/base-$suite-$arch
root=$dir/root
mkdir -p "$dir"

fail() { echo "package_check: FAIL: $*" >&2; exit 1; }
say() { echo "package_check: $*"; }
inroot() { chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin LC_ALL=C.UTF-8 \
                  DEBIAN_FRONTEND=noninteractive "$@"; }

unmount_root() {
  for m in "$root/proc" "$root/dev/pts"; do
    if mountpoint -q "$m" 2>/dev/null; then umount "$m" || umount -l "$m"; fi
  done
}
cleanup() {
  unmount_root
  if [ "${KEEP:-0}" != 1 ]; then rm -rf "$root"; fi
}
trap cleanup EXIT INT TERM

# 1. the clean root: debootstrap once, a fresh copy per run
if [ ! -f "$base/.complete" ]; then
  say "debootstrap --variant=minbase $suite ($mirror) into $base"
  rm -rf "$base"
  debootstrap --variant=minbase "$suite" "$base" "$mirror" >"$dir/debootstrap.log" 2>&1 ||
    { tail -n 20 "$dir/debootstrap.log" >&2; fail "debootstrap"; }
  touch "$base/.complete"
fi
unmount_root
rm -rf "$root"
cp -a "$base" "$root"
rm -f "$root/.complete"
cp /etc/resolv.conf "$root/etc/resolv.conf"
mount -t proc proc "$root/proc"
inroot apt-get update -qq >/dev/null

# the file tree (and the content of /etc) before the package
snapshot() {
  inroot sh -c 'find / -xdev \( -path /proc -o -path /sys -o -path /dev -o -path /tmp -o -path /run \
      -o -path /var/cache -o -path /var/lib/apt -o -path /var/lib/dpkg -o -path /var/log \) -prune \
      -o -print | LC_ALL=C sort; find /etc -xdev -type f -exec md5sum {} + | LC_ALL=C sort -k2'
}
snapshot >"$dir/before.txt"

# 2. install
cp "$deb" "$root/tmp/"
pkg=/tmp/$(basename "$deb")
say "apt-get install $pkg"
inroot apt-get install -y -q --no-install-recommends "$pkg" >"$dir/install.log" 2>&1 ||
  { tail -n 30 "$dir/install.log" >&2; fail "apt-get install"; }
grep -E '^(Setting up|Unpacking) ' "$dir/install.log" | sed 's/^/  /'

# 3. what it installed
for f in /usr/bin/coslam-robot /etc/coslam/robot.ini /lib/systemd/system/coslam-robot.service \
         /lib/udev/rules.d/60-coslam-gpio.rules /usr/share/doc/coslam-robot/README.md; do
  [ -e "$root$f" ] || fail "$f is missing"
done
[ -x "$root/usr/bin/coslam-robot" ] || fail "coslam-robot is not executable"
inroot dpkg-query -W -f='${Conffiles}\n' coslam-robot | grep -q '/etc/coslam/robot.ini' ||
  fail "/etc/coslam/robot.ini is not a conffile"
inroot getent passwd coslam >/dev/null || fail "no user coslam"
inroot getent group gpio >/dev/null || fail "no group gpio"
[ "$(inroot stat -c '%U:%G %a' /var/lib/coslam)" = "coslam:coslam 750" ] ||
  fail "/var/lib/coslam: $(inroot stat -c '%U:%G %a' /var/lib/coslam)"
if inroot ldd /usr/bin/coslam-robot | grep -q 'not found'; then
  inroot ldd /usr/bin/coslam-robot >&2; fail "unresolved libraries"
fi
say "files, conffile, user coslam, group gpio, /var/lib/coslam (coslam:coslam 750), libraries: ok"
say "Depends: $(inroot dpkg-query -W -f='${Depends}' coslam-robot)"

# 4. run it: the default configuration wants the fleet key
set +e
out=$(inroot runuser -u coslam -- /usr/bin/coslam-robot --dry-run 2>&1); rc=$?
set -e
[ "$rc" -eq 2 ] || { echo "$out" >&2; fail "--dry-run without the fleet key: exit $rc, expected 2"; }
echo "$out" | grep -q 'fleet.key' || { echo "$out" >&2; fail "the refusal does not name the key file"; }
say "no fleet key: refuses to start (exit 2): $(echo "$out" | grep -m1 'fleet.key')"
inroot sh -c 'od -An -tx1 -N32 /dev/urandom | tr -d " \n" > /etc/coslam/fleet.key &&
              chown root:coslam /etc/coslam/fleet.key && chmod 0640 /etc/coslam/fleet.key'
set +e
out=$(inroot runuser -u coslam -- /usr/bin/coslam-robot --dry-run 2>/dev/null); rc=$?
set -e
echo "$out" | sed 's/^/  | /'
[ "$rc" -eq 0 ] || fail "--dry-run as user coslam: exit $rc"
for d in laser can gpio; do
  echo "$out" | grep -Eq "^$d +down" || fail "--dry-run does not report the missing $d"
done
say "--dry-run as user coslam with the key: exit 0, laser, can, gpio reported down"

# 5. reinstall keeps a locally edited conffile; remove keeps it; purge removes all
inroot sh -c 'echo "; local edit" >> /etc/coslam/robot.ini'
inroot apt-get install -y -q --reinstall "$pkg" >>"$dir/install.log" 2>&1 || fail "reinstall"
grep -q '; local edit' "$root/etc/coslam/robot.ini" || fail "reinstall lost the local edit of robot.ini"
inroot apt-get remove -y -q coslam-robot >"$dir/remove.log" 2>&1 || fail "apt-get remove"
[ ! -e "$root/usr/bin/coslam-robot" ] || fail "remove left the binary"
[ -f "$root/etc/coslam/robot.ini" ] || fail "remove took the conffile"
say "reinstall kept the edited conffile; remove: binary gone, conffile kept"
inroot apt-get purge -y -q --autoremove coslam-robot >"$dir/purge.log" 2>&1 || fail "apt-get purge"
grep -E '^(Removing|Purging) ' "$dir/purge.log" | sed 's/^/  /'
inroot dpkg -l coslam-robot 2>/dev/null | grep -q '^[a-z][a-z] *coslam-robot' && fail "still known to dpkg"
snapshot >"$dir/after.txt"
# allowed to stay: the system user and group "coslam" and the group "gpio"
# (passwd, group, shadow, gshadow and their "-" backups)
left=$(diff "$dir/before.txt" "$dir/after.txt" |
       grep -E '^[<>]' | grep -Ev ' /etc/(passwd|group|shadow|gshadow)-?$' || true)
if [ -n "$left" ]; then echo "$left" >&2; fail "purge left changes behind"; fi
for f in passwd group; do
  diff "$root/etc/$f" "$base/etc/$f" | sed -n "s/^< /  left in \/etc\/$f (policy): /p"
done
say "purge: nothing left but the system user and groups"
say "PASS ($(basename "$deb"), $(( $(date +%s) - t0 )) s)"
