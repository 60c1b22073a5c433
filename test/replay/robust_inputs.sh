#!/bin/sh
# test/replay/robust_inputs.sh - bad input that coslam-replay used to take
# silently (a directory in place of a file, empty required files, a NUL byte,
# odometry gaps, periods too small to advance, fit-odometry with nothing to
# fit, 0.000 printed for what was not measured, settings for robots not in
# the data, figures not drawn, standard output on a full disk): each case
# must end with the expected exit code and say why.
#
#   robust_inputs.sh REPLAY_BIN SOURCE_DIR WORK_DIR
set -u
REPLAY=$1
SRC=$2
WORK=$3
rm -rf "$WORK"
mkdir -p "$WORK"
fails=0

# check NAME EXPECTED_RC PATTERN CMD...: run (at most 60 s: a hang fails),
# check the exit code and that the output has a line matching PATTERN
check() {
    name=$1
    want=$2
    pat=$3
    shift 3
    out="$WORK/out.txt"
    timeout 60 "$@" > "$out" 2>&1
    rc=$?
    msg=$(grep -E -m1 -- "$pat" "$out" | cut -c1-200)
    if [ "$rc" -ne "$want" ] || [ -z "$msg" ]; then
        fails=$((fails + 1))
        echo "FAIL $name: rc $rc (want $want), pattern '$pat'"
        sed -n 1,12p "$out"
    else
        echo "ok   $name: rc $rc: $msg"
    fi
}

# A small two-robot landmark log (20 s at 10 Hz) with robot ground truth
mk_log() {
    d=$1
    mkdir -p "$d"
    for k in 1 2; do
        awk -v k="$k" 'BEGIN {
            for (i = 0; i <= 200; i++) {
                t = i * 0.1
                printf "V %.1f 0.2 0.05\n", t
                if (i % 5 == 0) printf "Z %.1f -1 %.3f %.3f\n", t, 2.0 + 0.3 * sin(i), 0.2 * cos(i)
            }
        }' > "$d/robot$k.log"
        awk -v k="$k" 'BEGIN { for (i = 0; i <= 200; i++) printf "%.1f %.3f %.3f 0\n", i * 0.1, 0.02 * i, k }' \
            > "$d/robot${k}_truth.txt"
    done
}

# A small MRCLAM folder: robots 1 and 2 (barcodes 11, 12), landmarks 6-8
# (barcodes 16-18), 20 s of odometry at 50 Hz, sightings, ground truth
mk_mrclam() {
    d=$1
    mkdir -p "$d"
    printf '1 11\n2 12\n6 16\n7 17\n8 18\n' > "$d/Barcodes.dat"
    printf '6 3.0 0.0 0 0\n7 2.0 2.0 0 0\n8 0.0 2.0 0 0\n' > "$d/Landmark_Groundtruth.dat"
    for k in 1 2; do
        awk 'BEGIN { for (i = 0; i <= 1000; i++) printf "%.2f 0.1 0.0\n", 1000 + i * 0.02 }' > "$d/Robot${k}_Odometry.dat"
        awk 'BEGIN { for (i = 0; i <= 40; i++) printf "%.2f 16 %.3f 0.0\n", 1000 + i * 0.5, 3.0 - 0.05 * i }' \
            > "$d/Robot${k}_Measurement.dat"
        awk 'BEGIN { for (i = 0; i <= 200; i++) printf "%.2f %.3f 0.0 0.0\n", 1000 + i * 0.1, 0.01 * i }' \
            > "$d/Robot${k}_Groundtruth.dat"
    done
}

R="$REPLAY run --no-plots -q -f ekf"
B="$WORK/log"
mk_log "$B"
check "valid landmark log" 0 "outputs in" $R "$B" -o "$WORK/r"
M="$WORK/mrclam"
mk_mrclam "$M"
check "valid MRCLAM folder" 0 "outputs in" $R "$M" -o "$WORK/r"

# 1. periods too small to advance the replay's clock (the run never ended)
check "shipped config accepted" 0 "predict_period_s" "$REPLAY" print-config -c "$SRC/host/replay/mrclam6.ini"
for kv in "filter predict_period_s" "eval map_period_s" "eval pose_period_s"; do
    set -- $kv
    printf '[%s]\n%s = 1e-300\n' "$1" "$2" > "$WORK/tiny_$2.ini"
    check "$2 = 1e-300" 2 "\[$1\] $2 = 1e-300 outside" $R "$B" -c "$WORK/tiny_$2.ini" -o "$WORK/r"
done
printf '[filter]\npredict_period_s = 1e300\n' > "$WORK/huge_period.ini"
check "predict_period_s = 1e300" 2 "predict_period_s = 1e\+300 outside" $R "$B" -c "$WORK/huge_period.ini" -o "$WORK/r"

