#!/bin/sh
# test/replay/probe_inputs.sh - hostile and absurd inputs to coslam-replay and
# coslam-sim (issue 12): each probe must end with the expected exit code and
# say why (a message matching a pattern), print no raw binary, and the runs
# that are accepted must leave no NaN in the map they write.
#
#   probe_inputs.sh REPLAY_BIN SIM_BIN SCENARIO WORK_DIR [TABLE_OUT]
#
# TABLE_OUT (optional) receives a markdown table of every probe (the closing
# note of issue 12 and docs/robustness.md use it).
set -u
REPLAY=$1
SIM=$2
SCENARIO=$3
WORK=$4
TABLE=${5:-}
rm -rf "$WORK"
mkdir -p "$WORK"
fails=0
rows=""

# A small, valid two-robot landmark log: 20 s of driving at 10 Hz, a
# landmark field around the path, the robots sighting each other.
mk_base() {
    d=$1
    mkdir -p "$d"
    for k in 1 2; do
        awk -v k="$k" 'BEGIN {
            print "# probe base log, robot " k
            for (i = 0; i <= 200; i++) {
                t = i * 0.1
                printf "V %.1f 0.2 0.05\n", t
                if (i % 5 == 0) {
                    printf "Z %.1f -1 %.3f %.3f\n", t, 2.0 + 0.3 * sin(i), 0.2 * cos(i)
                    printf "Z %.1f -1 %.3f %.3f\n", t, 3.0 + 0.2 * cos(i), -0.3 * sin(i)
                }
                if (i == 100) printf "R %.1f %d 1.5 0.1\n", t, 3 - k
            }
        }' > "$d/robot$k.log"
    done
}

# probe NAME EXPECTED_RC PATTERN CMD...: run, check rc and stderr+stdout
probe() {
    name=$1
    want=$2
    pat=$3
    shift 3
    out="$WORK/out.txt"
    timeout 120 "$@" > "$out" 2>&1
    rc=$?
    msg=$(grep -E -m1 -i -- "$pat" "$out" | cut -c1-160)
    ok=1
    if [ "$want" = "nz" ]; then
        [ "$rc" -ne 0 ] || ok=0
    else
        [ "$rc" -eq "$want" ] || ok=0
    fi
    [ -n "$msg" ] || ok=0
    # no raw binary in what the tool printed
    if LC_ALL=C grep -q -P '[^\x09\x0a\x0d\x20-\x7e]' "$out"; then
        ok=0
        msg="$msg [raw binary in the output]"
    fi
    status=PASS
    if [ $ok -ne 1 ]; then
        status=FAIL
        fails=$((fails + 1))
        echo "FAIL $name: rc $rc (want $want), pattern '$pat'"
        sed -n 1,12p "$out"
    else
        echo "ok   $name: rc $rc: $msg"
    fi
    rows="$rows| $name | $rc | $(printf '%s' "$msg" | sed 's/|/\\|/g') | $status |
"
}

# the maps and paths an accepted run wrote have no NaN/inf
no_nan_map() {
    name=$1
    dir=$2
    # (other CSVs write nan for "no ground truth": not checked)
    if grep -l -i -E '(^|[ ,])(-?nan|-?inf)' "$dir"/robot*_map*.csv "$dir"/robot*_path.tum 2>/dev/null | head -1 | grep -q .; then
        echo "FAIL $name: NaN/inf in the map or path of $dir"
        grep -l -i -E '(^|[ ,])(-?nan|-?inf)' "$dir"/robot*_map*.csv "$dir"/robot*_path.tum | head -3
        fails=$((fails + 1))
    fi
}

# variant NAME ROBOT SED: $d = a fresh copy of the base log, robot ROBOT's
# log edited by the sed expression SED ('$a LINE' appends LINE)
variant() {
    d="$WORK/$1"
    mk_base "$d"
    sed -i "$3" "$d/robot$2.log"
}

