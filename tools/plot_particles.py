#!/usr/bin/python3
"""Particle-count curve (the paper's Fig. 10) from a coslam-calibrate
--sweep-particles run (docs/calibration.md "Particle count"):

  mean position error over the held-out episodes against the number of
  particles (log x), one line per filter (Fast-SLAM 1.0, 2.0), error bars
  one standard error over the episodes; the chosen count ringed, the best
  one marked; CPU time per episode on a second axis below.

usage: plot_particles.py SWEEP_DIR_OR_CSV [-o PNG] [--title TEXT] [--dpi N]
"""
import argparse
import csv
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

NAMES = {"fs1": "Fast-SLAM 1.0", "fs2": "Fast-SLAM 2.0"}


def read_sweep(path):
    """sweep.csv -> {filter: [row dicts sorted by particles]}"""
    out = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            out.setdefault(r["filter"], []).append(r)
    for rows in out.values():
        rows.sort(key=lambda r: int(r["particles"]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sweep", help="sweep.csv or the folder holding it")
    ap.add_argument("-o", "--out", help="PNG (default: particles.png beside sweep.csv)")
    ap.add_argument("--title", default="")
    ap.add_argument("--dpi", type=int, default=90)
    a = ap.parse_args()
    path = os.path.join(a.sweep, "sweep.csv") if os.path.isdir(a.sweep) else a.sweep
    if not os.path.isfile(path):
        sys.exit(f"plot_particles: no {path} (the sweep.csv of coslam-calibrate --sweep-particles)")
    data = read_sweep(path)
    if not data:
        sys.exit(f"plot_particles: {path} holds no sweep rows (a header at most): nothing to plot")
    out = a.out or os.path.join(os.path.dirname(path), "particles.png")

    fig, (ax, axc) = plt.subplots(2, 1, figsize=(6.4, 5.6), sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
    for k, (filt, rows) in enumerate(sorted(data.items())):
        n = [int(r["particles"]) for r in rows]
        err = [float(r["mean_pos_err_m"]) for r in rows]
        se = [float(r["pos_err_se_m"]) for r in rows]
        cpu = [float(r["cpu_s_per_episode"]) for r in rows]
        lost = [int(r["lost"]) for r in rows]
        label = NAMES.get(filt, filt)
        line = ax.errorbar(n, err, yerr=se, marker="o", capsize=3, label=label)
        c = line[0].get_color()
        for r in rows:
            x, y = int(r["particles"]), float(r["mean_pos_err_m"])
            if r["chosen"] == "1":
                ax.plot([x], [y], "o", ms=14, mfc="none", mec=c, mew=2)
                ax.annotate(f"chosen N={x}", (x, y), textcoords="offset points", xytext=(10, 8 if k == 0 else -16), color=c)
            if r["best"] == "1":
                ax.plot([x], [y], "*", ms=12, color=c)
        for x, y, lo in zip(n, err, lost):
            if lo:
                ax.annotate(f"{lo} lost", (x, y), textcoords="offset points", xytext=(-10, -14), fontsize=8, color=c)
        axc.plot(n, cpu, marker="o", color=c, label=label)
    ax.set_xscale("log")
    ax.set_ylabel("mean position error [m]\n(held-out episodes, +-1 se)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(title="star: lowest error, ring: chosen")
    if a.title:
        ax.set_title(a.title)
    axc.set_xscale("log")
    axc.set_yscale("log")
    axc.set_xlabel("particles")
    axc.set_ylabel("CPU [s] / episode")
    axc.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out, dpi=a.dpi, bbox_inches="tight")
    print(out)


if __name__ == "__main__":
    main()
