#!/usr/bin/python3
"""Per-robot issue-8 table of tools/team_table.sh: DIR holds sS/ (merging)
and sS_alone/ (--no-merge) coslam-replay outputs (metrics.json) for each
seed S; the goals are tools/merge_table.py's (goals_missed). A run missing,
unreadable, without robots or with robots lacking a field the table reads
(map_fit, its n_spurious and rmse_m, pose) is named, with the field (exit 1),
before any table row.
usage: team_table.py DIR SEED..."""
import importlib.util
import os
import sys

_spec = importlib.util.spec_from_file_location(
    "merge_table", os.path.join(os.path.dirname(os.path.abspath(__file__)), "merge_table.py"))
merge_table = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(merge_table)


def bad_inputs(d, seeds):
    """The runs table needs that are missing, not a coslam-replay
    metrics.json, hold no robot, hold robots without a field table reads
    (merge_table.ROBOT_FIELDS: the file, the robot and the field named), or (merged and
    alone) hold different robots, one line each: table would stop with a
    traceback on the first, or pair the robots wrongly."""
    bad = []
    for s in seeds:
        robots = {}
        for tag in (f"s{s}", f"s{s}_alone"):
            path = os.path.join(d, tag, "metrics.json")
            if not os.path.isfile(path):
                bad.append(f"{path}: missing (see {os.path.join(d, tag + '.txt')})")
                continue
            try:
                rs = merge_table.load(path).get("robots")
                robots[tag] = [r["id"] for r in rs]
            except (OSError, ValueError, AttributeError, KeyError, TypeError) as e:
                bad.append(f"{path}: not a coslam-replay metrics.json ({e})")
                continue
            if not robots[tag]:
                bad.append(f"{path}: no robots")
            for r in rs:
                bad.extend(f"{path}: robot {r['id']}: {p}" for p in merge_table.robot_problems(r))
        if len(robots) == 2 and robots[f"s{s}"] != robots[f"s{s}_alone"]:
            bad.append(f"{os.path.join(d, f's{s}')}: robots {robots[f's{s}']} merged, "
                       f"{robots[f's{s}_alone']} alone")
    return bad


def table(d, seeds):
    """Prints the table; returns (robot-runs, robot-runs missing a goal,
    spurious landmarks merged, spurious alone)."""
    print("| seed | robot | spurious alone / merged | landmark RMSE alone / merged [m] | "
          "pose RMSE alone / merged [m] | pose RMSE in the fitted map alone / merged [m] | goals missed |")
    print("|---|---|---|---|---|---|---|")
    n = bad = sp_m = sp_a = 0
    cnt = [0] * len(merge_table.GOALS)
    sums = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    counted = [0, 0, 0, 0, 0, 0]  # figures that exist (None: nothing matched, no truth, no fit)
    fit_worse = fit_both = 0  # robot-runs with both fitted-map poses, and those worse merged
    for s in seeds:
        alone = merge_table.load(os.path.join(d, f"s{s}_alone", "metrics.json"))["robots"]
        merged = merge_table.load(os.path.join(d, f"s{s}", "metrics.json"))["robots"]
        for ra, rm in zip(alone, merged):
            fa, fm = ra["map_fit"], rm["map_fit"]
            pa, pm = ra["pose"].get("rmse_m"), rm["pose"].get("rmse_m")
            # the pose in the map's fitted frame (information, not a goal)
            qa, qm = ra["pose"].get("fit_rmse_m"), rm["pose"].get("fit_rmse_m")
            if qa is not None and qm is not None:
                fit_both += 1
                fit_worse += int(qm > qa + 1e-9)
            missed = merge_table.goals_missed(fm, fa, pm, pa)
            for g, _ in missed:
                cnt[g] += 1
            bad += int(bool(missed))
            n += 1
            sp_m += fm["n_spurious"]
            sp_a += fa["n_spurious"]
            for k, v in enumerate((fa["rmse_m"], fm["rmse_m"], pa, pm, qa, qm)):
                if v is not None:
                    sums[k] += v
                    counted[k] += 1
            print(f"| {s} | {ra['id']} | {fa['n_spurious']} / {fm['n_spurious']} | "
                  f"{merge_table.fmt(fa['rmse_m'])} / {merge_table.fmt(fm['rmse_m'])} | "
                  f"{merge_table.fmt(pa, 2)} / {merge_table.fmt(pm, 2)} | "
                  f"{merge_table.fmt(qa, 2)} / {merge_table.fmt(qm, 2)} | "
                  f"{'; '.join(m for _, m in missed) or '-'} |")
    if n == 0:
        print("no runs")
        return 0, 0, 0, 0
    print()
    mean = [merge_table.fmt(sums[k] / counted[k] if counted[k] else None, 3 if k < 2 else 2) for k in range(6)]
    print(f"{n} robot-runs: spurious landmarks per robot alone {sp_a / n:.2f}, merged {sp_m / n:.2f}; "
          f"landmark RMSE {mean[0]} / {mean[1]} m; pose RMSE {mean[2]} / {mean[3]} m"
          + ("" if counted[0] == n and counted[1] == n else
             f" (no landmark matched: {n - counted[0]} alone, {n - counted[1]} merged)"))
    print(f"robot-runs missing a goal: {bad} of {n} ("
          + ", ".join(f"{g}: {c}" for g, c in zip(merge_table.GOALS, cnt)) + ")")
    print(f"pose RMSE in the fitted map alone / merged {mean[4]} / {mean[5]} m; higher with merging in "
          f"{fit_worse} of {fit_both} robot-runs with both (information, not a goal)")
    return n, bad, sp_m, sp_a


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit("usage: team_table.py DIR SEED...")
    if not os.path.isdir(sys.argv[1]):
        sys.exit(f"team_table: no folder {sys.argv[1]} (the outputs of tools/team_table.sh)")
    problems = bad_inputs(sys.argv[1], sys.argv[2:])
    if problems:
        sys.exit("team_table: no table, runs missing, empty or incomplete:\n  " + "\n  ".join(problems))
    table(sys.argv[1], sys.argv[2:])