R="$REPLAY run --no-plots -q"
B="$WORK/base"
mk_base "$B"
probe "valid log" 0 "outputs in" $R "$B" -o "$WORK/r0"
# the capacity profile the binaries were built with (their first line): the
# capacity probes below fill the default and large profiles' limits; the
# host profile's (2,048 landmarks, 64 sightings per frame) are beyond them
profile=$(sed -n 's/.*: profile \([a-z]*\):.*/\1/p' "$WORK/out.txt" | head -1)

# command-line values
probe "-p 0" 2 "outside|particles" $R "$B" -f fastslam2 -p 0 -o "$WORK/r"
probe "-p -5" 2 "outside" $R "$B" -p -5 -o "$WORK/r"
probe "-p 100000" 2 "outside" $R "$B" -p 100000 -o "$WORK/r"
probe "-d -5" 2 "outside" $R "$B" -d -5 -o "$WORK/r"
probe "-d nan" 2 "not a finite number" $R "$B" -d nan -o "$WORK/r"
probe "--merge-window nan" 2 "not a finite number" $R "$B" --merge-window nan -o "$WORK/r"
probe "--merge-interval -1" 2 "outside" $R "$B" --merge-interval -1 -o "$WORK/r"
probe "--seed -3" 2 "outside" $R "$B" --seed -3 -o "$WORK/r"
probe "-r 0" 2 "outside" $R "$B" -r 0 -o "$WORK/r"
probe "--robot-filter 20-digit id" 2 "robot id" $R "$B" --robot-filter 99999999999999999999=ekf -o "$WORK/r"

# files
probe "missing dataset folder" 2 "no such folder|not a folder" $R "$WORK/nope" -o "$WORK/r"
for id in 0 17 99999999999999999999; do
    d="$WORK/id$id"
    mk_base "$d"
    mv "$d/robot2.log" "$d/robot$id.log"
    probe "robot id $id from a file name" 2 "robot id .* outside 1\.\.16" $R "$d" -o "$WORK/r"
done
d="$WORK/empty"
mk_base "$d"
echo "# nothing recorded" > "$d/robot2.log"
probe "empty robot log" 2 "no odometry records" $R "$d" -o "$WORK/r"
variant unknownR 1 '$a R 20.0 7 1.0 0.0'
probe "R record naming robot 7 (not in the data)" 0 "robots not in the dataset" $R "$d" -o "$WORK/r"
variant negt 1 '2i V -5.0 0.2 0.05'
probe "negative first time stamp" 2 "outside \[0, 1e\+06\]" $R "$d" -o "$WORK/r"
variant t1e15 1 '$a V 1e15 0 0'
probe "final record at t = 1e15 s" 2 "outside \[0, 1e\+06\]" $R "$d" -o "$WORK/r"
variant bearing 1 '$a Z 20.0 -1 2.0 1e308'
probe "bearing 1e308" 2 "bearing 1e\+308 rad outside" $R "$d" -o "$WORK/r"
variant range 1 's/^Z 10.0 -1 [0-9.]* /Z 10.0 -1 1e308 /'
probe "range 1e308 (beyond the [input] range limit, counted)" 0 "sightings_range_dropped" $R "$d" -o "$WORK/rr"
no_nan_map "range 1e308" "$WORK/rr"
variant early 1 '/^V 0.0 /d'
probe "sightings before the first odometry record (counted, said)" 0 "before its first odometry record not used" $R "$d" -o "$WORK/re"
variant subnormal 1 's/^Z 10.0 -1 [0-9.]* /Z 10.0 -1 1e-310 /'
probe "subnormal range 1e-310 (refused by the core, counted)" 0 "rejected_sightings" $R "$d" -o "$WORK/rs"
variant vhuge 1 's/^V 10.0 .*/V 10.0 1e308 1e308/'
probe "V t 1e308 1e308" 0 "rejected_controls" $R "$d" -o "$WORK/rv"
no_nan_map "V 1e308" "$WORK/rv"
variant ohuge 1 's/^V 10.0 .*/O 10.0 1e308 1e308 1e308/'
probe "O t 1e308 1e308 1e308" 0 "rejected_controls" $R "$d" -o "$WORK/ro"
no_nan_map "O 1e308" "$WORK/ro"
d="$WORK/huge"
mk_base "$d"
truncate -s 2G "$d/robot2.log"
probe "2 GB file (sparse zeros)" 2 "more than the 256 MiB limit" $R "$d" -o "$WORK/r"
rm -f "$d/robot2.log"
d="$WORK/longline"
mk_base "$d"
head -c 300000 /dev/zero | tr '\0' 'x' >> "$d/robot2.log"
probe "300 kB line without newline" 2 "line longer than 4096 bytes" $R "$d" -o "$WORK/r"
d="$WORK/binary"
mk_base "$d"
printf 'V 20.5 0.2 \001\377\033[31m\n' >> "$d/robot2.log"
probe "binary bytes in a field" 2 "not a number: 'x01xffx1b|not a number: '\\\\x01" $R "$d" -o "$WORK/r"
variant dblmax 2 '$a Z 20.5 -1 -1.7976931348623157e308 0.0'
probe "range -DBL_MAX (short message)" 2 "range must be positive, got -1.79769e\+308" $R "$d" -o "$WORK/r"

