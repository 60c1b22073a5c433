#!/usr/bin/python3
"""Every host tool that prints results checks its standard output
(host/cli/stdout_check.h): with stdout on /dev/full (a full disk) each one,
on its cheapest real run and on --help, says "<tool>: cannot write standard
output: No space left on device" on stderr and exits 1, as for an output
file it cannot write; before, each exited 0 with its table, summary or
JSON lines lost. Also: bad usage stays 2; a run that ends early for its
own reason keeps its exit code and says the lost output too; stdout on a
pipe whose reader is gone, SIGPIPE ignored, is the same error ("Broken
pipe") rather than a silent exit 0.

usage: test_stdout_full.py WORK NAME=BINARY...
A NAME with an empty BINARY (not built in this configuration) is skipped.
Each run is short (a second of simulation, half a second of
coslam-sim-devices in real time, one seed, one frame); the
whole test takes about 15 s, most of it coslam-bench-merge's one
repetition (it has no smaller workload)."""
import os
import shutil
import struct
import subprocess
import sys
import zlib

WORK = os.path.abspath(sys.argv[1])
BINS = dict(a.split("=", 1) for a in sys.argv[2:])
failures = []

# "same": the exit code of the same run with stdout on /dev/null (a run
# that stops before its results, e.g. coslam-bench-filters in a profile too
# small for it: 2, or its --out not creatable: 1); stdout on /dev/full must
# not change it, only add the line.
SAME = "same"
# output longer than stdio's buffer (4 KiB) is written, and lost, as the
# buffer fills, where stdio keeps no errno (host/cli/stdout_check.h)
LOST = "lost"


def png(path, w=320, h=240):
    """A plain grey-green PNG of the camera's size (no markers in it)."""
    raw = b"".join(b"\x00" + bytes((90, 120, 90)) * w for _ in range(h))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def w(*parts):
    return os.path.join(WORK, *parts)


# NAME: [(label, args, wanted exit code[, the line said: True (default),
# False, or LOST: the line said with the OS's reason or, where stdio lost
# it, "a write failed")], the cheapest valid runs (from each tool's own CLI
# test) and --help where it prints to stdout
CASES = {
    "coslam-sim": [("1 s run", ["--duration", "1", "--quiet", "--out", w("sim")], 1),
                   ("--help", ["--help"], 1),
                   # nothing printed on stdout: exit 2, nothing to say
                   ("bad option", ["--no-such-option"], 2, False)],
    "coslam-replay": [("print-config", ["print-config"], 1),
                      ("--help", ["--help"], 1)],
    "coslam-calibrate": [("one generation", ["--evals", "5", "--lambda", "4", "--train-seeds", "1", "--test-seeds",
                                             "2", "-j", "1", "-q", "-o", w("cal")], 1),
                         ("--help (5 KiB)", ["--help"], 1, LOST)],
    "coslam-eval-worlds": [("one seed", ["--world", "paper", "--seeds", "1"], 1),
                           ("--help", ["--help"], 1),
                           ("bad option", ["--seeds", "0"], 2, False)],
    "coslam-demo": [("run", ["--out", w("demo"), "--landmarks", "10"], 1)],
    # a profile too small for them (default, large: exit 2) or --out not
    # creatable (host: exit 1), after the start-up line on stdout
    "coslam-bench-filters": [("stopped early", ["--seeds", "1", "--out", "/dev/null/bench"], SAME)],
    "coslam-bench-scale": [("stopped early", ["--quick", "--out", "/dev/null/bench"], SAME)],
    "coslam-bench-merge": [("one repetition", ["--reps", "1", "--no-naive", "--out", w("bench")], 1)],
    "coslam-bench-fastslam": [("two steps", ["--seeds", "1", "--steps", "2", "--no-flat", "--out", w("bench")], 1)],
    "coslam-bench-odo-check": [("one check", ["--checks", "1", "--out", w("bench")], 1),
                               # a flagged drive (3) yields to the lost table (1), as to a lost report
                               ("flagged drive", ["--checks", "5", "--odo-scale-pct", "300", "--out", w("bench")], 1),
                               ("--help", ["--help"], 1)],
    "coslam-bench-vision": [("one frame", ["--frames", "1", "--repeats", "1", "--out", w("bench")], 1),
                            ("--help", ["--help"], 1)],
    # no dataset there: it prints SKIPPED and exits 0
    "coslam-bench-mrclam": [("no dataset", ["--data", w("no-dataset"), "--out", w("bench")], 1),
                            ("--help", ["--help"], 1)],
    "coslam-bench-robot-camera": [("run", ["--out", w("bench")], 1)],
    "coslam-vision": [("one image", [w("grey.png")], 1),
                      ("--help", ["--help"], 1)],
    "coslam-vision-train": [("one image each", ["--train", "1", "--val", "1", "--test", "1", "--lut", w("lut.bin"),
                                                "--report", w("train.md")], 1),
                            ("--help", ["--help"], 1)],
    "coslam-vision-fit": [("40 frames", ["--frames", "40", "--out", w("range_model.txt")], 1),
                          ("--help", ["--help"], 1)],
    "coslam-vision-eval": [("two frames", ["--frames", "2"], 1),
                           ("--help", ["--help"], 1)],
    # half a second in real time, two stand-in robots (a sleeping script,
    # not coslam-robot: only the server's summary line is under test); no
    # --help, its usage goes to stderr: exit 2, nothing to say
    "coslam-sim-devices": [("0.5 s run", ["--scenario", w("two.toml"), "--robot", w("robot.sh"), "--duration", "0.5",
                                          "--out", w("devices")], 1),
                           ("bad option", ["--no-such-option"], 2, False)],
}
# stdout a pipe whose reader has gone, SIGPIPE ignored (inherited: python
# ignores it): EPIPE, the same error
PIPE_CASES = {"coslam-eval-worlds": ["--help"], "coslam-sim": ["--help"]}


