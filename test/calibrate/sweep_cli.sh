#!/bin/sh
# coslam-calibrate --sweep-particles on a tiny sweep (3 counts, 2 held-out
# seeds, both Fast-SLAM filters) and --figures on 2 seeds: the output files
# exist, have the expected rows, and exactly one count is chosen per filter
# and it passes the rule. The rule itself: test_calibrate_particles.
set -u
BIN=$1
WORK=$2
rm -rf "$WORK"; mkdir -p "$WORK"
fail() { echo "FAIL: $*"; exit 1; }
"$BIN" --sweep-particles 20,5,10 --sweep-filters fs1,fs2 --test-seeds 101-102 -j 2 -o "$WORK/sweep" \
  > "$WORK/sweep.log" 2>&1 || { cat "$WORK/sweep.log"; fail "sweep exit status"; }
cat "$WORK/sweep.log"
for f in sweep.csv sweep.json sweep.txt; do [ -s "$WORK/sweep/$f" ] || fail "missing $f"; done
head -1 "$WORK/sweep/sweep.csv" | grep -q '^filter,particles,episodes,mean_pos_err_m,pos_err_se_m,' || fail "csv header"
[ "$(tail -n +2 "$WORK/sweep/sweep.csv" | wc -l)" -eq 6 ] || fail "expected 6 rows (2 filters x 3 counts)"
# counts sorted ascending, 2 episodes each
[ "$(awk -F, '$1=="fs1"{printf "%s ", $2}' "$WORK/sweep/sweep.csv")" = "5 10 20 " ] || fail "counts not 5 10 20"
awk -F, 'NR>1 && $3!=2 {exit 1}' "$WORK/sweep/sweep.csv" || fail "episodes column"
for f in fs1 fs2; do
  [ "$(awk -F, -v f=$f '$1==f && $15==1' "$WORK/sweep/sweep.csv" | wc -l)" -eq 1 ] || fail "$f: not exactly one chosen"
  awk -F, -v f=$f '$1==f && $15==1 && $13!=1 {exit 1}' "$WORK/sweep/sweep.csv" || fail "$f: chosen does not pass"
  grep -q "^$f: chosen N = " "$WORK/sweep/sweep.txt" || fail "$f: no report line"
  grep -q "\"$f\"" "$WORK/sweep/sweep.json" || fail "$f: not in json"
done
"$BIN" --sweep-particles 0,5 --test-seeds 101 -o "$WORK/bad" > /dev/null 2>&1; [ $? -eq 2 ] || fail "count 0 accepted"
"$BIN" --sweep-particles 5 --sweep-filters ekf --test-seeds 101 -o "$WORK/bad" > /dev/null 2>&1; [ $? -eq 2 ] || fail "ekf sweep accepted"
[ -e "$WORK/bad" ] && fail "a refused call wrote output"
printf '[slam]\nbearing_var_rad2 = 0.002\n' > "$WORK/cal.ini"
"$BIN" --figures "$WORK/cal.ini" --test-seeds 101-102 --figure-seed 102 -j 2 -o "$WORK/fig" \
  > "$WORK/fig.log" 2>&1 || { cat "$WORK/fig.log"; fail "figures exit status"; }
for f in figures_error.csv figures_path.csv figures_map.csv figures.json; do [ -s "$WORK/fig/$f" ] || fail "missing $f"; done
grep -q '"figure_episode": "paper:102"' "$WORK/fig/figures.json" || fail "figure episode"
for s in truth hand calibrated; do grep -q "^$s," "$WORK/fig/figures_path.csv" || fail "no $s path"; done
[ "$(tail -n +2 "$WORK/fig/figures_error.csv" | wc -l)" -gt 10 ] || fail "error over time too short"
"$BIN" --figures "$WORK/cal.ini" --test-seeds 101-102 --figure-seed 7 -o "$WORK/bad" > /dev/null 2>&1
[ $? -eq 2 ] || fail "figure seed outside the held-out seeds accepted"
echo "OK"
