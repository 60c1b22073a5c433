#!/usr/bin/python3
"""Summary table of the replays under a folder (tools/run_replay.sh):
one row per setting (robots, merging) x filter x identities, the means over
the robots of each run (and over the runs of a group, e.g. the seven pairs);
the landmark RMSE is pooled over all matched landmarks of those robots.

usage: replay_table.py OUT_DIR   (reads OUT_DIR/*/metrics.json)
"""
import glob
import json
import math
import os
import sys

GROUPS = [("5r", "5 robots, merging"), ("5r-nomerge", "5 robots, each alone"), ("2r", "2 robots (7 pairs), merging")]


def main():
    d = sys.argv[1]
    runs = {}
    for p in sorted(glob.glob(os.path.join(d, "*", "metrics.json"))):
        name = os.path.basename(os.path.dirname(p))
        setting, filt, ids = name.rsplit("_", 2)
        group = "2r" if setting.startswith("2r-") else setting
        with open(p) as f:
            runs.setdefault((group, filt, ids), []).append(json.load(f))
    print("| setting | filter | ids | pose RMSE [m] | heading RMSE [deg] | pose NEES | landmark RMSE [m] | "
          "landmarks | spurious | missed | merges | transform err RMSE [m / deg] | transform NEES | "
          "time/step mean / max [us] | wall [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for group, label in GROUPS:
        for filt in ("ekf", "fastslam2"):
            for ids in ("unknown", "known"):
                ms = runs.get((group, filt, ids))
                if not ms:
                    continue
                robots = [r for m in ms for r in m["robots"]]
                n = len(robots)
                pose = sum(r["pose"]["rmse_m"] for r in robots) / n
                head = sum(r["pose"]["heading_rmse_deg"] for r in robots) / n
                nees = sum(r["pose"]["nees_mean"] for r in robots) / n
                nm = sum(r["map"]["n_matched"] for r in robots)
                lm = math.sqrt(sum(r["map"]["rmse_m"] ** 2 * r["map"]["n_matched"] for r in robots) / nm) if nm else 0.0
                est = sum(r["map"]["n_estimated"] for r in robots) / n
                spur = sum(r["map"]["n_spurious"] for r in robots) / n
                miss = sum(r["map"]["n_missed"] for r in robots) / n
                step = sum(r["steps"]["step_us_mean"] for r in robots) / n
                stepmax = max(r["steps"]["step_us_max"] for r in robots)
                merges = sum(m["merges"]["merged"] for m in ms)
                ev = [e for m in ms for e in m["merges"]["events"] if "t_err_m" in e and e["status"] in ("OK", "E_CAPACITY")]
                if ev:
                    terr = math.sqrt(sum(e["t_err_m"] ** 2 for e in ev) / len(ev))
                    trad = math.degrees(math.sqrt(sum(e["t_err_rad"] ** 2 for e in ev) / len(ev)))
                    tnees = sum(e["t_nees"] for e in ev) / len(ev)
                    tcol = "%.3f / %.2f" % (terr, trad)
                    tn = "%.2f" % tnees
                else:
                    tcol, tn = "-", "-"
                wall = sum(m["timing"]["wall_s"] for m in ms)
                fname = filt if filt == "ekf" else "%s (%d)" % (filt, ms[0]["robots"][0]["particles"])
                print("| %s | %s | %s | %.3f | %.1f | %.1f | %.3f | %.1f | %.1f | %.1f | %d | %s | %s | %.0f / %.0f | %.1f |"
                      % (label, fname, ids, pose, head, nees, lm, est, spur, miss, merges, tcol, tn, step, stepmax, wall))
    return 0


if __name__ == "__main__":
    sys.exit(main())
