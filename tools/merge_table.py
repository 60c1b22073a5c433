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


GOALS = ("spurious > 1", "more spurious than alone", "landmark RMSE higher", "pose RMSE higher")


def goals_missed(fm, fa, pm_, pa_):
    """Issue 8's per-robot goals that a run with merging misses against its
    run alone: (index into GOALS, message) for each."""
    missed = []
    if fm["n_spurious"] > 1:
        missed.append((0, f"{fm['n_spurious']} spurious with merging (goal <= 1)"))
    if fm["n_spurious"] > fa["n_spurious"]:
        missed.append((1, "more spurious with merging"))
    # rmse_m is None where no landmark could be matched after the fit
    if fm["rmse_m"] is None and fa["rmse_m"] is not None:
        missed.append((2, "no landmark matched with merging"))
    elif fm["rmse_m"] is not None and fa["rmse_m"] is not None and fm["rmse_m"] > fa["rmse_m"] + 1e-9:
        missed.append((2, "landmark RMSE higher with merging"))
    if pm_ is not None and pa_ is not None and pm_ > pa_ + 1e-9:
        missed.append((3, "pose RMSE higher with merging"))
    return missed


def seed_table(out, seeds):
    """Fast-SLAM 2.0 over particle seeds: per robot, the seeds missing each goal."""
    for d in (6, 1):
        runs = []
        for s in seeds:
            pm, pa = f"{out}/d{d}_fastslam2_s{s}/metrics.json", f"{out}/d{d}_fastslam2_s{s}_alone/metrics.json"
            if not (os.path.exists(pm) and os.path.exists(pa)):
                print(f"missing {pm} or {pa}")
                continue
            runs.append((load(pm), load(pa)))
        if not runs:
            continue
        print(f"\n### Dataset {d}, Fast-SLAM 2.0 over particle seeds {' '.join(seeds)}: per robot, seeds that miss "
              f"a goal\n")
        print(f"| robot | {' | '.join(GOALS)} | any goal missed | spurious merge / alone (sum) |")
        print("|---|---|---|---|---|---|---|")
        tot_bad = tot = sp_m = sp_a = 0
        for k in range(len(runs[0][0]["robots"])):
            cnt = [0, 0, 0, 0]
            bad = sm = sa = 0
            for m, a in runs:
                rm, ra = m["robots"][k], a["robots"][k]
                fm, fa = rm["map_fit"], ra["map_fit"]
                pm_, pa_ = rm["pose"].get("rmse_m"), ra["pose"].get("rmse_m")
                missed = goals_missed(fm, fa, pm_, pa_)
                for g, _ in missed:
                    cnt[g] += 1
                bad += int(bool(missed))
                sm += fm["n_spurious"]
                sa += fa["n_spurious"]
            n = len(runs)
            pose = "n/a" if runs[0][0]["robots"][k]["pose"].get("rmse_m") is None else f"{cnt[3]} / {n}"
            print(f"| {runs[0][0]['robots'][k]['id']} | {cnt[0]} / {n} | {cnt[1]} / {n} | {cnt[2]} / {n} | {pose} | "
                  f"{bad} / {n} | {sm} / {sa} |")
            tot_bad += bad
            tot += n
            sp_m += sm
            sp_a += sa
        print(f"\nRobot-runs missing a goal: {tot_bad} of {tot}; spurious landmarks {sp_m} with merging, "
              f"{sp_a} alone.")


# What the tables (this one's and team_table.py's) read of each robot of a
# metrics.json: FIELD: (type, may be
# null). "pose" is an object whose rmse_m and fit_rmse_m may be absent.
_NUMBER = (int, float)
ROBOT_FIELDS = {
    "map_fit": (dict, False),
    "map_fit.n_spurious": (_NUMBER, False),
    "map_fit.rmse_m": (_NUMBER, True),
    "pose": (dict, False),
}
# ... and what this table reads besides
MERGE_ROBOT_FIELDS = dict(ROBOT_FIELDS, **{"map_fit.n_estimated": (_NUMBER, False)})


def robot_problems(r, fields=ROBOT_FIELDS):
    """The fields of `fields` robot r lacks or holds as the wrong type, one
    phrase each (empty: the table can read it)."""
    problems = []
    for name, (kind, nullable) in fields.items():
        obj = r
        parts = name.split(".")
        for p in parts[:-1]:
            obj = obj.get(p) if isinstance(obj, dict) else None
        if not isinstance(obj, dict):
            continue  # its parent is missing or wrong: said for the parent
        if parts[-1] not in obj:
            problems.append(f"no '{name}'")
            continue
        v = obj[parts[-1]]
        ok = (nullable and v is None) or (isinstance(v, kind) and not isinstance(v, bool))
        if not ok:
            problems.append(f"'{name}' is {json.dumps(v)[:40]}, not "
                            f"{'an object' if kind is dict else 'a number'}{' or null' if nullable else ''}")
    return problems