# 2. a directory in place of a file (read as an empty file before)
check "print-config -c a directory" 2 "$WORK: is a directory" "$REPLAY" print-config -c "$WORK"
d="$WORK/dir_log"
mk_log "$d"
rm "$d/robot2.log" && mkdir "$d/robot2.log"
check "robot2.log is a directory" 2 "robot2.log: is a directory" $R "$d" -o "$WORK/r"
d="$WORK/dir_truth"
mk_log "$d"
rm "$d/robot1_truth.txt" && mkdir "$d/robot1_truth.txt"
check "robot1_truth.txt is a directory" 2 "robot1_truth.txt: is a directory" $R "$d" -o "$WORK/r"
d="$WORK/dir_gt"
mk_mrclam "$d"
rm "$d/Robot1_Groundtruth.dat" && mkdir "$d/Robot1_Groundtruth.dat"
check "Robot1_Groundtruth.dat is a directory" 2 "Robot1_Groundtruth.dat: is a directory" $R "$d" -o "$WORK/r"
d="$WORK/fifo"
mk_mrclam "$d"
rm "$d/Robot2_Measurement.dat" && mkfifo "$d/Robot2_Measurement.dat"
check "Robot2_Measurement.dat is a FIFO" 2 "Robot2_Measurement.dat: not a regular file" $R "$d" -o "$WORK/r"

# 3. required files without records
d="$WORK/empty_barcodes"
mk_mrclam "$d"
echo "# Subject # Barcode #" > "$d/Barcodes.dat"
check "empty Barcodes.dat" 2 "Barcodes.dat: no records" $R "$d" -o "$WORK/r"
d="$WORK/empty_landmarks"
mk_mrclam "$d"
: > "$d/Landmark_Groundtruth.dat"
check "empty Landmark_Groundtruth.dat" 2 "Landmark_Groundtruth.dat: no records" $R "$d" -o "$WORK/r"

# 4. odometry gaps: warned above 2 s (metrics.json too), refused above 3600 s
d="$WORK/gap"
mk_log "$d"
sed -i '/^V \(5\.[1-9]\|[67]\.[0-9]\|8\.0\) /d' "$d/robot1.log"
check "3.1 s odometry gap" 0 "warning: robot 1: 1 gap\(s\) of more than 2 s .* largest 3\.1 s \(before .*robot1\.log:" \
    $R "$d" -o "$WORK/rg"
if ! grep -q '"odometry_gaps": *{ *"1": *{[^}]*"count": *1' "$WORK/rg/metrics.json" \
    && ! tr -d ' \n' < "$WORK/rg/metrics.json" | grep -q '"odometry_gaps":{"1":{"count":1'; then
    fails=$((fails + 1))
    echo "FAIL 3.1 s odometry gap: no odometry_gaps count in metrics.json"
fi
d="$WORK/gap_mrclam"
mk_mrclam "$d"
echo "501011.00 0.1 0.0" >> "$d/Robot2_Odometry.dat"
check "stray odometry line 5.8 days later" 2 "Robot2_Odometry.dat:1002: odometry gap of 499991 s" $R "$d" -o "$WORK/r"
d="$WORK/gap_hour"
mk_log "$d"
echo "V 3621.0 0.2 0.05" >> "$d/robot2.log"
check "3601 s odometry gap" 2 "robot2.log:[0-9]+: odometry gap of 3601 s .* 3600 s limit" $R "$d" -o "$WORK/r"

# 5. fit-odometry with no ground truth: nothing fitted is an error
d="$WORK/no_truth"
mk_log "$d"
rm "$d"/robot*_truth.txt
check "fit-odometry without ground truth" 2 "nothing fitted" "$REPLAY" fit-odometry "$d"

# 6. nothing matched: n/a and null, not 0.000
d="$WORK/far"
mk_log "$d"
printf '1 1000 1000\n2 1001 1000\n3 1000 1002\n' > "$d/landmarks_truth.txt"
check "no landmark matched: map RMSE n/a" 0 "^ +1  ekf +[0-9.]+ +[0-9.]+ +[0-9.]+ +n/a " $R "$d" -o "$WORK/rf"
if ! tr -d ' \n' < "$WORK/rf/metrics.json" | grep -q '"map":{[^}]*"n_matched":0,[^}]*"rmse_m":null'; then
    fails=$((fails + 1))
    echo "FAIL no landmark matched: map.rmse_m is not null in metrics.json"
fi

# 7. a NUL byte ends the line early (the rest was ignored)
d="$WORK/nul"
mk_log "$d"
printf 'V 20.5 0.2 0.05\000 junk\n' >> "$d/robot2.log"
check "NUL byte in a line" 2 "robot2.log:[0-9]+: NUL byte" $R "$d" -o "$WORK/r"

