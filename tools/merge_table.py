#!/usr/bin/python3
"""Per-robot table of merging against no merging (tools/merge_table.sh)."""
import json
import os
import sys


def load(path):
    with open(path) as f:
        return json.load(f)


def fmt(v, nd=3):
    return "n/a" if v is None else f"{v:.{nd}f}"


def main(out):
    verdicts = []
    for d in (6, 1):
        for f, name in (("ekf", "EKF-SLAM"), ("fastslam2", "Fast-SLAM 2.0")):
            pm, pa = f"{out}/d{d}_{f}/metrics.json", f"{out}/d{d}_{f}_alone/metrics.json"
            if not (os.path.exists(pm) and os.path.exists(pa)):
                print(f"missing {pm} or {pa}")
                continue
            m, a = load(pm), load(pa)
            mg = m["merges"]
            print(f"\n### Dataset {d}, {name}: {mg['merged']} merges, refused {mg.get('refused_disagree', 0)} "
                  f"(maps disagree) + {mg['refused_range_check']} (ranges disagree); {mg.get('stale', 0)} stale\n")
            print("| robot | spurious merge / alone | landmark RMSE (fit) merge / alone [m] | "
                  "pose RMSE merge / alone [m] | landmarks merge / alone |")
            print("|---|---|---|---|---|")
            worse = []
            for rm, ra in zip(m["robots"], a["robots"]):
                fm, fa = rm["map_fit"], ra["map_fit"]
                pm_, pa_ = rm["pose"].get("rmse_m"), ra["pose"].get("rmse_m")
                print(f"| {rm['id']} | {fm['n_spurious']} / {fa['n_spurious']} | {fmt(fm['rmse_m'])} / "
                      f"{fmt(fa['rmse_m'])} | {fmt(pm_)} / {fmt(pa_)} | {fm['n_estimated']} / {fa['n_estimated']} |")
                if fm["n_spurious"] > 1:
                    worse.append(f"robot {rm['id']}: {fm['n_spurious']} spurious with merging (goal <= 1)")
                if fm["n_spurious"] > fa["n_spurious"]:
                    worse.append(f"robot {rm['id']}: more spurious with merging")
                if fm["rmse_m"] > fa["rmse_m"] + 1e-9:
                    worse.append(f"robot {rm['id']}: landmark RMSE higher with merging")
                if pm_ is not None and pa_ is not None and pm_ > pa_ + 1e-9:
                    worse.append(f"robot {rm['id']}: pose RMSE higher with merging")
            for w in worse:
                verdicts.append(f"Dataset {d}, {name}, {w}")
    print("\n### Goals not met\n")
    for v in verdicts or ["none"]:
        print(f"- {v}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "out/merge_table")