if [ "$profile" = host ]; then
    echo "skip capacity probes: built for the host profile, whose capacities this data does not reach"
else
# capacities. The map: a 300 m corridor with a marker about every metre on
# both sides (600 landmarks, irregular so that the corridor is not periodic,
# up to 7 in view), exact odometry; the core's map (64 landmarks in the
# default profile, 256 in the large) fills at about 32 m (128 m).
d="$WORK/capacity"
mkdir -p "$d"
printf '[odometry]\nscale_v = 1\nscale_w = 1\ndelay_s = 0\n' > "$WORK/exact_odometry.ini"
for k in 1 2; do
    awk -v k="$k" 'function fr(v) { return v - int(v) }
    BEGIN {
        for (j = 0; j < 300; j++) {
            for (s = 0; s < 2; s++) {
                X[j, s] = j + 0.6 * fr(sin(j * 12.9898 + s * 78.233) * 43758.5453)
                Y[j, s] = (2 * s - 1) * (1.0 + 0.8 * fr(sin(j * 39.346 + s * 11.135) * 24634.634))
            }
        }
        for (i = 0; i <= 6000; i++) {
            t = i * 0.1
            printf "V %.1f %.1f 0\n", t, (k == 1 ? 0.5 : 0.0)
            if (k != 1 || i % 5 != 0) continue
            for (j = 0; j < 300; j++) {
                for (s = 0; s < 2; s++) {
                    lx = X[j, s] - 0.5 * t
                    r = sqrt(lx * lx + Y[j, s] * Y[j, s])
                    b = atan2(Y[j, s], lx)
                    if (lx > 0.5 && r < 3.5 && b < 0.8 && b > -0.8) printf "Z %.1f -1 %.4f %.4f\n", t, r, b
                }
            }
        }
    }' > "$d/robot$k.log"
    awk -v k="$k" 'BEGIN { for (i = 0; i <= 6000; i++) printf "%.1f %.3f 0 0\n", i * 0.1, (k == 1 ? 0.05 * i : 0.0) }' \
        > "$d/robot${k}_truth.txt"
done
probe "capacity: map full (600 landmarks)" 3 "LIMIT robot 1: .* COSLAM_(EKF_)?MAX_LANDMARKS = " \
    $R "$d" -c "$WORK/exact_odometry.ini" -f ekf -o "$WORK/rc"
# the full map still localises the robot: sightings of unmapped markers are
# not forced onto mapped ones (pose RMSE, the column after the filter)
rmse=$(awk '$1 == "1" && $2 == "ekf" { print $3 }' "$WORK/out.txt")
if ! awk -v e="$rmse" 'BEGIN { exit !(e != "" && e + 0 < 0.2) }'; then
    echo "FAIL capacity: robot 1 pose RMSE '$rmse' m with a full map (want < 0.2)"
    fails=$((fails + 1))
else
    echo "ok   capacity: robot 1 pose RMSE $rmse m with a full map"
fi
no_nan_map "capacity" "$WORK/rc"
probe "capacity: map full, --allow-capacity-limits" 0 "LIMIT robot 1: .* COSLAM_(EKF_)?MAX_LANDMARKS = " \
    $R "$d" -c "$WORK/exact_odometry.ini" -f ekf --allow-capacity-limits -o "$WORK/rc"