def bad_inputs(out, seeds):
    """The runs main needs that are missing, empty, hold no robot, or hold
    robots without a field the table reads (MERGE_ROBOT_FIELDS: the file,
    the robot and the field named), one line each: a table without them
    would say "none" for goals it never checked, or stop with a traceback."""
    need = [f"d{d}_{f}{alone}" for d in (6, 1) for f in ("ekf", "fastslam2") for alone in ("", "_alone")]
    need += [f"d{d}_fastslam2_s{s}{alone}" for s in seeds for d in (6, 1) for alone in ("", "_alone")]
    bad = []
    for tag in need:
        path = os.path.join(out, tag, "metrics.json")
        if not os.path.isfile(path):
            bad.append(f"{path}: missing (see {os.path.join(out, tag + '.txt')})")
            continue
        try:
            robots = load(path).get("robots")
        except (ValueError, AttributeError) as e:
            bad.append(f"{path}: not a coslam-replay metrics.json ({e})")
            continue
        if not robots:
            bad.append(f"{path}: no robots")
            continue
        for r in robots:
            bad.extend(f"{path}: robot {r.get('id')}: {p}" for p in robot_problems(r, MERGE_ROBOT_FIELDS))
        if "_s" not in tag and not tag.endswith("_alone"):  # main reads its merge counts
            mg = load(path).get("merges")
            if not isinstance(mg, dict) or not all(k in mg for k in ("merged", "refused_range_check")):
                bad.append(f"{path}: no 'merges' with 'merged' and 'refused_range_check'")
    return bad


def main(out, seeds):
    if not os.path.isdir(out):
        sys.exit(f"merge_table: no folder {out} (the outputs of tools/merge_table.sh)")
    bad = bad_inputs(out, seeds)
    if bad:
        sys.exit("merge_table: no table, runs missing, empty or incomplete:\n  " + "\n  ".join(bad))
    verdicts = []
    fitted = []
    for d in (6, 1):
        for f, name in (("ekf", "EKF-SLAM"), ("fastslam2", "Fast-SLAM 2.0")):
            pm, pa = f"{out}/d{d}_{f}/metrics.json", f"{out}/d{d}_{f}_alone/metrics.json"
            m, a = load(pm), load(pa)  # both there (bad_inputs)
            mg = m["merges"]
            print(f"\n### Dataset {d}, {name}: {mg['merged']} merges, refused {mg.get('refused_disagree', 0)} "
                  f"(maps disagree) + {mg.get('refused_lost', 0)} (receiver lost) + {mg['refused_range_check']} "
                  f"(ranges disagree); {mg.get('stale', 0)} stale\n")
            print("| robot | spurious merge / alone | landmark RMSE (fit) merge / alone [m] | "
                  "pose RMSE merge / alone [m] | pose RMSE in the fitted map merge / alone [m] | "
                  "landmarks merge / alone |")
            print("|---|---|---|---|---|---|")
            for rm, ra in zip(m["robots"], a["robots"]):
                fm, fa = rm["map_fit"], ra["map_fit"]
                pm_, pa_ = rm["pose"].get("rmse_m"), ra["pose"].get("rmse_m")
                # the pose in the frame of the map's rigid fit (coslam-replay
                # pose.fit_rmse_m): information, not one of the goals
                qm, qa = rm["pose"].get("fit_rmse_m"), ra["pose"].get("fit_rmse_m")
                print(f"| {rm['id']} | {fm['n_spurious']} / {fa['n_spurious']} | {fmt(fm['rmse_m'])} / "
                      f"{fmt(fa['rmse_m'])} | {fmt(pm_)} / {fmt(pa_)} | {fmt(qm)} / {fmt(qa)} | "
                      f"{fm['n_estimated']} / {fa['n_estimated']} |")
                for _, w in goals_missed(fm, fa, pm_, pa_):
                    verdicts.append(f"Dataset {d}, {name}, robot {rm['id']}: {w}")
                if qm is not None and qa is not None and qm > qa + 1e-9:
                    fitted.append(f"Dataset {d}, {name}, robot {rm['id']}: {qm:.3f} / {qa:.3f} m")
    if seeds:
        seed_table(out, seeds)
    print("\n### Goals not met\n")
    for v in verdicts or ["none"]:
        print(f"- {v}")
    print("\n### Pose in the fitted map higher with merging (information, merge / alone)\n")
    for v in fitted or ["none"]:
        print(f"- {v}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "out/merge_table", sys.argv[2:])