def run(binary, args, stdout, **kw):
    p = subprocess.run([binary] + args, stdout=stdout, stderr=subprocess.PIPE, cwd=WORK, timeout=120, **kw)
    return p.returncode, p.stderr.decode(errors="replace")


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(w("bench"))
png(w("grey.png"))
# coslam-sim-devices: the smallest scenario it takes (two robots) and a
# robot that waits for its SIGTERM
with open(w("two.toml"), "w") as f:
    f.write('name = "two"\nduration_s = 0.5\nseed = 1\n\n[world]\n'
            'arena = [[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]]\n\n'
            '[[robot]]\nname = "robot0"\nstart = [-0.8, 0.0, 0.0]\n\n'
            '[[robot]]\nname = "robot1"\nstart = [0.8, 0.0, 0.0]\n')
with open(w("robot.sh"), "w") as f:
    f.write("#!/bin/sh\nexec sleep 10\n")
os.chmod(w("robot.sh"), 0o755)
unknown = sorted(set(BINS) - set(CASES))
check(not unknown, f"a case for every tool given ({unknown or 'all'})")
for name, cases in CASES.items():
    binary = BINS.get(name, "")
    if not binary:
        print(f"skip {name}: not built")
        continue
    for label, args, want, *said in cases:
        said = said[0] if said else True
        if want == SAME:
            want, _ = run(binary, args, subprocess.DEVNULL)
        with open("/dev/full", "wb") as full:
            rc, err = run(binary, args, full)
        line = f"{name}: cannot write standard output: No space left on device"
        lost = f"{name}: cannot write standard output: a write failed"
        got = line in err or (said == LOST and lost in err)
        check(rc == want and got == bool(said),
              f"{name} {label} > /dev/full: exit {rc} (want {want}), "
              + (("said: " + (line if line in err else lost)) if got else "no such line")
              + ("" if got == bool(said) else f" (want {'one' if said else 'none'}): {err.strip()[-300:]!r}"))
for name, args in PIPE_CASES.items():
    binary = BINS.get(name, "")
    if not binary:
        continue
    r, wr = os.pipe()
    os.close(r)
    try:
        rc, err = run(binary, args, wr, restore_signals=False)
    finally:
        os.close(wr)
    line = f"{name}: cannot write standard output: Broken pipe"
    check(rc == 1 and line in err,
          f"{name} {' '.join(args)} to a closed pipe, SIGPIPE ignored: exit {rc} (want 1), "
          + (line if line in err else f"no '{line}': {err.strip()[-300:]!r}"))
# coslam-sim-devices' numbers are in its result.json only: that file on a
# full disk is an error naming it, exit 1, and no "result in" line
if BINS.get("coslam-sim-devices"):
    os.makedirs(w("devices_full"), exist_ok=True)
    res = w("devices_full") + "/result.json"
    if os.path.lexists(res):
        os.remove(res)
    os.symlink("/dev/full", res)
    p = subprocess.run([BINS["coslam-sim-devices"], "--scenario", w("two.toml"), "--robot", w("robot.sh"),
                        "--duration", "0.5", "--out", w("devices_full")],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=WORK, timeout=120)
    err = p.stderr.decode(errors="replace")
    line = f"coslam-sim-devices: cannot write {res}: No space left on device"
    check(p.returncode == 1 and line in err and b"result in" not in p.stdout,
          f"coslam-sim-devices, result.json on /dev/full: exit {p.returncode} (want 1), "
          + (line if line in err else f"no '{line}': {err.strip()[-300:]!r}"))
if failures:
    print(f"{len(failures)} case(s) failed")
    sys.exit(1)
print("test_stdout_full: ok")
