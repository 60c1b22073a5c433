#!/usr/bin/python3
"""Figures of a coslam-sim run directory (out/<run>/), like the paper's:

  fig6_paths_maps.png  per robot, before and after its merge: the arena,
                       the robot's occupancy grid, true and estimated path,
                       true landmarks (x) and the estimated ones with 2-sigma
                       ellipses, coloured by where the estimate comes from:
                       own (robot colour), fused with the other robot's
                       (purple), added from the other robot (red); the
                       square is where the robot stood at the merge
                       (paper Figs. 6 and 10).
  fig7_errors.png      position error, heading error and map error (RMSE
                       of the matched landmarks) over time for every robot,
                       merges marked (paper Fig. 7).

Reads what coslam-sim writes (docs/sim.md): world.json, metrics.json,
robot<k>_path.tum, robot<k>_truth_path.tum, robot<k>_map_premerge.csv,
robot<k>_map_postmerge.csv, robot<k>_map.csv, robot<k>_errors.csv,
robot<k>_grid.pgm, truth_map.csv, merge_events.csv.

usage: plot_sim.py RUN_DIR
"""
import csv
import json
import math
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Ellipse, Circle, Rectangle  # noqa: E402
from matplotlib.transforms import Affine2D  # noqa: E402
import numpy as np  # noqa: E402

ROBOT_COLORS = ["tab:blue", "tab:green", "tab:orange", "tab:cyan"]


def read_tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            rows.append((v[0], v[1], v[2], 2.0 * math.atan2(v[6], v[7])))
    return np.array(rows) if rows else np.zeros((0, 4))


def read_csv(path):
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return [{k: float(v) if k != "status" else v for k, v in r.items()} for r in csv.DictReader(f)]


def read_pgm(path):
    with open(path, "rb") as f:
        data = f.read()
    parts = data.split(maxsplit=4)
    w, h = int(parts[1]), int(parts[2])
    return np.frombuffer(parts[4][: w * h], dtype=np.uint8).reshape(h, w)


def ellipse(ax, lm, color, nsig=2.0):
    c = np.array([[lm["cxx"], lm["cxy"]], [lm["cxy"], lm["cyy"]]])
    w, v = np.linalg.eigh(c)
    w = np.maximum(w, 1e-12)
    ang = math.degrees(math.atan2(v[1, 1], v[0, 1]))
    ax.add_patch(Ellipse((lm["x"], lm["y"]), 2 * nsig * math.sqrt(w[1]), 2 * nsig * math.sqrt(w[0]), angle=ang,
                         fill=False, color=color, lw=0.9))


def draw_world(ax, world):
    for x0, y0, x1, y1 in world["walls"]:
        ax.plot([x0, x1], [y0, y1], color="0.3", lw=1.5)
    for x, y, r in world["pillars"]:
        ax.add_patch(Circle((x, y), r, color="0.3", fill=False, lw=1.5))


def draw_grid(ax, run, k, robot, grid_meta):
    path = os.path.join(run, "robot%d_grid.pgm" % k)
    if not os.path.exists(path):
        return
    img = read_pgm(path)
    ox, oy, cell = grid_meta["origin_x_m"], grid_meta["origin_y_m"], grid_meta["cell_m"]
    h, w = img.shape
    sx, sy, st = robot["start"]
    # the grid is in the robot's map frame (its start pose): move it into the world
    tr = Affine2D().rotate(st).translate(sx, sy) + ax.transData
    im = ax.imshow(img, cmap="gray", vmin=0, vmax=255, alpha=0.45, interpolation="nearest",
                   extent=(ox, ox + w * cell, oy, oy + h * cell), zorder=0)
    im.set_transform(tr)


