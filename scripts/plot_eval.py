#!/usr/bin/python3
"""Plots for vloc_eval: reads the CSVs it wrote in --out and writes PNGs there.

  traverse_map.png      ground truth, dead reckoning, visual (chained BA) and
                        optimised site positions over the orthoimage of the
                        simulated terrain (ortho.png + ortho.pgw, written by
                        vloc_eval --terrain) when present; sites numbered,
                        3-sigma ellipses of the optimised marginal covariance,
                        loop-closure (revisit) edges
  error_vs_distance.png position and heading error of each estimate vs
                        distance driven, with the 1 % of distance line
  uav_route.png         UAV route (estimate and truth), when uav.csv has rows
  uav_height.png        UAV height over time (estimate and truth)

Needs python3 with numpy and matplotlib only (Debian: /usr/bin/python3).
"""
import argparse
import csv
import os
import sys

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.patheffects as pe  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Ellipse  # noqa: E402

ELLIPSE_SIGMA = 3.0

# One style per estimate: colour, line style, marker, line width, zorder.
# Dead reckoning is drawn dashed ABOVE the optimised line so both stay
# visible where they coincide (before the first visual edge).
STYLES = {
    "gt": dict(color="black", ls="-", marker="o", lw=2.2, ms=5, zorder=5, label="ground truth"),
    "opt": dict(color="#00a651", ls="-", marker="o", lw=3.0, ms=6, zorder=6, label="optimised graph"),
    "dr": dict(color="#ff7f0e", ls=(0, (5, 3)), marker="^", lw=1.6, ms=6, zorder=7, label="dead reckoning"),
    "vis": dict(color="#1f77ff", ls=":", marker="s", lw=1.4, ms=5, zorder=8, label="visual (chained BA)"),
}
HALO = [pe.Stroke(linewidth=4.5, foreground="white", alpha=0.7), pe.Normal()]


def read_csv(path):
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def column(rows, key):
    out = []
    for r in rows:
        v = r.get(key, "")
        try:
            out.append(float(v) if v not in ("", None, "-") else np.nan)
        except ValueError:
            out.append(np.nan)
    return np.array(out, dtype=float)


def read_ortho(out):
    """(image, extent) from ortho.png + ortho.pgw, or None."""
    png, pgw = os.path.join(out, "ortho.png"), os.path.join(out, "ortho.pgw")
    if not (os.path.exists(png) and os.path.exists(pgw)):
        return None
    try:
        with open(pgw) as f:
            a, d, b, e, c, f_ = (float(x) for x in f.read().split()[:6])
        image = plt.imread(png)
    except (OSError, ValueError) as err:
        print(f"plot_eval.py: ignoring orthoimage ({err})", file=sys.stderr)
        return None
    if abs(d) > 1e-12 or abs(b) > 1e-12 or a <= 0 or e >= 0:
        print("plot_eval.py: ignoring ortho.pgw (rotated or flipped world files are not supported)", file=sys.stderr)
        return None
    rows, cols = image.shape[:2]
    # Pixel centres are at c + i * a, f + j * e: the image spans half a pixel more.
    extent = (c - 0.5 * a, c + (cols - 0.5) * a, f_ + (rows - 0.5) * e, f_ - 0.5 * e)
    return image, extent


def plot_track(ax, x, y, style):
    """A line through the sites that have the estimate, broken where a site has none (markers show single sites)."""
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return False
    s = dict(style)
    ax.plot(x, y, color=s["color"], ls=s["ls"], lw=s["lw"], marker=s["marker"], ms=s["ms"],
            mec="white", mew=0.6, zorder=s["zorder"], path_effects=HALO if s["zorder"] <= 6 else None)
    return True


