#!/usr/bin/env python3
"""The helper scripts under tools/ on inputs that used to give a wrong or
empty result with exit 0:
 - plot_run.py pairs each estimated path with its own robot's truth
   (robot1 is not robot10, whose name starts the same);
 - plot_particles.py, plot_calibration_figs.py and replay_table.py refuse
   header-only or missing inputs (a message naming what is missing, exit
   non-zero, no figure or table written);
 - merge_table.py refuses a folder with missing or empty runs instead of
   reporting "Goals not met: none"; team_table.py, run on its own, names a
   missing folder, missing and empty runs, and robots without a field it
   reads (the file and the field; exit 1) instead of a traceback;
 - merge_table.sh and team_table.sh fail (exit 1, the run and its log or the
   missing binary and its target named) when a binary is missing or a
   background run fails.
usage: test_tool_inputs.py SOURCE_DIR"""
import contextlib
import importlib.util
import io
import json
import os
import stat
import subprocess
import sys
import tempfile

SRC = os.path.abspath(sys.argv[1])
TOOLS = os.path.join(SRC, "tools")
failures = []


def check(cond, what):
    print(("ok: " if cond else "FAIL: ") + what)
    if not cond:
        failures.append(what)


def tool(name, *args, cwd=None, env=None):
    """Runs tools/NAME (python3 for .py, sh for .sh): (exit status, stdout, stderr)."""
    path = os.path.join(TOOLS, name)
    cmd = [sys.executable, path] if name.endswith(".py") else ["sh", path]
    p = subprocess.run(cmd + list(args), cwd=cwd or SRC, env=env, capture_output=True, text=True, timeout=120)
    return p.returncode, p.stdout, p.stderr


def write(path, text):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)


def tum(path, x0):
    # t x y z qx qy qz qw: a straight line at y = 0 from x0
    write(path, "".join(f"{t} {x0 + 0.1 * t} 0 0 0 0 0 1\n" for t in range(20)))