# 8. settings for a robot not in the data
check "--robot-filter 9=ekf" 0 "note: settings for robot\(s\) 9 .* not used" $R "$B" --robot-filter 9=ekf -o "$WORK/r"

# 9. an output file that cannot be written whole (a full disk: /dev/full
# fails every write with ENOSPC) is an error naming it and the OS's reason,
# exit 1; it used to exit 0 with a short or empty file
if [ -e /dev/full ]; then
    for f in metrics.json errors.csv robot1_path.tum robot2_map.csv merge_events.csv; do
        d="$WORK/full_$f"
        mkdir -p "$d"
        ln -s /dev/full "$d/$f"
        check "full disk: run -o, $f" 1 "^coslam-replay: cannot write $d/$f: No space left on device" $R "$B" -o "$d"
    done
    d="$WORK/full_convert"
    mkdir -p "$d"
    ln -s /dev/full "$d/robot1.log"
    check "full disk: convert, robot1.log" 1 "^coslam-replay: cannot write $d/robot1.log: No space left on device" \
        "$REPLAY" convert "$M" "$d"
    check "full disk: fit-noise -o" 1 "^coslam-replay: cannot write /dev/full: No space left on device" \
        "$REPLAY" fit-noise "$M" -o /dev/full
    : > "$WORK/plain_file"
    check "output folder under a file" 1 "^coslam-replay: cannot create the output folder $WORK/plain_file/r: Not a directory" \
        $R "$B" -o "$WORK/plain_file/r"
else
    echo "skip full disk: no /dev/full"
fi

# 10. figures asked for that cannot be drawn (the plot script fails) are an
# error line and exit 4 (was a warning and exit 0); a plot script that
# works (python3 runs /dev/null: exit 0) leaves exit 0
check "plot script fails" 4 "^coslam-replay: error: the figures were not drawn: the plotter exited with status 2 " \
    env COSLAM_PLOT_REPLAY="$WORK/no_such_plot.py" "$REPLAY" run -q -f ekf "$B" -o "$WORK/rp"
if ! grep -q "^outputs in $WORK/rp " "$WORK/out.txt" || [ ! -s "$WORK/rp/metrics.json" ]; then
    fails=$((fails + 1))
    echo "FAIL plot script fails: the summary or metrics.json missing"
fi
check "plot script works" 0 "outputs in" env COSLAM_PLOT_REPLAY=/dev/null "$REPLAY" run -q -f ekf "$B" -o "$WORK/rp"
check "--no-plots with a failing plot script" 0 "outputs in" \
    env COSLAM_PLOT_REPLAY="$WORK/no_such_plot.py" $R "$B" -o "$WORK/rp"

# 11. standard output that cannot be written (a full disk) is an error,
# exit 1, whatever was written to files (was exit 0 with the output lost)
# full_stdout NAME PATTERN CMD...: stdout on /dev/full, stderr checked
full_stdout() {
    name=$1
    pat=$2
    shift 2
    timeout 60 "$@" > /dev/full 2> "$WORK/err.txt"
    rc=$?
    msg=$(grep -E -m1 -- "$pat" "$WORK/err.txt" | cut -c1-200)
    if [ "$rc" -ne 1 ] || [ -z "$msg" ]; then
        fails=$((fails + 1))
        echo "FAIL $name: rc $rc (want 1), pattern '$pat'"
        sed -n 1,12p "$WORK/err.txt"
    else
        echo "ok   $name: rc $rc: $msg"
    fi
}
if [ -e /dev/full ]; then
    enospc="^coslam-replay: cannot write standard output: No space left on device"
    full_stdout "stdout full: run" "$enospc" $R "$B" -o "$WORK/rs"
    full_stdout "stdout full: print-config" "$enospc" "$REPLAY" print-config
    full_stdout "stdout full: fit-odometry" "$enospc" "$REPLAY" fit-odometry "$B"
    full_stdout "stdout full: --help" "$enospc" "$REPLAY" --help
    # a bad input stays exit 2 (nothing ran), the lost stdout said as well
    timeout 60 "$REPLAY" run --no-such-option > /dev/full 2> "$WORK/err.txt"
    rc=$?
    if [ $rc -ne 2 ]; then
        fails=$((fails + 1))
        echo "FAIL stdout full: bad option: rc $rc (want 2)"
    else
        echo "ok   stdout full: bad option: rc 2"
    fi
else
    echo "skip stdout full: no /dev/full"
fi

if [ $fails -ne 0 ]; then
    echo "$fails case(s) failed"
    exit 1
fi
echo "all cases behave"
