#!/usr/bin/env python3
"""Plots for vloc_eval: reads the CSVs it wrote in --out and writes PNGs there.

  traverse_map.png      ground truth, dead reckoning, visual and optimised
                        site positions, sites numbered, 2-sigma ellipses of
                        the optimised marginal covariance
  error_vs_distance.png position error of each source vs distance driven
  uav_route.png         UAV route (estimate and truth), when uav.csv has rows
  uav_height.png        UAV height over time (estimate and truth)

Needs python3 with numpy and matplotlib only.
"""
import argparse
import csv
import os
import sys

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Ellipse  # noqa: E402


def read_csv(path):
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def column(rows, key):
    out = []
    for r in rows:
        v = r.get(key, "")
        out.append(float(v) if v not in ("", None) else np.nan)
    return np.array(out, dtype=float)


def traverse_map(sites, out):
    fig, ax = plt.subplots(figsize=(8, 8))
    gx, gy = column(sites, "gt_x"), column(sites, "gt_y")
    ax.plot(gx, gy, "k.-", label="ground truth")
    for key, style, label in (("dr", "r.--", "dead reckoning"), ("vis", "b.:", "visual (chained BA)"),
                              ("opt", "g.-", "optimised graph")):
        x, y = column(sites, key + "_x"), column(sites, key + "_y")
        if np.isfinite(x).any():
            ax.plot(x, y, style, label=label)
    ox, oy = column(sites, "opt_x"), column(sites, "opt_y")
    cxx, cxy, cyy = column(sites, "opt_cov_xx"), column(sites, "opt_cov_xy"), column(sites, "opt_cov_yy")
    for i in range(len(sites)):
        if not (np.isfinite(ox[i]) and cxx[i] > 0 and cyy[i] > 0):
            continue
        cov = np.array([[cxx[i], cxy[i]], [cxy[i], cyy[i]]])
        w, v = np.linalg.eigh(cov)
        w = np.maximum(w, 0)
        angle = np.degrees(np.arctan2(v[1, 1], v[0, 1]))
        ax.add_patch(Ellipse((ox[i], oy[i]), 4 * np.sqrt(w[1]), 4 * np.sqrt(w[0]), angle=angle,
                             fill=False, color="g", alpha=0.6))
    for i, r in enumerate(sites):
        ax.annotate(r["site"], (gx[i], gy[i]), textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.set_xlabel("east m")
    ax.set_ylabel("north m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title("traverse (ellipses: optimised 2-sigma)")
    fig.savefig(os.path.join(out, "traverse_map.png"), dpi=120, bbox_inches="tight")
    plt.close(fig)


def error_vs_distance(sites, out):
    fig, ax = plt.subplots(figsize=(8, 5))
    d = column(sites, "distance_m")
    for key, style, label in (("dr", "r.--", "dead reckoning"), ("vis", "b.:", "visual (chained BA)"),
                              ("opt", "g.-", "optimised graph")):
        e = column(sites, key + "_err_m")
        if np.isfinite(e).any():
            ax.plot(d, e, style, label=label)
    ax.set_xlabel("distance driven m")
    ax.set_ylabel("position error m")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.savefig(os.path.join(out, "error_vs_distance.png"), dpi=120, bbox_inches="tight")
    plt.close(fig)


def uav_plots(uav, out):
    fig, ax = plt.subplots(figsize=(8, 8))
    ax.plot(column(uav, "gt_east_m"), column(uav, "gt_north_m"), "k-", label="ground truth")
    ax.plot(column(uav, "east_m"), column(uav, "north_m"), "b-", label="vloc route")
    ax.set_xlabel("east of take-off m")
    ax.set_ylabel("north of take-off m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.savefig(os.path.join(out, "uav_route.png"), dpi=120, bbox_inches="tight")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(8, 4))
    t = column(uav, "t_s")
    ax.plot(t, column(uav, "gt_height_m"), "k-", label="ground truth")
    ax.plot(t, column(uav, "height_m"), "b-", label="vloc height")
    ax.set_xlabel("time s")
    ax.set_ylabel("height above ground m")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.savefig(os.path.join(out, "uav_height.png"), dpi=120, bbox_inches="tight")
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="folder with vloc_eval's CSVs; PNGs are written there")
    args = parser.parse_args()
    if not os.path.isdir(args.out):
        print(f"plot_eval.py: {args.out} is not a folder (run vloc_eval first)", file=sys.stderr)
        return 1
    sites = read_csv(os.path.join(args.out, "sites.csv"))
    uav = read_csv(os.path.join(args.out, "uav.csv"))
    written = []
    if sites:
        traverse_map(sites, args.out)
        error_vs_distance(sites, args.out)
        written += ["traverse_map.png", "error_vs_distance.png"]
    if uav:
        uav_plots(uav, args.out)
        written += ["uav_route.png", "uav_height.png"]
    print("plot_eval.py: wrote " + (", ".join(written) if written else "nothing (no rows)") + " in " + args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