def traverse_map(sites, pairs, out):
    ortho = read_ortho(out)
    fig, ax = plt.subplots(figsize=(10, 10))
    gx, gy = column(sites, "gt_x"), column(sites, "gt_y")
    ids = [r["site"] for r in sites]
    handles = []
    if ortho is not None:
        image, extent = ortho
        ax.imshow(image, cmap="gray", extent=extent, origin="upper", interpolation="bilinear", zorder=0,
                  vmin=0, vmax=1 if image.dtype != np.uint8 else 255)
    for key in ("gt", "opt", "dr", "vis"):
        x, y = (gx, gy) if key == "gt" else (column(sites, key + "_x"), column(sites, key + "_y"))
        if plot_track(ax, x, y, STYLES[key]):
            st = STYLES[key]
            handles.append(Line2D([], [], color=st["color"], ls=st["ls"], lw=st["lw"], marker=st["marker"],
                                  ms=st["ms"], label=st["label"]))
    # Uncertainty: optimised marginal covariance, ELLIPSE_SIGMA-sigma.
    ox, oy = column(sites, "opt_x"), column(sites, "opt_y")
    cxx, cxy, cyy = column(sites, "opt_cov_xx"), column(sites, "opt_cov_xy"), column(sites, "opt_cov_yy")
    drew_ellipse = False
    for i in range(len(sites)):
        if not (np.isfinite(ox[i]) and cxx[i] > 0 and cyy[i] > 0):
            continue
        w, v = np.linalg.eigh(np.array([[cxx[i], cxy[i]], [cxy[i], cyy[i]]]))
        w = np.maximum(w, 0)
        angle = np.degrees(np.arctan2(v[1, 1], v[0, 1]))
        ax.add_patch(Ellipse((ox[i], oy[i]), 2 * ELLIPSE_SIGMA * np.sqrt(w[1]), 2 * ELLIPSE_SIGMA * np.sqrt(w[0]),
                             angle=angle, fc=(0.0, 0.65, 0.32, 0.10), ec=STYLES["opt"]["color"], lw=1.4,
                             zorder=4))
        drew_ellipse = True
    if drew_ellipse:
        handles.append(Ellipse((0, 0), 1, 1, fc=(0.0, 0.65, 0.32, 0.10), ec=STYLES["opt"]["color"], lw=1.4,
                               label=f"optimised {ELLIPSE_SIGMA:.0f}-sigma position ellipse"))
    # Revisits: visual edges between non-adjacent sites, drawn between the true positions.
    pos = {r["site"]: (gx[i], gy[i]) for i, r in enumerate(sites)}
    loops = 0
    for p in pairs:
        try:
            ref, cur, status = int(p["reference"]), int(p["site"]), int(p["status"])
        except (KeyError, ValueError):
            continue
        if abs(cur - ref) <= 1 or str(ref) not in pos or str(cur) not in pos:
            continue
        (x0, y0), (x1, y1) = pos[str(ref)], pos[str(cur)]
        colour = "magenta" if status == 0 else "gray"
        if np.hypot(x1 - x0, y1 - y0) > 1.0:  # an arrow only where it can be seen
            ax.annotate("", xy=(x0, y0), xytext=(x1, y1), zorder=9,
                        arrowprops=dict(arrowstyle="->", color=colour, lw=2, connectionstyle="arc3,rad=0.35",
                                        ls="-" if status == 0 else "--"))
        for x, y in ((x0, y0), (x1, y1)):
            ax.plot(x, y, marker="o", ms=18, mfc="none", mec=colour, mew=2.2, zorder=9, ls="none")
        loops += 1
    if loops:
        handles.append(Line2D([], [], color="magenta", lw=0, marker="o", ms=12, mfc="none", mew=2.2,
                              label="revisit: site matched with an earlier one (loop closure)"))
    # Site numbers next to the ground truth, on a white box so they read over the terrain;
    # sites at the same place (a revisit) share one label, "2/6".
    labels = []  # [x, y, text]
    for i, sid in enumerate(ids):
        if not np.isfinite(gx[i]):
            continue
        for lab in labels:
            if np.hypot(lab[0] - gx[i], lab[1] - gy[i]) < 1.0:
                lab[2] += "/" + sid
                break
        else:
            labels.append([gx[i], gy[i], sid])
    for x, y, text in labels:
        ax.annotate(text, (x, y), textcoords="offset points", xytext=(-14, 6), fontsize=8, zorder=10,
                    ha="right" if "/" in text else "left",
                    bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8))
    # Start and end.
    if len(sites):
        ax.plot(gx[0], gy[0], marker="*", ms=16, color="gold", mec="black", zorder=11, ls="none")
        handles.append(Line2D([], [], marker="*", ms=12, color="gold", mec="black", ls="none", label="start (site 0)"))
    ax.set_xlabel("east m (world frame: origin at site 0)")
    ax.set_ylabel("north m")
    ax.set_aspect("equal")
    # Frame on the sites (the orthoimage may extend further), with room for the ellipses.
    xs = np.concatenate([a[np.isfinite(a)] for a in (gx, ox, column(sites, "dr_x"), column(sites, "vis_x"))])
    ys = np.concatenate([a[np.isfinite(a)] for a in (gy, oy, column(sites, "dr_y"), column(sites, "vis_y"))])
    if xs.size:
        pad = 0.08 * max(np.ptp(xs), np.ptp(ys), 10.0)
        x0, x1, y0, y1 = xs.min() - pad, xs.max() + pad, ys.min() - pad, ys.max() + pad
        if ortho is not None:  # stay inside the image
            ex = ortho[1]
            x0, x1, y0, y1 = max(x0, ex[0]), min(x1, ex[1]), max(y0, ex[2]), min(y1, ex[3])
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
    ax.grid(True, alpha=0.25 if ortho is None else 0.15, color="gray" if ortho is None else "white")
    ax.legend(handles=handles, loc="best", framealpha=0.9, fontsize=9)
    title = f"traverse: {len(sites)} sites"
    d = column(sites, "distance_m")
    if np.isfinite(d).any():
        title += f", {np.nanmax(d):.1f} m driven"
    if ortho is not None:
        title += " (over the simulated terrain)"
    ax.set_title(title)
    fig.savefig(os.path.join(out, "traverse_map.png"), dpi=110, bbox_inches="tight")
    plt.close(fig)


