#!/usr/bin/python3
"""Summary table of the replays under a folder (tools/run_replay.sh):
one row per setting (robots, merging) x filter x identities, the means over
the robots of each run (and over the runs of a group, e.g. the seven pairs);
the landmark RMSE is pooled over all matched landmarks of those robots.
Figures that need the robots' ground truth (pose, map-frame landmark
figures, transform errors) are null in metrics.json without it: they are
averaged over the robots that have them, "n/a" if none does. The "fit"
column (landmark RMSE / spurious / missed after the best rigid fit of each
map onto the true landmarks, docs/replay.md) needs the landmarks only.

usage: replay_table.py OUT_DIR   (reads OUT_DIR/*/metrics.json)
"""
import glob
import json
import math
import os
import sys

GROUPS = [("5r", "5 robots, merging"), ("5r-nomerge", "5 robots, each alone"), ("2r", "2 robots (7 pairs), merging")]


def mean(values):
    """Mean of the values that are not None (null: no ground truth), or None."""
    v = [x for x in values if x is not None]
    return sum(v) / len(v) if v else None


def fmt(fmt_str, value):
    return "n/a" if value is None else fmt_str % value


def pooled_rmse(scores):
    """RMSE pooled over the matched landmarks of map scores (dicts with rmse_m, n_matched)."""
    s = [m for m in scores if m.get("n_matched") is not None and m.get("rmse_m") is not None]
    if not s:
        return None
    nm = sum(m["n_matched"] for m in s)
    return math.sqrt(sum(m["rmse_m"] ** 2 * m["n_matched"] for m in s) / nm) if nm else 0.0


def main():
    if len(sys.argv) != 2:
        print("usage: replay_table.py OUT_DIR", file=sys.stderr)
        return 2
    d = sys.argv[1]
    if not os.path.isdir(d):
        print(f"replay_table: no folder {d}", file=sys.stderr)
        return 1
    found = sorted(glob.glob(os.path.join(d, "*", "metrics.json")))
    if not found:
        print(f"replay_table: no {d}/*/metrics.json (the coslam-replay runs of tools/run_replay.sh): no table",
              file=sys.stderr)
        return 1
    runs = {}
    for p in found:
        name = os.path.basename(os.path.dirname(p))
        if name.count("_") < 2:
            print(f"replay_table: {p}: not a SETTING_FILTER_IDS folder, left out", file=sys.stderr)
            continue
        setting, filt, ids = name.rsplit("_", 2)
        group = "2r" if setting.startswith("2r-") else setting
        with open(p) as f:
            runs.setdefault((group, filt, ids), []).append(json.load(f))
    filters, idents = ("ekf", "fastslam2"), ("unknown", "known")
    if not any(runs.get((g, f, i)) for g, _ in GROUPS for f in filters for i in idents):
        print(f"replay_table: none of the {len(found)} runs under {d} is of a setting, filter and identities "
              f"of the table ({', '.join(g for g, _ in GROUPS)}; ekf, fastslam2; unknown, known): no table",
              file=sys.stderr)
        return 1
    print("| setting | filter | ids | pose RMSE [m] | heading RMSE [deg] | pose NEES | landmark RMSE [m] | "
          "landmarks | spurious | missed | fit: landmark RMSE [m] / spurious / missed | merges | "
          "transform err RMSE [m / deg] | transform NEES | time/step mean / max [us] | wall [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for group, label in GROUPS:
        for filt in filters:
            for ids in idents:
                ms = runs.get((group, filt, ids))
                if not ms:
                    continue
                robots = [r for m in ms for r in m["robots"]]
                n = len(robots)
                pose = mean(r["pose"]["rmse_m"] for r in robots)
                head = mean(r["pose"]["heading_rmse_deg"] for r in robots)
                nees = mean(r["pose"]["nees_mean"] for r in robots)
                lm = pooled_rmse(r["map"] for r in robots)
                est = sum(r["map"]["n_estimated"] for r in robots) / n
                spur = mean(r["map"].get("n_spurious") for r in robots)
                miss = mean(r["map"].get("n_missed") for r in robots)
                fits = [r["map_fit"] for r in robots if r.get("map_fit", {}).get("evaluated")]
                if fits:
                    fcol = "%s / %.1f / %.1f" % (fmt("%.3f", pooled_rmse(fits)),
                                                 mean(f["n_spurious"] for f in fits), mean(f["n_missed"] for f in fits))
                else:
                    fcol = "n/a"
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
                print("| %s | %s | %s | %s | %s | %s | %s | %.1f | %s | %s | %s | %d | %s | %s | %.0f / %.0f | %.1f |"
                      % (label, fname, ids, fmt("%.3f", pose), fmt("%.1f", head), fmt("%.1f", nees), fmt("%.3f", lm),
                         est, fmt("%.1f", spur), fmt("%.1f", miss), fcol, merges, tcol, tn, step, stepmax, wall))
    return 0


if __name__ == "__main__":
    sys.exit(main())
