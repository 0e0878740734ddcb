#!/usr/bin/python3
"""The cooperative run's own figures (scripts/coop_demo.sh): how well the UAV mosaic is
georeferenced, what map_localizer made of it, and the picture of the traverse over the mosaic.

  /usr/bin/python3 scripts/coop_eval.py --dir out/coop [--figure FILE.jpg]

Reads from DIR: uav_mosaic.png + .pgw (the mosaicker's, lon/lat degrees), coop_orthomap.png + .pgw
(the ground the UAV saw, world metres), eval/sites.csv and eval/fixes.csv (vloc_eval on the rover
log), map_localizer.log. Writes DIR/coop_summary.md (and prints it), DIR/mosaic_error.csv and the
figure (DIR/coop_traverse.jpg by default).

Mosaic georeferencing error: the mosaic is resampled north-up on the orthomap's grid at 10 cm/px
through its world file (degrees -> metres around the UAV simulator's GPS origin, the first-order
WGS84 tangent plane the simulator uses), and 12.8 m tiles of it are located in the orthomap by
normalised cross-correlation (the same sun: the UAV saw that image); error = where the mosaic puts
a tile minus where it is.
"""
import argparse
import csv
import math
import os
import re
import sys

import cv2
import numpy as np

A_WGS84 = 6378137.0
E2_WGS84 = 6.69437999014e-3


def world_file(path):
    with open(path) as f:
        v = [float(x) for x in f.read().split()[:6]]
    a, d, b, e, c, f_ = v
    return np.array([[a, b, c], [d, e, f_]])  # file coords of pixel centre (col, row)


def degrees_to_metres(m_deg, lat0, lon0, alt0=0.0):
    """Affine pixel -> (lon, lat) deg to pixel -> (east, north) m (first-order WGS84, as vloc::LocalTangentPlane)."""
    s = math.sin(math.radians(lat0))
    w = math.sqrt(1 - E2_WGS84 * s * s)
    m_lat = A_WGS84 * (1 - E2_WGS84) / w ** 3 + alt0
    m_lon = (A_WGS84 / w + alt0) * math.cos(math.radians(lat0))
    k = np.array([[math.radians(1) * m_lon, 0], [0, math.radians(1) * m_lat]])
    out = k @ m_deg
    out[0, 2] = math.radians(m_deg[0, 2] - lon0) * m_lon
    out[1, 2] = math.radians(m_deg[1, 2] - lat0) * m_lat
    return out


