#!/bin/sh
# Runs the libFuzzer targets of test/fuzz (docs/fuzzing.md).
#
#   run_fuzz.sh ctest <exe> <scratch_dir> <seed_dir> [libFuzzer args...]
#       CTest: a fresh scratch corpus (new inputs go there, never into the
#       source tree) plus the seed corpus; deterministic with -seed/-runs.
#   run_fuzz.sh long <build_dir> <out_dir> <seconds> [target...]
#       `make fuzz`: each target (all of <build_dir>/test/fuzz/fuzz_targets.txt
#       by default) for <seconds> with a persistent corpus <out_dir>/<target>
#       (seeded from the seed corpus), crash artifacts in <out_dir>/crashes/,
#       logs in <out_dir>/<target>.log; then a summary table (executions,
#       exec/s, cov, ft, corpus) into <out_dir>/summary.md and stdout.
#       Exit status 1 if any target found a failure.
set -eu
mode=${1:-}
case "$mode" in
ctest)
    exe=$2 scratch=$3 seeds=$4
    shift 4
    rm -rf "$scratch"
    mkdir -p "$scratch"
    exec "$exe" -artifact_prefix="$scratch/" -print_final_stats=1 "$@" "$scratch" "$seeds"
    ;;
long)
    build=$2 out=$3 secs=$4
    shift 4
    list="$build/test/fuzz/fuzz_targets.txt"
    if [ ! -f "$list" ]; then
        echo "run_fuzz.sh: $list missing (no clang with libFuzzer at configure time?)" >&2
        exit 2
    fi
    mkdir -p "$out/crashes"
    summary="$out/summary.md"
    printf '| target | seconds | executions | exec/s | cov | ft | corpus | result |\n|---|---|---|---|---|---|---|---|\n' >"$summary.tmp"
    fail=0
    while IFS='|' read -r name exe seeds args; do
        [ -n "$name" ] || continue
        if [ $# -gt 0 ]; then
            case " $* " in *" $name "*) ;; *) continue ;; esac
        fi
        mkdir -p "$out/$name"
        log="$out/$name.log"
        echo "== $name: ${secs} s, corpus $out/$name" >&2
        rc=0
        # shellcheck disable=SC2086 # args is a list of libFuzzer flags
        "$exe" -max_total_time="$secs" -print_final_stats=1 -artifact_prefix="$out/crashes/$name-" \
            $args "$out/$name" "$seeds" >"$log" 2>&1 || rc=$?
        runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
        rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n 1)
        last=$(grep -E '^#[0-9]+' "$log" | tail -n 1 || true)
        cov=$(printf '%s\n' "$last" | sed -n 's/.* cov: \([0-9]*\).*/\1/p')
        ft=$(printf '%s\n' "$last" | sed -n 's/.* ft: \([0-9]*\).*/\1/p')
        corp=$(printf '%s\n' "$last" | sed -n 's/.* corp: \([0-9]*\/[0-9]*[a-zA-Z]*\).*/\1/p')
        if [ "$rc" -eq 0 ]; then
            res=ok
        else
            res="FAIL (rc $rc, $log)"
            fail=1
        fi
        printf '| %s | %s | %s | %s | %s | %s | %s | %s |\n' "$name" "$secs" "${runs:-?}" "${rate:-?}" \
            "${cov:-?}" "${ft:-?}" "${corp:-?}" "$res" >>"$summary.tmp"
    done <"$list"
    mv "$summary.tmp" "$summary"
    cat "$summary"
    exit $fail
    ;;
*)
    sed -n '2,16p' "$0" >&2
    exit 2
    ;;
esac
