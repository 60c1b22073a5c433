#!/bin/sh
# CPU use of coslam-robot at its configured rates (docs/robot.md, "CPU").
#
#   tools/robot_cpu.sh [SECONDS] [FILTER]     (defaults: 30 s, fastslam2)
#   BUILD=dir tools/robot_cpu.sh ...          (default build dir: build)
#
# The robot runs as on the robot: 10 ms control step, the URG laser at
# 10 scans/s (the simulator's URG emulator on a pty, byte for byte:
# urg_pty_bridge), the camera at 5 frames/s (the landmark-log replay source,
# six landmarks in view), a snapshot every 30 s, the status line every 10 s;
# no CAN bus or GPIO on this machine (no drive, no motion). Measured from
# /proc/<pid>/stat (user + system time over the run after a 2 s warm-up),
# as a percentage of one core; the robot's own getrusage figure (status
# line cpu_pct, whole run) is printed beside it. Not a pass/fail test.
set -eu
SECONDS_RUN=${1:-30}
FILTER=${2:-fastslam2}
BUILD=${BUILD:-build}
ROBOT=$BUILD/firmware/port/linux/coslam-robot
BRIDGE=$BUILD/test/port_linux/urg_pty_bridge
for f in "$ROBOT" "$BRIDGE"; do
    [ -x "$f" ] || { echo "robot_cpu.sh: $f missing (build the coslam-robot and urg_pty_bridge targets)" >&2; exit 2; }
done
DIR=$(mktemp -d /tmp/coslam-robot-cpu-XXXXXX)
BPID=""
RPID=""
cleanup() {
    [ -n "$RPID" ] && kill "$RPID" 2>/dev/null || true
    [ -n "$BPID" ] && kill "$BPID" 2>/dev/null || true
    wait 2>/dev/null || true
    rm -rf "$DIR"
}
trap cleanup EXIT INT TERM

# six landmarks seen from the origin at 5 Hz, for the whole run (looped)
awk 'BEGIN { srand(7); n = split("2.0 0.5 2.5 -0.8 3.0 1.2 1.5 -0.3 3.5 0.2 2.2 1.6", v, " ");
  for (k = 0; k < 300; ++k) { t = 0.2 * k;
    for (i = 1; i < n; i += 2) { x = v[i]; y = v[i + 1];
      r = sqrt(x * x + y * y) + 0.02 * (rand() - 0.5); b = atan2(y, x) + 0.02 * (rand() - 0.5);
      if (b < 0.43 && b > -0.43) printf "Z %.3f %d %.4f %.5f\n", t, (i - 1) / 2, r, b } } }' > "$DIR/lm.log"

# the fleet key: the robot runs its DDS link (authenticated) as on a robot
head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$DIR/fleet.key"
chmod 600 "$DIR/fleet.key"

cat > "$DIR/robot.ini" <<EOF
[robot]
step_period_s = 0.01
status_period_s = 10
snapshot_period_s = 30
[laser]
device = $DIR/urg
[can]
interface =
[gpio]
chip =
[camera]
replay_log = $DIR/lm.log
[storage]
dir = $DIR/store
[filter]
type = $FILTER
[link]
domain = 199
[fleet]
key_file = $DIR/fleet.key
EOF

"$BRIDGE" "$DIR/urg" &
BPID=$!
i=0
while [ ! -L "$DIR/urg" ] && [ $i -lt 100 ]; do sleep 0.05; i=$((i + 1)); done

"$ROBOT" -c "$DIR/robot.ini" 2> "$DIR/err" &
RPID=$!
TCK=$(getconf CLK_TCK)
ticks() { awk '{ print $14 + $15 }' "/proc/$1/stat"; }
sleep 2
T0=$(ticks "$RPID")
W0=$(date +%s.%N)
sleep "$SECONDS_RUN"
T1=$(ticks "$RPID")
W1=$(date +%s.%N)
BT=$(ticks "$BPID")
kill -TERM "$RPID"
wait "$RPID" || true
RPID=""
PCT=$(echo "$T0 $T1 $W0 $W1 $TCK" | awk '{ printf "%.2f", 100 * ($2 - $1) / $5 / ($4 - $3) }')
echo "coslam-robot CPU ($FILTER, ${SECONDS_RUN} s, 10 ms step, laser 10 Hz on a pty, camera 5 Hz): $PCT % of one core"
grep "coslam-robot: status" "$DIR/err" | tail -1 | tr ' ' '\n' | grep -E '^(steps|overruns|late_max_us|scans|frames|landmarks|cpu_pct)=' | tr '\n' ' '
echo
echo "(the URG emulator bridge itself used $BT ticks of CPU; machine load: $(cut -d' ' -f1-3 /proc/loadavg))"