def to_grid(image, world_from_pixel, x_min, y_max, res, size, interpolation=cv2.INTER_LINEAR):
    """image resampled on the north-up grid (x_min, y_max, res, size=(w, h)); cell centres."""
    world_from_out = np.array([[res, 0, x_min + 0.5 * res], [0, -res, y_max - 0.5 * res], [0, 0, 1]])
    src = np.vstack([world_from_pixel, [0, 0, 1]])
    warp = (np.linalg.inv(src) @ world_from_out)[:2]
    return cv2.warpAffine(image, warp, size, flags=interpolation | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def read_csv(path):
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return list(csv.DictReader(f))


def num(row, key):
    try:
        return float(row[key])
    except (KeyError, ValueError, TypeError):
        return float("nan")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dir", required=True)
    ap.add_argument("--figure", default=None)
    ap.add_argument("--origin", default="45.4642,9.19,120", help="lat,lon,alt of the world origin (sim_uav_coop.yaml)")
    ap.add_argument("--res", type=float, default=0.1)
    ap.add_argument("--tile", type=int, default=128)
    args = ap.parse_args()
    d = args.dir
    lat0, lon0, alt0 = (float(x) for x in args.origin.split(","))
    res = args.res

    ortho = cv2.imread(os.path.join(d, "coop_orthomap.png"), cv2.IMREAD_GRAYSCALE)
    ortho_w = world_file(os.path.join(d, "coop_orthomap.pgw"))
    mosaic = cv2.imread(os.path.join(d, "uav_mosaic.png"), cv2.IMREAD_UNCHANGED)
    if ortho is None or mosaic is None:
        sys.exit("coop_eval.py: need coop_orthomap.png and uav_mosaic.png in " + d)
    mosaic_w = degrees_to_metres(world_file(os.path.join(d, "uav_mosaic.pgw")), lat0, lon0, alt0)
    # The grid: the orthomap's extent at `res`.
    x_min = ortho_w[0, 2] - 0.5 * ortho_w[0, 0]
    y_max = ortho_w[1, 2] - 0.5 * ortho_w[1, 1]
    size = (int(round(ortho.shape[1] * ortho_w[0, 0] / res)), int(round(ortho.shape[0] * -ortho_w[1, 1] / res)))
    ortho_g = cv2.resize(ortho, size, interpolation=cv2.INTER_AREA).astype(np.float32)
    grey = cv2.cvtColor(mosaic[:, :, :3], cv2.COLOR_BGR2GRAY)
    alpha = mosaic[:, :, 3] if mosaic.shape[2] == 4 else np.full(grey.shape, 255, np.uint8)
    mosaic_g = to_grid(grey, mosaic_w, x_min, y_max, res, size).astype(np.float32)
    valid_g = to_grid((alpha > 0).astype(np.float32), mosaic_w, x_min, y_max, res, size) > 0.999

    def world_of(col, row):
        return x_min + (col + 0.5) * res, y_max - (row + 0.5) * res

    # Tiles of the mosaic located in the orthomap (search +-4 m).
    t, pad = args.tile, int(round(4.0 / res))
    rows = []
    for r0 in range(pad, size[1] - t - pad, t // 2):
        for c0 in range(pad, size[0] - t - pad, t // 2):
            if valid_g[r0:r0 + t, c0:c0 + t].mean() < 0.999:
                continue
            tmpl = mosaic_g[r0:r0 + t, c0:c0 + t]
            if tmpl.std() < 3:
                continue
            search = ortho_g[r0 - pad:r0 + t + pad, c0 - pad:c0 + t + pad]
            score = cv2.matchTemplate(search, tmpl, cv2.TM_CCOEFF_NORMED)
            _, best, _, (bx, by) = cv2.minMaxLoc(score)
            if best < 0.5 or bx in (0, score.shape[1] - 1) or by in (0, score.shape[0] - 1):
                continue
            # Sub-pixel peak (parabola per axis).
            def sub(a, b, c):
                den = a - 2 * b + c
                return 0.0 if den == 0 else 0.5 * (a - c) / den
            sx = bx + sub(score[by, bx - 1], score[by, bx], score[by, bx + 1])
            sy = by + sub(score[by - 1, bx], score[by, bx], score[by + 1, bx])
            # The tile's content lies (sx - pad, sy - pad) px away in the truth; the mosaic puts it here.
            ex, ey = -(sx - pad) * res, (sy - pad) * res  # m, mosaic minus truth (x east, y north)
            cx, cy = world_of(c0 + 0.5 * t - 0.5, r0 + 0.5 * t - 0.5)
            rows.append((cx, cy, ex, ey, best))
    errs = np.array([[r[2], r[3]] for r in rows]) if rows else np.zeros((0, 2))
    with open(os.path.join(d, "mosaic_error.csv"), "w") as f:
        f.write("x,y,err_x,err_y,err,ncc\n")
        for cx, cy, ex, ey, s in rows:
            f.write(f"{cx:.2f},{cy:.2f},{ex:.4f},{ey:.4f},{math.hypot(ex, ey):.4f},{s:.3f}\n")

    sites = read_csv(os.path.join(d, "eval", "sites.csv"))
    fixes = read_csv(os.path.join(d, "eval", "fixes.csv"))
    log = open(os.path.join(d, "map_localizer.log")).read() if os.path.exists(os.path.join(d, "map_localizer.log")) else ""
    attempted = len(re.findall(r"site \d+: (?:fix|no fix)", log)) or None
    fixed = set(re.findall(r"site (\d+): fix \(ok\)", log))
    no_fix = [(s, why) for s, why in re.findall(r"site (\d+): no fix: ([^(]*)", log) if s not in fixed]
    retried = sorted(set(re.findall(r"site (\d+): tried again on the new map", log)) & fixed, key=int)
    status = re.findall(r"(\d+) fixes, (\d+) sites without a fix", log)

    def local_mosaic_error(x, y, radius=15.0):
        near = [math.hypot(r[2], r[3]) for r in rows if math.hypot(r[0] - x, r[1] - y) <= radius]
        mean = [(r[2], r[3]) for r in rows if math.hypot(r[0] - x, r[1] - y) <= radius]
        if not near:
            return float("nan"), float("nan"), float("nan")
        m = np.mean(np.array(mean), axis=0)
        return float(np.median(near)), float(m[0]), float(m[1])

    out = []
    out.append("# Cooperative run: the UAV mosaic as the rover's map\n")
    mpp = math.sqrt(abs(np.linalg.det(mosaic_w[:, :2])))
    rot = math.degrees(math.atan2(mosaic_w[1, 0], mosaic_w[0, 0]))
    out.append(f"mosaic: {mosaic.shape[1]} x {mosaic.shape[0]} px at {mpp:.4f} m/px, turned {rot:.1f} deg from north-up;"
               f" covers {valid_g.mean() * size[0] * size[1] * res * res:.0f} m^2 of the orthomap grid\n")
    if len(errs):
        e = np.hypot(errs[:, 0], errs[:, 1])
        out.append(f"mosaic georeferencing error ({len(errs)} tiles of {t * res:.1f} m, mosaic minus truth):"
                   f" median {np.median(e):.3f} m, RMS {math.sqrt(np.mean(e ** 2)):.3f} m, max {e.max():.3f} m;"
                   f" mean vector ({errs[:, 0].mean():+.3f}, {errs[:, 1].mean():+.3f}) m\n")
    else:
        out.append("mosaic georeferencing error: no tile located\n")
    if status:
        ok, bad = status[-1]
        out.append(f"map_localizer: {ok} fixes, {bad} sites without a fix"
                   + ("".join(f"; site {s}: {why.strip()}" for s, why in no_fix))
                   + ("".join(f"; site {s} fixed when tried again on a later map" for s in retried)) + "\n")
    if fixes:
        out.append("| site | fix error m (x, y) | heading error deg | sigma x / y m | NEES xy / xyh | mosaic error there m (mean x, y) |")
        out.append("|---|---|---|---|---|---|")
        for fx in fixes:
            site = int(fx["site"])
            gt = next((s for s in sites if int(s["site"]) == site), None)
            med, mx, my = local_mosaic_error(num(gt, "gt_x"), num(gt, "gt_y")) if gt else (float("nan"),) * 3
            out.append(f"| {site} | {num(fx, 'err_xy'):.3f} ({num(fx, 'err_x'):+.3f}, {num(fx, 'err_y'):+.3f}) |"
                       f" {num(fx, 'heading_err_deg'):+.2f} | {num(fx, 'sigma_x'):.3f} / {num(fx, 'sigma_y'):.3f} |"
                       f" {num(fx, 'nees_xy'):.2f} / {num(fx, 'nees_xyh'):.2f} | {med:.3f} ({mx:+.3f}, {my:+.3f}) |")
        out.append("")
    if sites:
        last = sites[-1]
        out.append(f"end of traverse (site {last['site']}, {num(last, 'distance_m'):.1f} m): optimised with fixes"
                   f" {num(last, 'opt_err_m'):.3f} m, chained visual (no fixes) {num(last, 'vis_err_m'):.3f} m,"
                   f" dead reckoning {num(last, 'dr_err_m'):.3f} m\n")
    text = "\n".join(out)
    print(text)
    with open(os.path.join(d, "coop_summary.md"), "w") as f:
        f.write(text + "\n")
    figure(args.figure or os.path.join(d, "coop_traverse.jpg"), mosaic_g, valid_g, x_min, y_max, res, sites, fixes)


def figure(path, mosaic_g, valid_g, x_min, y_max, res, sites, fixes):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    xs = [num(s, "gt_x") for s in sites]
    ys = [num(s, "gt_y") for s in sites]
    if xs:
        bx0, bx1, by0, by1 = min(xs) - 16, max(xs) + 16, min(ys) - 16, max(ys) + 16
    else:
        bx0, bx1, by0, by1 = x_min, x_min + mosaic_g.shape[1] * res, y_max - mosaic_g.shape[0] * res, y_max
    c0, c1 = int((bx0 - x_min) / res), int((bx1 - x_min) / res)
    r0, r1 = int((y_max - by1) / res), int((y_max - by0) / res)
    c0, r0 = max(c0, 0), max(r0, 0)
    img = mosaic_g[r0:r1, c0:c1].copy()
    img[~valid_g[r0:r1, c0:c1]] = 255
    extent = [x_min + c0 * res, x_min + c1 * res, y_max - r1 * res, y_max - r0 * res]
    fig, ax = plt.subplots(figsize=(6.4, 6.4 * (extent[3] - extent[2]) / max(1e-6, extent[1] - extent[0]) * 0.9 + 0.6),
                           dpi=110)
    ax.imshow(img, cmap="gray", extent=extent, vmin=np.percentile(img, 1), vmax=np.percentile(img, 99.5))

    def line(kx, ky, **kw):
        pts = [(num(s, kx), num(s, ky)) for s in sites if math.isfinite(num(s, kx))]
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], **kw)

    line("gt_x", "gt_y", color="lime", lw=5, alpha=0.7, marker="o", ms=7, label="truth")
    line("dr_x", "dr_y", color="orange", lw=1.4, marker=".", label="dead reckoning")
    line("vis_x", "vis_y", color="deepskyblue", lw=1.2, ls="--", marker=".", label="chained visual (no fixes)")
    line("opt_x", "opt_y", color="magenta", lw=1.4, marker="x", ms=5, label="optimised (with fixes)")
    if fixes:
        ax.plot([num(f, "x") for f in fixes], [num(f, "y") for f in fixes], "s", mfc="none", mec="red", ms=11,
                mew=2, label="map fix")
    for s in sites:
        ax.annotate(s["site"], (num(s, "gt_x"), num(s, "gt_y")), xytext=(5, 4), textcoords="offset points",
                    color="yellow", fontsize=8)
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")
    ax.set_title("rover traverse over the UAV mosaic (10 cm/px, GPS-tied)", fontsize=10)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", fontsize=7, framealpha=0.8)
    fig.tight_layout()
    fig.savefig(path, dpi=110, pil_kwargs={"quality": 82, "optimize": True})
    print("figure:", path)


if __name__ == "__main__":
    main()