def error_vs_distance(sites, out):
    fig, (ax, axh) = plt.subplots(2, 1, figsize=(9, 7.5), sharex=True, gridspec_kw=dict(height_ratios=[2, 1]))
    d = column(sites, "distance_m")
    for key in ("dr", "vis", "opt"):
        st = STYLES[key]
        for a, col in ((ax, key + "_err_m"), (axh, key + "_heading_err_deg")):
            e = column(sites, col)
            if (np.isfinite(e) & np.isfinite(d)).any():  # NaN breaks the line where a site has no estimate
                a.plot(d, e, color=st["color"], ls=st["ls"], marker=st["marker"], lw=max(st["lw"] - 0.8, 1.2),
                       ms=st["ms"], label=st["label"], zorder=st["zorder"])
    if np.isfinite(d).any():
        dd = np.array([0, np.nanmax(d)])
        ax.plot(dd, 0.01 * dd, color="gray", ls="-.", lw=1, label="1 % of distance (target)")
        ax.plot(dd, 0.15 * dd, color="gray", ls=":", lw=1, label="15 % of distance (DR worst case)")
    # The end figures as text, the number an operator asks for.
    last = sites[-1] if sites else {}
    lines = []
    for key in ("dr", "vis", "opt"):
        v = last.get(key + "_err_pct", "")
        if v not in ("", None):
            lines.append(f"{STYLES[key]['label']}: {float(v):.2f} % at the end")
    if lines:
        ax.text(0.02, 0.97, "\n".join(lines), transform=ax.transAxes, va="top", fontsize=9,
                bbox=dict(boxstyle="round", fc="white", ec="lightgray", alpha=0.9))
    ax.set_ylabel("position error m")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=9)
    ax.set_title("error versus distance driven")
    axh.set_ylabel("heading error deg")
    axh.set_xlabel("distance driven m (ground truth, site to site)")
    axh.set_ylim(bottom=0)
    axh.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "error_vs_distance.png"), dpi=110, bbox_inches="tight")
    plt.close(fig)


def uav_plots(uav, out):
    fig, ax = plt.subplots(figsize=(8, 8))
    ax.plot(column(uav, "gt_east_m"), column(uav, "gt_north_m"), "k-", lw=2.2, label="ground truth")
    ax.plot(column(uav, "east_m"), column(uav, "north_m"), color="#1f77ff", ls="--", lw=1.5, label="vloc route")
    ax.set_xlabel("east of take-off m")
    ax.set_ylabel("north of take-off m")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.savefig(os.path.join(out, "uav_route.png"), dpi=110, bbox_inches="tight")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(8, 4))
    t = column(uav, "t_s")
    ax.plot(t, column(uav, "gt_height_m"), "k-", lw=2.2, label="ground truth")
    ax.plot(t, column(uav, "height_m"), color="#1f77ff", ls="--", lw=1.5, label="vloc height")
    ax.set_xlabel("time s")
    ax.set_ylabel("height above ground m")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.savefig(os.path.join(out, "uav_height.png"), dpi=110, bbox_inches="tight")
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="folder with vloc_eval's CSVs; PNGs are written there")
    args = parser.parse_args()
    if not os.path.isdir(args.out):
        print(f"plot_eval.py: {args.out} is not a folder (run vloc_eval first)", file=sys.stderr)
        return 1
    sites = read_csv(os.path.join(args.out, "sites.csv"))
    pairs = read_csv(os.path.join(args.out, "pairs.csv"))
    uav = read_csv(os.path.join(args.out, "uav.csv"))
    written = []
    if sites:
        traverse_map(sites, pairs, args.out)
        error_vs_distance(sites, args.out)
        written += ["traverse_map.png", "error_vs_distance.png"]
    if uav:
        uav_plots(uav, args.out)
        written += ["uav_route.png", "uav_height.png"]
    print("plot_eval.py: wrote " + (", ".join(written) if written else "nothing (no rows)") + " in " + args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