def map_panel(ax, run, world, metrics, k, which, t_cut, merge_t):
    robot = world["robots"][k]
    color = ROBOT_COLORS[k % len(ROBOT_COLORS)]
    draw_grid(ax, run, k, robot, metrics["robots"][k]["grid"])
    draw_world(ax, world)
    truth = read_tum(os.path.join(run, "robot%d_truth_path.tum" % k))
    est = read_tum(os.path.join(run, "robot%d_path.tum" % k))
    if t_cut is not None:
        truth = truth[truth[:, 0] <= t_cut]
        est = est[est[:, 0] <= t_cut]
    ax.plot(truth[:, 1], truth[:, 2], "k-", lw=0.8, label="true path")
    ax.plot(est[:, 1], est[:, 2], ".", ms=1.2, color=color, label="estimated path")
    tm = read_csv(os.path.join(run, "truth_map.csv")) or []
    ax.plot([r["x"] for r in tm], [r["y"] for r in tm], "kx", ms=6, label="true landmarks")
    lms = read_csv(os.path.join(run, "robot%d_map_%s.csv" % (k, which))) if which else None
    if lms is None:
        lms = read_csv(os.path.join(run, "robot%d_map.csv" % k)) or []
    own = 1 << k
    kinds = {"own": color, "fused": "tab:purple", "added": "tab:red"}
    used = set()
    for lm in lms:
        mask = int(lm["src_mask"])
        kind = "own" if mask == own else ("fused" if mask & own else "added")
        used.add(kind)
        ellipse(ax, lm, kinds[kind])
        ax.plot(lm["x"], lm["y"], "+", color=kinds[kind], ms=4)
    for kind in ("own", "fused", "added"):
        if kind in used:
            ax.plot([], [], color=kinds[kind], lw=1, label="%s landmarks (2 sigma)" % kind)
    if merge_t is not None and len(truth) > 0 and which != "premerge":
        i = min(np.searchsorted(truth[:, 0], merge_t), len(truth) - 1)
        ax.add_patch(Rectangle((truth[i, 1] - 0.3, truth[i, 2] - 0.3), 0.6, 0.6, fill=False, color="r", lw=1.2))
    ax.set_aspect("equal")
    ax.grid(True, lw=0.3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    run = sys.argv[1]
    with open(os.path.join(run, "world.json")) as f:
        world = json.load(f)
    with open(os.path.join(run, "metrics.json")) as f:
        metrics = json.load(f)
    n = len(world["robots"])
    merges = read_csv(os.path.join(run, "merge_events.csv")) or []

    fig, axs = plt.subplots(n, 2, figsize=(13, 5.2 * n), squeeze=False)
    for k in range(n):
        rm = metrics["robots"][k]
        mt = rm["first_merge_s"]  # None (JSON null): the robot never merged
        name = "%s (%s%s)" % (rm["name"], rm["filter"], "/%d" % rm["particles"] if rm["particles"] else "")
        if mt is not None:
            map_panel(axs[k][0], run, world, metrics, k, "premerge", mt, None)
            axs[k][0].set_title("%s before its merge (t = %.1f s)" % (name, mt), fontsize=10)
        else:
            map_panel(axs[k][0], run, world, metrics, k, None, None, None)
            axs[k][0].set_title("%s: no merge" % name, fontsize=10)
        map_panel(axs[k][1], run, world, metrics, k, None, None, mt)
        axs[k][1].set_title("%s at the end (t = %.0f s)" % (name, metrics["timing"]["sim_s"]), fontsize=10)
        axs[k][1].legend(loc="lower right", fontsize=7)
    fig.suptitle("coslam-sim '%s', seed %d: paths and maps before and after the merge"
                 % (metrics["scenario"]["name"], metrics["scenario"]["seed"]))
    fig.tight_layout()
    fig.savefig(os.path.join(run, "fig6_paths_maps.png"), dpi=110)
    plt.close(fig)

    fig, axs = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for k in range(n):
        e = read_csv(os.path.join(run, "robot%d_errors.csv" % k)) or []
        rm = metrics["robots"][k]
        label = "%s (%s)" % (rm["name"], rm["filter"])
        color = ROBOT_COLORS[k % len(ROBOT_COLORS)]
        t = np.array([r["t"] for r in e])
        axs[0].plot(t, [r["pos_err_m"] for r in e], color=color, lw=0.9, label=label)
        axs[1].plot(t, [r["heading_err_deg"] for r in e], color=color, lw=0.9, label=label)
        rmse = np.array([r["map_rmse_m"] if r["n_matched"] > 0 else np.nan for r in e])
        axs[2].plot(t, rmse, color=color, lw=0.9, label=label)
    for m in merges:
        for a in axs:
            a.axvline(m["t"], color="r", ls="--", lw=0.7)
    axs[0].set_ylabel("position error [m]")
    axs[1].set_ylabel("heading error [deg]")
    axs[2].set_ylabel("map error (RMSE) [m]")
    axs[2].set_xlabel("t [s] (dashed: merges)")
    for a in axs:
        a.grid(True, lw=0.3)
        a.legend(fontsize=8, loc="upper left")
    fig.suptitle("pose and map errors over time")
    fig.tight_layout()
    fig.savefig(os.path.join(run, "fig7_errors.png"), dpi=110)
    plt.close(fig)
    print("figures: %s %s" % (os.path.join(run, "fig6_paths_maps.png"), os.path.join(run, "fig7_errors.png")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
