#!/usr/bin/env python3
"""tools/merge_table.py on made-up replay outputs: the per-robot goals of
issue 8 and the counts over particle seeds (tools/merge_table.sh SEEDS)."""
import contextlib
import importlib.util
import io
import json
import os
import sys
import tempfile

spec = importlib.util.spec_from_file_location("merge_table", sys.argv[1])
mt = importlib.util.module_from_spec(spec)
spec.loader.exec_module(mt)


def robot(rid, spurious, rmse, pose):
    return {"id": rid, "map_fit": {"n_spurious": spurious, "rmse_m": rmse, "n_estimated": 15},
            "pose": {"rmse_m": pose}}


def write(root, tag, robots):
    os.makedirs(f"{root}/{tag}")
    doc = {"robots": robots, "merges": {"merged": 1, "refused_range_check": 0}}
    with open(f"{root}/{tag}/metrics.json", "w") as f:
        json.dump(doc, f)


failures = []


def check(cond, what):
    if not cond:
        failures.append(what)


# one run: each goal on its own, and equality is no miss
fa = {"n_spurious": 1, "rmse_m": 0.2}
check(mt.goals_missed({"n_spurious": 1, "rmse_m": 0.2}, fa, 0.5, 0.5) == [], "equal figures miss nothing")
check([g for g, _ in mt.goals_missed({"n_spurious": 2, "rmse_m": 0.2}, fa, 0.5, 0.5)] == [0, 1], "2 spurious")
# no landmark matched after the fit (rmse_m None): a miss only with merging
check([g for g, _ in mt.goals_missed({"n_spurious": 1, "rmse_m": None}, fa, 0.5, 0.5)] == [2],
      "nothing matched with merging is a landmark miss")
check(mt.goals_missed({"n_spurious": 1, "rmse_m": None}, {"n_spurious": 1, "rmse_m": None}, 0.5, 0.5) == [],
      "nothing matched either way is no miss")
check(mt.goals_missed(fa, {"n_spurious": 1, "rmse_m": None}, 0.5, 0.5) == [], "nothing matched alone is no miss")
check([g for g, _ in mt.goals_missed({"n_spurious": 0, "rmse_m": 0.21}, fa, 0.5, 0.5)] == [2], "landmark RMSE")
check([g for g, _ in mt.goals_missed({"n_spurious": 0, "rmse_m": 0.2}, fa, 0.6, 0.5)] == [3], "pose RMSE")
check(mt.goals_missed({"n_spurious": 0, "rmse_m": 0.2}, fa, None, None) == [], "no truth: no pose goal")

with tempfile.TemporaryDirectory() as root:
    # Dataset 6, two robots, three seeds: robot 1 misses the landmark goal
    # in seeds 1 and 3, robot 2 has 2 spurious landmarks in seed 2
    for s in (1, 2, 3):
        write(root, f"d6_fastslam2_s{s}_alone", [robot(1, 0, 0.10, 0.5), robot(2, 0, 0.10, 0.5)])
        write(root, f"d6_fastslam2_s{s}",
              [robot(1, 0, 0.12 if s != 2 else 0.09, 0.4), robot(2, 2 if s == 2 else 0, 0.10, 0.5)])
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        mt.seed_table(root, ["1", "2", "3"])
    text = buf.getvalue()
    check("| 1 | 0 / 3 | 0 / 3 | 2 / 3 | 0 / 3 | 2 / 3 | 0 / 0 |" in text, "robot 1 row:\n" + text)
    check("| 2 | 1 / 3 | 1 / 3 | 0 / 3 | 0 / 3 | 1 / 3 | 2 / 0 |" in text, "robot 2 row:\n" + text)
    check("Robot-runs missing a goal: 3 of 6; spurious landmarks 2 with merging, 0 alone." in text, "total:\n" + text)
    check("Dataset 1" not in text, "no Dataset 1 table without its runs")

for f in failures:
    print("FAIL:", f)
print("test_merge_table:", "failed" if failures else "ok")
sys.exit(1 if failures else 0)
