#!/bin/sh
# coslam-eval-worlds refuses malformed numbers (exit 2, the option named,
# before any run), --help exits 0, and a write error on the .md table is an
# error naming the file.
set -u
BIN=$1
WORK=$2
fail=0
rm -rf "$WORK"
mkdir -p "$WORK"
check() {
  opt=$1
  shift
  out=$("$BIN" "$@" 2>&1); rc=$?
  if [ $rc -ne 2 ] || ! echo "$out" | grep -q -- "$opt"; then
    echo "FAIL: '$*' gave exit $rc: $out"; fail=1
  else
    echo "ok: '$*' -> $(echo "$out" | grep -- "$opt" | head -1)"
  fi
}
check --seed0 --seed0 abc
check --seed0 --seed0 -1
check --seed0 --seed0 99999999999999999999999
check --seeds --seeds 1e3
check --seeds --seeds 0
check --seeds --seeds 1001
check -p -p 5abc
check -p -p 0
check --active-radius --active-radius abc
check --active-radius --active-radius nan
check --active-radius --active-radius -2
check --active-radius --active-radius inf
check --robots --robots 2x --write-log "$WORK/never"
check --bogus --bogus
check --seeds --seeds
"$BIN" --help > "$WORK/help.txt" 2>&1; rc=$?
if [ $rc -ne 0 ] || ! grep -q "usage: coslam-eval-worlds" "$WORK/help.txt"; then
  echo "FAIL: --help gave exit $rc"; fail=1
fi
[ ! -e "$WORK/never" ] || { echo "FAIL: --write-log ran with a bad --robots"; fail=1; }
# a full disk: the .md table (symlink to /dev/full)
if [ -e /dev/full ]; then
  mkdir -p "$WORK/md"
  ln -s /dev/full "$WORK/md/paper_ekf_0.md"
  out=$("$BIN" --world paper --seeds 1 --out "$WORK/md" 2>&1); rc=$?
  if [ $rc -eq 0 ] || ! echo "$out" | grep -q "cannot write $WORK/md/paper_ekf_0.md"; then
    echo "FAIL: a full disk gave exit $rc: $(echo "$out" | tail -2)"; fail=1
  else
    echo "ok: full disk -> $(echo "$out" | grep 'cannot write')"
  fi
  mkdir -p "$WORK/log"
  ln -s /dev/full "$WORK/log/robot1.log"
  out=$("$BIN" --world paper --write-log "$WORK/log" 2>&1); rc=$?
  if [ $rc -eq 0 ] || ! echo "$out" | grep -q "cannot write $WORK/log/robot1.log"; then
    echo "FAIL: a full disk (--write-log) gave exit $rc: $(echo "$out" | tail -2)"; fail=1
  else
    echo "ok: full disk (--write-log) -> $(echo "$out" | grep 'cannot write')"
  fi
fi
exit $fail
