#!/bin/sh
# The end-to-end run (docs/e2e.md): the in-process simulator on the
# scenario for SEEDS seeds (the envelope), then the device server with two
# real coslam-robot processes (pty URG, CAN socketpair, live sightings,
# Cyclone DDS on loopback), then the comparison.
#   run_e2e.sh COSLAM_SIM COSLAM_SIM_DEVICES COSLAM_ROBOT SCENARIO OUT [SEEDS] [DURATION_S]
set -eu
sim=$1 devices=$2 robot=$3 scenario=$4 out=$5 seeds=${6:-8} duration=${7:-}
here=$(dirname "$0")
rm -rf "$out"
mkdir -p "$out/sweep"
dur_opt=""
[ -n "$duration" ] && dur_opt="--duration $duration"
s=1
while [ "$s" -le "$seeds" ]; do
    # shellcheck disable=SC2086
    "$sim" --scenario "$scenario" --camera oracle --seed "$s" $dur_opt --quiet --out "$out/sweep/seed$s" > /dev/null
    s=$((s + 1))
done
# Real time makes each e2e run one more random run (scheduling moves when
# sightings land), and in-process runs too sometimes merge one way only
# (a stale pairing): a run outside the envelope is run once more, and the
# test fails only if both are outside (docs/e2e.md). Both verdicts are printed.
attempt=1
while :; do
    # shellcheck disable=SC2086
    # robot 0's e-stop held from 60 to 64 s and robot 1's bumper pressed
    # from 62 to 63 s (after the meeting: the run stays comparable with the
    # in-process one), through the GPIO stand-in; robot 0's process stopped
    # (SIGSTOP) from 69 to 70.5 s: its drives' watchdog must stop the wheels
    "$devices" --scenario "$scenario" --robot "$robot" --out "$out/e2e" $dur_opt --domain "${COSLAM_E2E_DOMAIN:-175}" \
        --estop "${COSLAM_E2E_ESTOP:-0:60:64}" --bump "${COSLAM_E2E_BUMP:-1:62:63}" \
        --freeze "${COSLAM_E2E_FREEZE:-0:69:70.5}"
    if python3 "$here/e2e_compare.py" "$out/sweep" "$out/e2e"; then
        exit 0
    fi
    [ "$attempt" -ge 2 ] && exit 1
    echo "run_e2e: attempt $attempt outside the envelope, running once more"
    attempt=$((attempt + 1))
    rm -rf "$out/e2e"
done
