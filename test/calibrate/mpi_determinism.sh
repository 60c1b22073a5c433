#!/bin/sh
# mpirun -np 2 coslam-calibrate twice with one seed: the same result, bit
# for bit (calibrated.ini is written with %.17g). Also the same as one
# process with threads: the evaluator's reduction is order-independent.
# Exit 77 (CTest: skipped) without mpirun or without an MPI build.
set -u
BIN=$1
WORK=$2
if ! command -v mpirun >/dev/null 2>&1; then
  echo "SKIP: mpirun not found (apt-get install openmpi-bin)"; exit 77
fi
if "$BIN" --help 2>/dev/null | grep -qi "built without MPI"; then
  echo "SKIP: coslam-calibrate built without MPI"; exit 77
fi
rm -rf "$WORK"; mkdir -p "$WORK"
ARGS="--train-seeds 1-3 --test-seeds 101 --evals 20 --lambda 10 --seed 5 -q"
MPI="mpirun --allow-run-as-root --oversubscribe -np 2"
export OMPI_MCA_btl=self,vader OMPI_MCA_rmaps_base_oversubscribe=1
for run in a b; do
  $MPI "$BIN" $ARGS -j 1 -o "$WORK/np2_$run" > "$WORK/np2_$run.log" 2>&1 || { cat "$WORK/np2_$run.log"; exit 1; }
done
"$BIN" $ARGS -j 2 -o "$WORK/np1" > "$WORK/np1.log" 2>&1 || { cat "$WORK/np1.log"; exit 1; }
grep -q "x 2 process(es)" "$WORK/np2_a.log" || { echo "FAIL: not 2 processes"; cat "$WORK/np2_a.log"; exit 1; }
cat "$WORK/np2_a/report.txt"
cmp "$WORK/np2_a/calibrated.ini" "$WORK/np2_b/calibrated.ini" || { echo "FAIL: -np 2 twice differ"; exit 1; }
cmp "$WORK/np2_a/calibrated.ini" "$WORK/np1/calibrated.ini" || { echo "FAIL: -np 2 and -j 2 differ"; exit 1; }
b1=$(grep '"best_fitness_m"' "$WORK/np2_a/report.json"); b2=$(grep '"best_fitness_m"' "$WORK/np2_b/report.json")
[ "$b1" = "$b2" ] || { echo "FAIL: best fitness differs: $b1 / $b2"; exit 1; }
echo "OK: identical results ($b1)"