# the sighting buffer: one frame of 24 sightings (16 per frame in the default
# and large profiles; the host profile takes 64, and this probe is for those)
variant frame 1 '$a Z 20.5 -1 1.0 0.0'
for i in $(seq 1 23); do echo "Z 20.5 -1 $((i / 6 + 1)).$((i % 6 + 1)) 0.0$i" >> "$d/robot1.log"; done
probe "capacity: 24 sightings in one frame" 3 "LIMIT robot 1: .* COSLAM_MAX_SIGHTINGS = 16" $R "$d" -f ekf -o "$WORK/r"
fi

# the simulator
probe "coslam-sim --duration 1e7" nz "outside" "$SIM" --scenario "$SCENARIO" --duration 1e7 --quiet --out "$WORK/s"
probe "coslam-sim --duration nan" nz "not a finite number" "$SIM" --scenario "$SCENARIO" --duration nan --quiet --out "$WORK/s"
sed 's/^start = \[1.0, 0.0, 0.0\].*/start = [2.0, 1.3, 0.0]/' "$SCENARIO" > "$WORK/in_box.toml"
probe "scenario: robot started inside a box" 2 "overlaps box" "$SIM" --scenario "$WORK/in_box.toml" --quiet --out "$WORK/s"
sed 's/^start = \[1.0, 0.0, 0.0\].*/start = [9.0, 0.0, 0.0]/' "$SCENARIO" > "$WORK/outside.toml"
probe "scenario: robot started outside the arena" 2 "outside the arena" "$SIM" --scenario "$WORK/outside.toml" --quiet --out "$WORK/s"
sed 's/^start = \[1.0, 0.0, 0.0\].*/start = [-1.1, 0.0, 0.0]/' "$SCENARIO" > "$WORK/overlap.toml"
probe "scenario: robots on top of each other" 2 "overlaps robot" "$SIM" --scenario "$WORK/overlap.toml" --quiet --out "$WORK/s"
sed 's/^\[timing\]/[timing]\nbogus_key = 3/' "$SCENARIO" > "$WORK/badkey.toml"
probe "scenario: unknown key (line number)" 2 "line [0-9]+: timing.bogus_key: unknown key" "$SIM" --scenario "$WORK/badkey.toml" --quiet --out "$WORK/s"
if [ "$profile" != host ]; then
# a simulated map that cannot fit: a marker every 0.3 m over the arena
# (about 700), far more than COSLAM_MAX_LANDMARKS in the default and large
# profiles (the host profile skips this), and more in
# one frame than COSLAM_MAX_SIGHTINGS
awk 'BEGIN { skip = 0 }
    /^landmarks = \[/ {
        print "landmarks = ["
        for (x = -4.2; x <= 4.2; x += 0.3) for (y = -3.2; y <= 3.2; y += 0.3)
            if (x * x + y * y > 2.0) printf "  { pos = [%.2f, %.2f], signature = %d },\n", x, y, int((x + 5) * 7 + (y + 4) * 3) % 4
        skip = 1; next
    }
    skip && /^\]/ { print "]"; skip = 0; next }
    !skip { print }' "$SCENARIO" > "$WORK/dense.toml"
probe "coslam-sim: map full (dense markers)" 3 "LIMIT robot [01]: .* COSLAM_MAX_(LANDMARKS|SIGHTINGS) = " \
    "$SIM" --scenario "$WORK/dense.toml" --camera oracle --duration 20 --quiet --out "$WORK/sd"
probe "coslam-sim: map full, --allow-capacity-limits" 0 "LIMIT robot [01]: " \
    "$SIM" --scenario "$WORK/dense.toml" --camera oracle --duration 20 --allow-capacity-limits --quiet --out "$WORK/sd"
fi

if [ -n "$TABLE" ]; then
    {
        echo "| probe | exit | message (first line matching) | |"
        echo "|---|---|---|---|"
        printf '%s' "$rows"
    } > "$TABLE"
fi
if [ $fails -ne 0 ]; then
    echo "$fails probe(s) failed"
    exit 1
fi
echo "all probes behave"
