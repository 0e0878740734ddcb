#!/usr/bin/python3
"""Vision heights against the GPS altitude minus a fitted ground, for three
ground models: one level (what uav_mosaic_files reports), a tilted plane and
a quadratic surface over the GPS east / north.

  scripts/heights_vs_ground.py out/seneca.tsv

Reads the report uav_mosaic_files --report writes (columns status,
height_m, gps_height_m, gps_east_m, gps_north_m; gps_height_m is the GPS
altitude minus the level ground the tool fitted). A photo's vision height is
above the ground under it; with relief, "altitude minus one level" is not
that height. The more parameters the ground gets, the more of the vision's
own slow drift it absorbs too: without a terrain model the two cannot be
told apart, so the level figure stays the measure and the others bound what
relief can explain.
"""
import csv
import sys

import numpy as np


USAGE = "usage: scripts/heights_vs_ground.py REPORT.tsv (a uav_mosaic_files --report)"
NEED = ("status", "height_m", "gps_height_m", "gps_east_m", "gps_north_m")


def read_report(path):
    """The report's rows, or exits with one line naming the problem."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f, delimiter="\t"))
    except OSError as e:
        sys.exit(f"heights_vs_ground.py: {path}: {e.strerror}")
    except (UnicodeDecodeError, csv.Error) as e:
        sys.exit(f"heights_vs_ground.py: {path}: not a text report ({e.__class__.__name__})")
    if not rows or any(k not in rows[0] for k in NEED):
        sys.exit(f"heights_vs_ground.py: {path}: not a uav_mosaic_files report (needs columns {', '.join(NEED)})")
    return rows


def value(row, key):
    try:
        return float(row[key])
    except (TypeError, ValueError):  # a short row (None) or a word
        return float("nan")


def main():
    if len(sys.argv) != 2:
        sys.exit(USAGE)
    rows = read_report(sys.argv[1])
    data = np.array([[value(r, k) for k in NEED[1:]] for r in rows if r["status"] != "LOST"]).reshape(-1, 4)
    data = data[np.all(np.isfinite(data), axis=1)]
    if len(data) < 10:
        sys.exit(f"heights_vs_ground.py: {sys.argv[1]}: only {len(data)} registered photos with a height and GPS")
    height, gps, east, north = data.T
    diff = gps - height
    one = np.ones_like(east)
    models = {
        "level (1 parameter)": np.c_[one],
        "tilted plane (3)": np.c_[one, east, north],
        "quadratic surface (6)": np.c_[one, east, north, east * east, east * north, north * north],
    }
    print(f"{len(data)} photos: vision height against the GPS height minus a fitted ground")
    for name, basis in models.items():
        coef, *_ = np.linalg.lstsq(basis, diff, rcond=None)
        reference = gps - basis @ coef
        rms = np.sqrt(np.mean((height - reference) ** 2))
        print(f"  {name:24s} RMS {rms:.3f} m = {100 * rms / reference.mean():.2f} %")


if __name__ == "__main__":
    main()
