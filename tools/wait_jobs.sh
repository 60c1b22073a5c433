# Sourced by tools/merge_table.sh and tools/team_table.sh.
# wait_jobs NAME PID...: waits for each background job (`wait` alone returns
# 0 whatever they returned); if one failed (each says which run and where
# its log is), says so as NAME and exits 1: no table from partial runs.
wait_jobs() {
  _wj_name=$1
  shift
  _wj_bad=0
  for _wj_p in "$@"; do
    wait "$_wj_p" || _wj_bad=1
  done
  if [ $_wj_bad -ne 0 ]; then
    echo "$_wj_name: no table (a run failed, above)" >&2
    exit 1
  fi
}
