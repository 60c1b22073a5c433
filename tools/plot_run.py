#!/usr/bin/python3
"""Figures for a run directory (out/<run>/): paths with landmark ellipses
(paper Figs. 4, 6, 10) and pose/map error over time (Figs. 5, 7).

Reads the run outputs of DESIGN.md: <name>_path.tum files, <name>_map.csv
files (id,x,y,cxx,cxy,cyy), optional truth_path / truth_map files, and
optional merge_events.csv (t,robot) to mark merges. Writes paths.png and
errors.png into the same directory.

usage: plot_run.py RUN_DIR [--title TEXT]
"""
import argparse
import csv
import glob
import math
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Ellipse  # noqa: E402
import numpy as np  # noqa: E402


def read_tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            th = 2.0 * math.atan2(v[6], v[7])
            rows.append((v[0], v[1], v[2], th))
    return np.array(rows) if rows else np.zeros((0, 4))


def read_map(path):
    rows = []
    with open(path) as f:
        for r in csv.DictReader(f):
            rows.append({k: float(v) for k, v in r.items()})
    return rows


def ellipse(ax, lm, color, nsig=2.0):
    c = np.array([[lm["cxx"], lm["cxy"]], [lm["cxy"], lm["cyy"]]])
    w, v = np.linalg.eigh(c)
    w = np.maximum(w, 1e-12)
    ang = math.degrees(math.atan2(v[1, 1], v[0, 1]))
    e = Ellipse((lm["x"], lm["y"]), 2 * nsig * math.sqrt(w[1]), 2 * nsig * math.sqrt(w[0]), angle=ang,
                fill=False, color=color, lw=0.8)
    ax.add_patch(e)


def truth_for(name, truth_paths):
    """The truth path of the estimate <name>_path.tum: <robot>_truth_path.tum
    for the robot of the name (its part before the first "_": robot1_ekf ->
    robot1), matched whole (robot1 is not robot10); else a single
    truth_path.tum shared by every estimate; else None."""
    by_name = {os.path.basename(q): q for q in truth_paths}
    robot = name.split("_")[0]
    return by_name.get(robot + "_truth_path.tum") or by_name.get("truth_path.tum")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run_dir")
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    d = a.run_dir
    paths = sorted(glob.glob(os.path.join(d, "*_path.tum")))
    if not paths:
        print("plot_run: no *_path.tum in %s" % d, file=sys.stderr)
        return 1
    truth_paths = [p for p in paths if "truth" in os.path.basename(p)]
    est_paths = [p for p in paths if p not in truth_paths]
    merges = []
    mpath = os.path.join(d, "merge_events.csv")
    if os.path.exists(mpath):
        with open(mpath) as f:
            merges = [float(r["t"]) for r in csv.DictReader(f)]
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]

    fig, ax = plt.subplots(figsize=(8, 8))
    for p in truth_paths:
        t = read_tum(p)
        ax.plot(t[:, 1], t[:, 2], "k-", lw=1.0, label=os.path.basename(p).replace("_path.tum", ""))
    for i, p in enumerate(est_paths):
        t = read_tum(p)
        name = os.path.basename(p).replace("_path.tum", "")
        ax.plot(t[:, 1], t[:, 2], ".", ms=1.5, color=colors[i % len(colors)], label=name)
        mp = p.replace("_path.tum", "_map.csv")
        if os.path.exists(mp):
            for lm in read_map(mp):
                ellipse(ax, lm, colors[i % len(colors)])
                ax.plot(lm["x"], lm["y"], "+", color=colors[i % len(colors)], ms=4)
    tm = os.path.join(d, "truth_map.csv")
    if os.path.exists(tm):
        with open(tm) as f:
            pts = [(float(r["x"]), float(r["y"])) for r in csv.DictReader(f)]
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "kx", ms=6, label="true landmarks")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(a.title or "paths and landmark estimates (2-sigma ellipses)")
    ax.legend(loc="best", fontsize=8)
    ax.grid(True, lw=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(d, "paths.png"), dpi=130)
    plt.close(fig)

    if truth_paths:
        fig, axs = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
        for i, p in enumerate(est_paths):
            est = read_tum(p)
            name = os.path.basename(p).replace("_path.tum", "")
            tp = truth_for(name, truth_paths)
            if tp is None:
                print("plot_run: no truth path for %s (neither %s_truth_path.tum nor one truth_path.tum): "
                      "no error curve" % (name, name.split("_")[0]), file=sys.stderr)
                continue
            tru = read_tum(tp)
            if len(est) == 0 or len(tru) == 0:
                continue
            tx = np.interp(est[:, 0], tru[:, 0], tru[:, 1])
            ty = np.interp(est[:, 0], tru[:, 0], tru[:, 2])
            tth = np.interp(est[:, 0], tru[:, 0], np.unwrap(tru[:, 3]))
            pe = np.hypot(est[:, 1] - tx, est[:, 2] - ty)
            he = np.abs((est[:, 3] - tth + np.pi) % (2 * np.pi) - np.pi)
            axs[0].plot(est[:, 0], pe, color=colors[i % len(colors)], lw=0.8, label=name)
            axs[1].plot(est[:, 0], np.degrees(he), color=colors[i % len(colors)], lw=0.8, label=name)
        for t in merges:
            for ax_ in axs:
                ax_.axvline(t, color="r", ls="--", lw=0.8)
        axs[0].set_ylabel("position error [m]")
        axs[1].set_ylabel("heading error [deg]")
        axs[1].set_xlabel("t [s]")
        axs[0].legend(fontsize=8)
        for ax_ in axs:
            ax_.grid(True, lw=0.3)
        fig.tight_layout()
        fig.savefig(os.path.join(d, "errors.png"), dpi=130)
        plt.close(fig)
    return 0


if __name__ == "__main__":
    sys.exit(main())
