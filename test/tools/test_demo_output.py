#!/usr/bin/python3
"""coslam-demo checks every file it writes (host/cli/checked_file.h): each
output file in turn on a full disk (a symlink to /dev/full in --out) is
"coslam-demo: cannot write <path>: No space left on device" and exit 1,
and a file that cannot be opened (a directory in its place) is "cannot
write <path>: Is a directory" and exit 1; before, each was an exit 0 with
the file short or missing. A plain run first: exit 0 and every file
written, so the names below are the ones the tool writes.

usage: test_demo_output.py WORK COSLAM_DEMO
Each run is about 0.2 s (10 landmarks)."""
import os
import shutil
import subprocess
import sys

WORK = os.path.abspath(sys.argv[1])
DEMO = sys.argv[2]
FILES = ["metrics.json", "robot0_ekfslam_path.tum", "robot0_truth_path.tum", "robot0_ekfslam_map.csv",
         "robot0_fastslam2_path.tum", "robot0_fastslam2_map.csv", "truth_map.csv"]
failures = []


def run(out):
    p = subprocess.run([DEMO, "--out", out, "--landmarks", "10"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       timeout=120)
    return p.returncode, p.stderr.decode(errors="replace")


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def expect_error(label, out, line):
    rc, err = run(out)
    check(rc == 1 and line in err,
          f"{label}: exit {rc} (want 1), " + (line if line in err else f"no '{line}': {err.strip()[-300:]!r}"))


shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(WORK)

d = os.path.join(WORK, "plain")
rc, err = run(d)
written = sorted(f for f in os.listdir(d) if os.path.getsize(os.path.join(d, f)) > 0) if os.path.isdir(d) else []
check(rc == 0 and written == sorted(FILES),
      f"plain run: exit {rc} (want 0), files {written} (want {sorted(FILES)}): {err.strip()[-300:]!r}")

if os.path.exists("/dev/full"):
    for name in FILES:
        d = os.path.join(WORK, "full_" + name)
        os.makedirs(d)
        os.symlink("/dev/full", os.path.join(d, name))
        expect_error(f"{name} on a full disk", d,
                     f"coslam-demo: cannot write {d}/{name}: No space left on device")
else:
    print("skip the full-disk cases: no /dev/full")

# not openable, even as root
d = os.path.join(WORK, "dir_in_place")
os.makedirs(os.path.join(d, "truth_map.csv"))
expect_error("truth_map.csv a directory", d, f"coslam-demo: cannot write {d}/truth_map.csv: Is a directory")

if failures:
    print(f"{len(failures)} case(s) failed")
    sys.exit(1)
print("test_demo_output: ok")
