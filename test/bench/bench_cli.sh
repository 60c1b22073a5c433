#!/bin/sh
# The coslam-bench-* programs refuse malformed and out-of-range numbers
# and conflicting options (exit 2, the option and the accepted range said,
# before any run), say a report they cannot write (exit 1, the path and the
# OS's reason), and write no inf/nan into their JSON (null instead).
#   bench_cli.sh WORK PYTHON3 NAME=BINARY...
set -u
WORK=$1
PY=$2
shift 2
fail=0
rm -rf "$WORK"
mkdir -p "$WORK"
bin() { # NAME -> its binary, empty if not built
  for nb in $ALL; do
    [ "${nb%%=*}" = "$1" ] && { echo "${nb#*=}"; return; }
  done
}
ALL="$*"
# refused NAME EXPECTED-TEXT ARGS...: exit 2 and EXPECTED-TEXT in the output
refused() {
  b=$(bin "$1")
  want=$2
  shift 2
  [ -n "$b" ] || return 0
  out=$("$b" --out "$WORK/never" "$@" 2>&1); rc=$?
  if [ $rc -ne 2 ] || ! printf '%s\n' "$out" | grep -qF -- "$want"; then
    echo "FAIL: $(basename "$b") $* gave exit $rc, wanted 2 and '$want': $(printf '%s\n' "$out" | tail -2)"
    fail=1
  else
    echo "ok: $(basename "$b") $* -> $(printf '%s\n' "$out" | grep -F -- "$want" | head -1)"
  fi
}
refused merge "--reps 0 outside [1, 100]" --reps 0
refused merge "--reps -3 outside [1, 100]" --reps -3
refused merge "--reps 'abc': not a whole number" --reps abc
refused merge "--reps '5x': not a whole number" --reps 5x
refused filters "--seeds 0 outside [1, 100]" --seeds 0
refused filters "--seeds 'abc': not a whole number" --seeds abc
refused fastslam "--seeds 0 outside [1, 100]" --seeds 0
refused fastslam "--steps 0 outside [2, 100000]" --steps 0
refused fastslam "--steps 'abc': not a whole number" --steps abc
refused scale "--quick (Fast-SLAM 2.0, 100 particles) and --ekf (EKF-SLAM) are alternatives" --quick --ekf
refused scale "--seed 'abc': not a whole number" --seed abc
refused scale "--seed -1 outside [0," --seed -1
refused odo-check "--checks 0 outside [1, 1000000]" --checks 0
refused odo-check "--checks '5x': not a whole number" --checks 5x
refused odo-check "--odo-scale-pct 5 outside [10, 1000]" --odo-scale-pct 5
refused vision "--frames: value -1 outside [1, 5000]" --frames -1
refused vision "--frames: value 0 outside [1, 5000]" --frames 0
refused vision "--frames: value 5001 outside [1, 5000]" --frames 5001
refused vision "--repeats: value 0 outside [1, 1000]" --repeats 0
refused vision "--repeats: not an integer: abc" --repeats abc
refused mrclam "--repeats: value 0 outside [1, 100]" --repeats 0
refused mrclam "--particles: value 0 outside [1, " -p 0
refused mrclam "--mrpt-sd-range: not a finite number: nan" --mrpt-sd-range nan
refused robot-camera "usage: coslam-bench-robot-camera" --frames 3
[ ! -e "$WORK/never" ] || { echo "FAIL: a refused command line created $WORK/never"; fail=1; }

# a report that cannot be written (a full disk: a symlink to /dev/full)
full() { # NAME FILE ARGS...
  b=$(bin "$1")
  f=$2
  shift 2
  [ -n "$b" ] && [ -e /dev/full ] || return 0
  d="$WORK/full_$(basename "$b")"
  mkdir -p "$d"
  ln -s /dev/full "$d/$f"
  out=$("$b" --out "$d" "$@" 2>&1); rc=$?
  if [ $rc -ne 1 ] || ! printf '%s\n' "$out" | grep -qF "cannot write $d/$f: No space left on device"; then
    echo "FAIL: $(basename "$b") with $f on a full disk gave exit $rc: $(printf '%s\n' "$out" | tail -2)"
    fail=1
  else
    echo "ok: full disk -> $(printf '%s\n' "$out" | grep -F 'cannot write')"
  fi
}
full fastslam fastslam_scale.json --seeds 1 --steps 2 --no-flat
full odo-check odo_check.md --checks 1
full vision vision.json --frames 1 --repeats 1
full robot-camera robot_camera.md

