#!/bin/sh
# The vision host tools (coslam-vision-eval, -fit, -train) refuse counts
# outside their range (exit 2, the option and the range said), and a report,
# figure, colour table or range model they cannot write (a full disk: a
# symlink to /dev/full) is "cannot write PATH: No space left on device",
# exit 1 (they ignored the write before and exited 0).
#   tools_cli.sh WORK EVAL FIT TRAIN
set -u
WORK=$1
EVAL=$2
FIT=$3
TRAIN=$4
fail=0
rm -rf "$WORK"
mkdir -p "$WORK/img"
# expect RC TEXT CMD...: exit RC and TEXT in the output
expect() {
  want_rc=$1
  want=$2
  shift 2
  out=$("$@" 2>&1); rc=$?
  if [ $rc -ne "$want_rc" ] || ! printf '%s\n' "$out" | grep -qF -- "$want"; then
    echo "FAIL: $(basename "$1") ${*#"$1"} gave exit $rc, wanted $want_rc and '$want': $(printf '%s\n' "$out" | tail -2)"
    fail=1
  else
    echo "ok: $(basename "$1") -> $(printf '%s\n' "$out" | grep -F -- "$want" | head -1)"
  fi
}
expect 2 "--frames: value 0 outside [1, 1000000]" "$EVAL" --frames 0
expect 2 "--frames: value -1 outside [1, 1000000]" "$FIT" --frames -1 --out "$WORK/never.txt"
expect 2 "--per-bin: value 0 outside [1, 100000]" "$TRAIN" --per-bin 0 --lut "$WORK/never.bin"
[ ! -e "$WORK/never.txt" ] && [ ! -e "$WORK/never.bin" ] || { echo "FAIL: a refused command wrote a file"; fail=1; }
if [ -e /dev/full ]; then
  for f in eval.json img/example1.png model.txt samples.txt lut.bin report.md; do
    ln -s /dev/full "$WORK/$f"
  done
  nospace="No space left on device"
  expect 1 "cannot write $WORK/eval.json: $nospace" "$EVAL" --frames 2 --json "$WORK/eval.json"
  expect 1 "cannot write $WORK/img/example1.png: $nospace" "$EVAL" --frames 2 --dump --images "$WORK/img"
  expect 1 "cannot write $WORK/samples.txt: $nospace" "$FIT" --frames 2 --out "$WORK/m.txt" --dump-samples "$WORK/samples.txt"
  expect 1 "cannot write $WORK/model.txt: $nospace" "$FIT" --frames 40 --out "$WORK/model.txt"
  expect 1 "cannot write $WORK/lut.bin: $nospace" "$TRAIN" --train 1 --val 1 --test 1 --lut "$WORK/lut.bin" \
    --report "$WORK/r.md"
  expect 1 "cannot write $WORK/report.md: $nospace" "$TRAIN" --train 1 --val 1 --test 1 --lut "$WORK/l.bin" \
    --report "$WORK/report.md"
fi
exit $fail
