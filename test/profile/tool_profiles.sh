#!/bin/sh
# Every tool of a build prints the build's capacity profile at start-up
# ("<tool>: profile NAME: ..."), the same line (app/profile.h), and the run
# outputs carry it (metrics.json "profile"). Usage:
#   tool_profiles.sh WORK PROFILE PARTICLES LANDMARKS SIGHTINGS TOOL=PATH...
# A tool whose path is empty (not built) is skipped; each check runs the
# tool briefly (a short run, --dry-run, or a run stopped by a bad argument
# after the line is printed).
set -u
work=$1 profile=$2 particles=$3 landmarks=$4 sightings=$5
shift 5
mkdir -p "$work"
fails=0
want="profile $profile: $particles particles, $landmarks landmarks \\(EKF-SLAM [0-9]+\\), $sightings sightings per frame, [0-9]+ landmarks per map message \([0-9]+ B, link payload [0-9]+ B\)"
check() { # name, log, [expected profile name]
    if grep -Eq "^$1: $want" "$2"; then
        echo "ok   $1: $(grep -E "^$1: profile" "$2" | head -1)"
    else
        echo "FAIL $1: no start-up line matching '$1: $want'; its output:"
        sed 's/^/     /' "$2" | head -20
        fails=$((fails + 1))
    fi
}
for spec in "$@"; do
    name=${spec%%=*}
    bin=${spec#*=}
    [ -n "$bin" ] && [ -x "$bin" ] || { echo "skip $name (not built)"; continue; }
    log="$work/$name.log"
    case $name in
    coslam-sim)
        "$bin" --duration 1 --quiet --out "$work/sim" > "$log" 2>&1
        check "$name" "$log"
        if ! /usr/bin/python3 -c "import json,sys; p=json.load(open(sys.argv[1]))['profile']; \
sys.exit(not (p['name']==sys.argv[2] and p['particles']==int(sys.argv[3]) and p['landmarks']==int(sys.argv[4]) \
and p['sightings_per_frame']==int(sys.argv[5]) and p['msg_max_bytes']+64<=p['link_payload_bytes']))" \
            "$work/sim/metrics.json" "$profile" "$particles" "$landmarks" "$sightings"; then
            echo "FAIL coslam-sim: metrics.json has no matching \"profile\" object"
            fails=$((fails + 1))
        else
            echo "ok   coslam-sim: metrics.json \"profile\""
        fi ;;
    coslam-replay)
        "$bin" run "$work/no-such-dataset" -o "$work/replay" > "$log" 2>&1 ;;
    coslam-calibrate)
        "$bin" --evals 0 -o "$work/cal" > "$log" 2>&1 ;;
    coslam-robot)
        "$bin" -c "$ROBOT_INI" --dry-run > "$log" 2>&1 ;;
    coslam-bench-odo-check)
        "$bin" --checks 1 --out "$work/bench" > "$log" 2>&1 ;;
    coslam-bench-filters)
        # an --out that cannot be made stops it after its start-up line (a
        # bad --seeds is refused before it)
        "$bin" --seeds 1 --out /dev/null/bench > "$log" 2>&1 ;;
    coslam-eval-worlds)
        "$bin" --world nowhere > "$log" 2>&1 ;;
    coslam-bench-merge | coslam-bench-fastslam)
        # their own core (host/bench/CMakeLists.txt): the line names it
        timeout 5 "$bin" --out "$work/bench" > "$log" 2>&1
        if grep -Eq "^$name: profile bench-own: 1000 particles, 2048 landmarks" "$log"; then
            echo "ok   $name: $(grep -E "^$name: profile" "$log" | head -1)"
        else
            echo "FAIL $name: no 'profile bench-own' start-up line"
            fails=$((fails + 1))
        fi
        continue ;;
    *)
        echo "FAIL $name: no check for this tool"
        fails=$((fails + 1))
        continue ;;
    esac
    [ "$name" = coslam-sim ] || check "$name" "$log"
done
[ "$fails" -eq 0 ] || { echo "$fails failure(s)"; exit 1; }
echo "all tools report profile $profile"