# coslam-bench-vision streams its frames: the peak resident memory of 200
# frames is within 25 MB of one frame's (each frame held was 384 KB, RGB24
# and YUYV: +72 MB at 200 frames, 1.9 GB at the 5000 allowed)
b=$(bin vision)
if [ -n "$b" ]; then
  mkdir -p "$WORK/vision_rss"
  rss() { # FRAMES -> peak resident KB of a run (fails the test if it fails)
    "$PY" -c 'import resource, subprocess, sys
rc = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL).returncode
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss if rc == 0 else "exit %d" % rc)' \
      "$b" --frames "$1" --repeats 1 --out "$WORK/vision_rss"
  }
  r1=$(rss 1); r200=$(rss 200)
  case "$r1$r200" in
    *exit*) echo "FAIL: coslam-bench-vision runs: 1 frame $r1, 200 frames $r200"; fail=1 ;;
    *) if [ $((r200 - r1)) -gt 25600 ]; then
         echo "FAIL: coslam-bench-vision holds its frames: peak $r1 KB at 1 frame, $r200 KB at 200"; fail=1
       else
         echo "ok: coslam-bench-vision peak $r1 KB at 1 frame, $r200 KB at 200"
       fi ;;
  esac
fi

# coslam-bench-odo-check: a drive the check flags (odometry reporting 3x the
# motion) is exit 3 with the report written, not 1 as a lost report; a
# lost report stays 1 when the drive is flagged too; --help says the codes
b=$(bin odo-check)
if [ -n "$b" ]; then
  # odo_case NAME WANT-RC WANT-TEXT ARGS...: exit WANT-RC, WANT-TEXT in the output
  odo_case() {
    name=$1; want=$2; text=$3; shift 3
    out=$("$b" "$@" 2>&1); rc=$?
    if [ $rc -ne "$want" ] || ! printf '%s\n' "$out" | grep -qF -- "$text"; then
      echo "FAIL: odo-check $name: exit $rc, wanted $want and '$text': $(printf '%s\n' "$out" | tail -2)"
      fail=1
    else
      echo "ok: odo-check $name: exit $rc"
    fi
  }
  mkdir -p "$WORK/odo_clean" "$WORK/odo_fault" "$WORK/odo_full"
  odo_case "fault-free" 0 "| 5 | " --checks 5 --out "$WORK/odo_clean"
  odo_case "odometry 3x" 3 "the check flagged the drive (5 disagreements" --checks 5 --odo-scale-pct 300 \
    --out "$WORK/odo_fault"
  if ! grep -q '^| 5 | .* | [1-9][0-9]* |$' "$WORK/odo_fault/odo_check.md"; then
    echo "FAIL: odo-check odometry 3x: odo_check.md not written or nothing flagged in it"; fail=1
  fi
  if [ -e /dev/full ]; then
    ln -s /dev/full "$WORK/odo_full/odo_check.md"
    odo_case "flagged and a full disk" 1 "cannot write $WORK/odo_full/odo_check.md: No space left on device" \
      --checks 5 --odo-scale-pct 300 --out "$WORK/odo_full"
  fi
  odo_case "--help" 0 "3  the check flagged the drive" --help
fi

# every number in the JSON finite: --no-naive (the naive search not
# measured) wrote nan before; now null
b=$(bin merge)
if [ -n "$b" ]; then
  if ! "$b" --reps 1 --no-naive --out "$WORK/merge" > "$WORK/merge.txt" 2>&1; then
    echo "FAIL: coslam-bench-merge --reps 1 --no-naive: $(tail -2 "$WORK/merge.txt")"; fail=1
  elif ! "$PY" - "$WORK/merge/merge_time.json" <<'PYEOF'
import json, sys
def refuse(c):
    raise ValueError("not finite: " + c)
with open(sys.argv[1]) as f:
    text = f.read()
try:
    d = json.loads(text, parse_constant=refuse)
except ValueError as e:
    sys.exit("merge_time.json is not valid JSON (%s): %s" % (e, text[:300]))
naive = [r["naive_search_us"] for r in d["fastslam"]]
if naive != [None] * 4:
    sys.exit("naive_search_us without the naive search: %s (wanted null)" % naive)
PYEOF
  then
    fail=1
  else
    echo "ok: merge_time.json is valid JSON, naive_search_us null with --no-naive"
  fi
fi
exit $fail