with tempfile.TemporaryDirectory() as tmp:
    # --- plot_run.py: robot1 with robot1's truth, not robot10's ---
    spec = importlib.util.spec_from_file_location("plot_run", os.path.join(TOOLS, "plot_run.py"))
    pr = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(pr)
    run = os.path.join(tmp, "run")
    for k in (1, 10):
        tum(os.path.join(run, f"robot{k}_path.tum"), k)
        tum(os.path.join(run, f"robot{k}_truth_path.tum"), k)
    read = []
    real_read_tum = pr.read_tum

    def logged(path):
        read.append(os.path.basename(path))
        return real_read_tum(path)

    pr.read_tum = logged
    sys.argv = ["plot_run.py", run]
    rc = pr.main()
    # the error figure reads each estimate, then the truth it is compared with
    pairs = {read[i]: read[i + 1] for i in range(len(read) - 1) if "truth" not in read[i] and "truth" in read[i + 1]}
    check(rc == 0 and os.path.exists(os.path.join(run, "errors.png")), "plot_run.py wrote errors.png")
    check(pairs.get("robot1_path.tum") == "robot1_truth_path.tum",
          f"plot_run.py: robot1 compared with robot1's truth (pairs {pairs})")
    check(pairs.get("robot10_path.tum") == "robot10_truth_path.tum",
          f"plot_run.py: robot10 compared with robot10's truth (pairs {pairs})")
    # robot1 without a truth of its own: no curve, said; not robot10's truth
    os.remove(os.path.join(run, "robot1_truth_path.tum"))
    read.clear()
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        pr.main()
    pairs = {read[i]: read[i + 1] for i in range(len(read) - 1) if "truth" not in read[i] and "truth" in read[i + 1]}
    check("robot1_path.tum" not in pairs and "no truth path for robot1" in err.getvalue(),
          f"plot_run.py: robot1 without its truth is said, not paired (pairs {pairs}, stderr {err.getvalue()!r})")

    # --- plot_particles.py: a sweep.csv with only its header ---
    sweep = os.path.join(tmp, "sweep")
    write(os.path.join(sweep, "sweep.csv"),
          "filter,particles,mean_pos_err_m,pos_err_se_m,cpu_s_per_episode,lost,chosen,best\n")
    rc, out, errs = tool("plot_particles.py", sweep)
    check(rc != 0 and "no sweep rows" in errs and not os.path.exists(os.path.join(sweep, "particles.png")),
          f"plot_particles.py on a header-only sweep.csv: exit {rc}, {errs.strip()!r}")
    rc, out, errs = tool("plot_particles.py", os.path.join(tmp, "nowhere"))
    check(rc != 0 and "no " + os.path.join(tmp, "nowhere") in errs, f"plot_particles.py on a missing file: {errs.strip()!r}")

    # --- plot_calibration_figs.py: header-only figures_*.csv ---
    figs = os.path.join(tmp, "figs")
    write(os.path.join(figs, "figures_path.csv"), "set,t_s,x_m,y_m\n")
    write(os.path.join(figs, "figures_map.csv"), "set,x_m,y_m\n")
    write(os.path.join(figs, "figures_error.csv"), "t_s,pos_err_hand_m,pos_err_calibrated_m\n")
    ep = {"episodes": [{"episode": "s101", "mean_pos_err_m": 0.1, "final_lm_rmse_m": 0.1}],
          "mean_pos_err_m": 0.1, "final_lm_rmse_m": 0.1}
    write(os.path.join(figs, "figures.json"), json.dumps({"figure_episode": "s101", "hand": ep, "calibrated": ep}))
    rc, out, errs = tool("plot_calibration_figs.py", figs)
    check(rc != 0 and "figures_path.csv holds no rows" in errs
          and not os.path.exists(os.path.join(figs, "fig4_paths_maps.png")),
          f"plot_calibration_figs.py on header-only CSVs: exit {rc}, {errs.strip()!r}")

    # --- replay_table.py: a missing or empty folder ---
    rc, out, errs = tool("replay_table.py", os.path.join(tmp, "nowhere"))
    check(rc != 0 and "no folder" in errs and "|" not in out, f"replay_table.py on a missing folder: {errs.strip()!r}")
    os.makedirs(os.path.join(tmp, "empty"))
    rc, out, errs = tool("replay_table.py", os.path.join(tmp, "empty"))
    check(rc != 0 and "metrics.json" in errs and "|" not in out, f"replay_table.py on an empty folder: {errs.strip()!r}")

    # --- merge_table.py: runs missing or empty ---
    mt = os.path.join(tmp, "mt")
    write(os.path.join(mt, "d6_ekf", "metrics.json"), "")
    rc, out, errs = tool("merge_table.py", mt)
    check(rc != 0 and "d6_ekf/metrics.json: not a coslam-replay metrics.json" in errs
          and "d1_fastslam2_alone/metrics.json: missing" in errs and "none" not in out,
          f"merge_table.py on missing and empty runs: exit {rc}, {errs.strip()[:300]!r}")

    # every run there but robots without fields the table reads, and a merged
    # run without its merge counts: each named, exit 1, no table (a KeyError
    # traceback before)
    mt2 = os.path.join(tmp, "mt2")
    whole = {"id": 1, "map_fit": {"n_spurious": 0, "rmse_m": 0.1, "n_estimated": 15}, "pose": {"rmse_m": 0.2}}
    for d in (6, 1):
        for f in ("ekf", "fastslam2"):
            write(os.path.join(mt2, f"d{d}_{f}_alone", "metrics.json"), json.dumps({"robots": [whole]}))
            write(os.path.join(mt2, f"d{d}_{f}", "metrics.json"),
                  json.dumps({"robots": [whole], "merges": {"merged": 1, "refused_range_check": 0}}))
    write(os.path.join(mt2, "d6_ekf_alone", "metrics.json"), json.dumps({"robots": [{"id": 1, "pose": {}}]}))
    write(os.path.join(mt2, "d1_ekf", "metrics.json"), json.dumps(
        {"robots": [{"id": 2, "map_fit": {"n_spurious": 0, "rmse_m": 0.1}, "pose": {}}]}))
    rc, out, errs = tool("merge_table.py", mt2)
    check(rc == 1 and "Traceback" not in errs and "|" not in out
          and f"{mt2}/d6_ekf_alone/metrics.json: robot 1: no 'map_fit'" in errs
          and f"{mt2}/d1_ekf/metrics.json: robot 2: no 'map_fit.n_estimated'" in errs
          and f"{mt2}/d1_ekf/metrics.json: no 'merges' with 'merged' and 'refused_range_check'" in errs,
          f"merge_table.py on robots without the table's fields: exit {rc}, {errs.strip()[:400]!r}")
    # the same runs whole: the table
    write(os.path.join(mt2, "d6_ekf_alone", "metrics.json"), json.dumps({"robots": [whole]}))
    write(os.path.join(mt2, "d1_ekf", "metrics.json"),
          json.dumps({"robots": [whole], "merges": {"merged": 1, "refused_range_check": 0}}))
    rc, out, errs = tool("merge_table.py", mt2)
    check(rc == 0 and "| 1 | 0 / 0 | 0.100 / 0.100 |" in out, f"merge_table.py on whole runs: exit {rc}, "
          f"{errs.strip()[:300]!r}")

    # --- team_table.py on its own (team_table.sh checks its runs first;
    # run alone it gave a traceback on a missing metrics.json) ---
    rc, out, errs = tool("team_table.py", os.path.join(tmp, "nowhere"), "1")
    check(rc == 1 and "team_table: no folder " + os.path.join(tmp, "nowhere") in errs
          and "Traceback" not in errs and "|" not in out,
          f"team_table.py on a missing folder: exit {rc}, {errs.strip()[:300]!r}")
    tt = os.path.join(tmp, "tt")
    robot = {"id": 1, "map_fit": {"n_spurious": 0, "rmse_m": 0.1}, "pose": {"rmse_m": 0.2}}
    write(os.path.join(tt, "s1", "metrics.json"), json.dumps({"robots": [robot]}))
    write(os.path.join(tt, "s2", "metrics.json"), "")
    rc, out, errs = tool("team_table.py", tt, "1", "2")
    check(rc == 1 and "Traceback" not in errs and "|" not in out
          and f"{tt}/s1_alone/metrics.json: missing (see {tt}/s1_alone.txt)" in errs
          and f"{tt}/s2/metrics.json: not a coslam-replay metrics.json" in errs
          and f"{tt}/s2_alone/metrics.json: missing" in errs,
          f"team_table.py on missing and empty runs: exit {rc}, {errs.strip()[:400]!r}")
    # robots without the fields the table reads (a metrics.json of another
    # tool, or of an older coslam-replay): the file and the field named, exit
    # 1, no row (a KeyError traceback before)
    write(os.path.join(tt, "s1_alone", "metrics.json"), json.dumps({"robots": [{"id": 1, "pose": {}}]}))
    rc, out, errs = tool("team_table.py", tt, "1")
    check(rc == 1 and "Traceback" not in errs and "|" not in out
          and f"{tt}/s1_alone/metrics.json: robot 1: no 'map_fit'" in errs,
          f"team_table.py on a run whose robots lack map_fit: exit {rc}, {errs.strip()[:400]!r}")
    write(os.path.join(tt, "s1_alone", "metrics.json"),
          json.dumps({"robots": [{"id": 1, "map_fit": {"rmse_m": None}, "pose": {}}]}))
    rc, out, errs = tool("team_table.py", tt, "1")
    check(rc == 1 and "Traceback" not in errs and "|" not in out
          and f"{tt}/s1_alone/metrics.json: robot 1: no 'map_fit.n_spurious'" in errs,
          f"team_table.py on a run whose map_fit lacks n_spurious: exit {rc}, {errs.strip()[:400]!r}")
    write(os.path.join(tt, "s1_alone", "metrics.json"), json.dumps({"robots": [robot]}))
    rc, out, errs = tool("team_table.py", tt, "1")
    check(rc == 0 and "| 1 | 1 | 0 / 0 |" in out and "robot-runs missing a goal: 0 of 1" in out,
          f"team_table.py on a whole run: exit {rc}, {errs.strip()[:300]!r}")

    # --- merge_table.sh and team_table.sh ---
    env = dict(os.environ, COSLAM_DATA_DIR=os.path.join(tmp, "data"))
    for d in (6, 1):
        os.makedirs(os.path.join(tmp, "data", "mrclam", f"MRCLAM_Dataset{d}"))
    rc, out, errs = tool("merge_table.sh", os.path.join(tmp, "build-nonexistent"), os.path.join(tmp, "o1"), env=env)
    check(rc == 1 and "no " + os.path.join(tmp, "build-nonexistent", "host/replay/coslam-replay") in errs
          and "--target coslam-replay" in errs and "Goals not met" not in out,
          f"merge_table.sh without coslam-replay: exit {rc}, {errs.strip()!r}")

    def fake_build(name, script):
        b = os.path.join(tmp, name)
        write(os.path.join(b, "host", "replay", "coslam-replay"), script)
        os.chmod(os.path.join(b, "host", "replay", "coslam-replay"), stat.S_IRWXU)
        return b

    # every run fails: each background job's failure fails the script
    b = fake_build("build-failing", "#!/bin/sh\necho 'cannot read the data' >&2\nexit 3\n")
    o2 = os.path.join(tmp, "o2")
    rc, out, errs = tool("merge_table.sh", b, o2, env=env)
    check(rc == 1 and f"run d6_ekf failed (exit 3), its log: {o2}/d6_ekf.txt" in errs
          and f"run d6_fastslam2 failed (exit 3), its log: {o2}/d6_fastslam2.txt" in errs
          and "Goals not met" not in out,
          f"merge_table.sh with failing runs: exit {rc}, {errs.strip()!r}")
    # runs that exit 0 but leave no metrics.json: merge_table.py refuses
    b = fake_build("build-silent", "#!/bin/sh\nexit 0\n")
    rc, out, errs = tool("merge_table.sh", b, os.path.join(tmp, "o3"), env=env)
    check(rc == 1 and "runs missing, empty or incomplete" in errs and "Goals not met" not in out,
          f"merge_table.sh with runs writing nothing: exit {rc}, {errs.strip()[:200]!r}")
    # team_table.sh without coslam-eval-worlds (its call hid the shell's error)
    rc, out, errs = tool("team_table.sh", b, os.path.join(tmp, "o4"), "ekf", "1")
    check(rc == 1 and "no " + os.path.join(b, "host/eval/coslam-eval-worlds") in errs
          and "--target coslam-eval-worlds" in errs,
          f"team_table.sh without coslam-eval-worlds: exit {rc}, {errs.strip()!r}")

    # run_replay.sh (make replay): a run that fails stops it with the run
    # named, its exit code and its log (it ran with stderr thrown away and
    # set -e: exit 3 and nothing said, or a failed first run hidden by sed)
    b = fake_build("build-replay", "#!/bin/sh\nfor a in \"$@\"; do [ \"$a\" = --no-merge ] && "
                   "{ echo 'capacity: 257 landmarks' >&2; exit 3; }; done\necho 'coslam-replay: ok'\nexit 0\n")
    cwd = os.path.join(tmp, "replay-cwd")
    os.makedirs(cwd)
    rc, out, errs = tool("run_replay.sh", b, cwd=cwd, env=env)
    log = os.path.join("out/replay", "5r-nomerge_ekf_unknown.log")
    check(rc == 1 and f"run 5r-nomerge_ekf_unknown failed with exit 3; its log: {log}" in errs
          and "capacity: 257 landmarks" in errs and "coslam-replay: ok" in out,
          f"run_replay.sh with a failing run: exit {rc}, {errs.strip()!r}")

print("test_tool_inputs:", "failed" if failures else "ok")
sys.exit(1 if failures else 0)
