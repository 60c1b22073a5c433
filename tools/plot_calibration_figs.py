#!/usr/bin/python3
"""The paper's Figs. 4 and 5 from a coslam-calibrate --figures run
(docs/calibration.md "Figures 4 and 5"): hand-tuned against calibrated
noise weights on the same held-out episodes.

  fig4_paths_maps.png  one held-out episode: true path and landmarks, the
                       estimated path and final map with the hand-tuned
                       weights (left) and with the calibrated ones (right).
  fig5_errors.png      position error and landmark RMSE over time, means
                       over the held-out episodes, both weight sets.

Reads figures_path.csv, figures_map.csv, figures_error.csv, figures.json.

usage: plot_calibration_figs.py FIGURES_DIR [-o OUT_DIR] [--dpi N]
"""
import argparse
import csv
import json
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

SETS = (("hand", "hand-tuned", "tab:blue"), ("calibrated", "calibrated", "tab:red"))


def read_rows(path):
    """The rows of a figures_*.csv; exits with a message naming the file
    when it is missing or holds no row (a header at most): an empty figure
    is not written."""
    if not os.path.isfile(path):
        sys.exit(f"plot_calibration_figs: no {path} (an output of coslam-calibrate --figures)")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"plot_calibration_figs: {path} holds no rows (a header at most): nothing to plot")
    return rows


def xy(rows, name):
    sel = [r for r in rows if r["set"] == name]
    return [float(r["x_m"]) for r in sel], [float(r["y_m"]) for r in sel]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir", help="output folder of coslam-calibrate --figures")
    ap.add_argument("-o", "--out", help="where the PNGs go (default: the same folder)")
    ap.add_argument("--dpi", type=int, default=90)
    a = ap.parse_args()
    out = a.out or a.dir
    os.makedirs(out, exist_ok=True)
    paths = read_rows(os.path.join(a.dir, "figures_path.csv"))
    maps = read_rows(os.path.join(a.dir, "figures_map.csv"))
    err = read_rows(os.path.join(a.dir, "figures_error.csv"))
    summ_path = os.path.join(a.dir, "figures.json")
    if not os.path.isfile(summ_path):
        sys.exit(f"plot_calibration_figs: no {summ_path} (an output of coslam-calibrate --figures)")
    with open(summ_path) as f:
        summ = json.load(f)

    # Fig. 4: paths and maps of one held-out episode
    fig, axes = plt.subplots(1, 2, figsize=(10, 5), sharex=True, sharey=True)
    tx, ty = xy(paths, "truth")
    lx, ly = xy(maps, "truth")
    for ax, (key, label, col) in zip(axes, SETS):
        ax.plot(tx, ty, "k-", lw=1, label="true path")
        ax.plot(lx, ly, "k+", ms=7, label="true landmarks")
        ex, ey = xy(paths, key)
        ax.plot(ex, ey, "-", color=col, lw=1, label="estimated path")
        mx, my = xy(maps, key)
        ax.plot(mx, my, "o", mfc="none", mec=col, ms=5, label="estimated landmarks")
        s = summ[key]
        ep = next(e for e in s["episodes"] if e["episode"] == summ["figure_episode"])
        ax.set_title(f"{label}: {summ['figure_episode']}\nmean position error {ep['mean_pos_err_m']:.3f} m, "
                     f"landmark RMSE {ep['final_lm_rmse_m']:.3f} m", fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("y [m]")
    axes[0].legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    p4 = os.path.join(out, "fig4_paths_maps.png")
    fig.savefig(p4, dpi=a.dpi, bbox_inches="tight")

    # Fig. 5: errors over time, means over the held-out episodes
    t = [float(r["t_s"]) for r in err]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    n = len(summ["hand"]["episodes"])
    for key, label, col in SETS:
        s = summ[key]
        ax1.plot(t, [float(r[f"pos_err_{key}_m"]) for r in err], color=col,
                 label=f"{label} (mean {s['mean_pos_err_m']:.4f} m)")
        ax2.plot(t, [float(r[f"lm_rmse_{key}_m"]) for r in err], color=col,
                 label=f"{label} (final {s['final_lm_rmse_m']:.4f} m)")
    ax1.set_ylabel("position error [m]")
    ax2.set_ylabel("landmark RMSE [m]")
    ax2.set_xlabel("time [s]")
    ax1.set_title(f"mean over {n} held-out episodes")
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    p5 = os.path.join(out, "fig5_errors.png")
    fig.savefig(p5, dpi=a.dpi, bbox_inches="tight")
    print(p4)
    print(p5)


if __name__ == "__main__":
    main()
