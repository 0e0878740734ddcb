#!/usr/bin/python3
"""A photogrammetric height reference for a geotagged survey, made by a peer
tool: COLMAP (Debian package colmap) reconstructs the flight (SIFT, matching
of the photos the GPS puts near each other, incremental structure from motion
with bundle adjustment, one camera with its focal length and radial
distortion self-calibrated), the model is aligned to the photos' GPS in local
east-north-up metres, and each registered photo's height above the ground it
sees is its camera centre minus the median height of the 3-D points it
observes. A camera GPS's altitude is noisy (on uav_seneca 1.7 m RMS = 2.7 %
from this reference) and "altitude minus one ground level" ignores the
relief; this height is neither.

  scripts/survey_reference.py IMAGES_DIR OUT_DIR [--exclude NAME ...]
  -> OUT_DIR/reference_heights.tsv (name, height_m, east_m, north_m, up_m, points)
  build/bin/uav_mosaic_files --height-reference OUT_DIR/reference_heights.tsv --out out/survey.png IMAGES_DIR

--exclude leaves photos out (COLMAP's one camera cannot hold a photo of
another field of view at the same pixel size, e.g. uav_seneca's cropped
IMG_0446.jpg). --level-gps aligns on the GPS east/north with every photo at
one altitude, for a GPS altitude that drifts (uav_caliterra's climbs 113 m
while the photos keep their scale): the heights then take the scale of the
least-squares fit of the camera centres to the GPS east/north. The model is aligned by RANSAC with --alignment-max-error
(m, default 5) as its inlier threshold: give about 3x the GPS's horizontal
error (uav_caliterra's GPS is off by ~15 m: 45); the script says when the
alignment's scale strays from the least-squares fit of every photo's GPS. Installs colmap with apt-get when it is missing (as root).
uav_seneca (166 photos, 960 px) on 2 cores: about 13 min.
"""
import argparse
import os
import shutil
import sqlite3
import subprocess
import sys

import numpy as np

WGS84_A = 6378137.0
WGS84_E2 = (1 / 298.257223563) * (2 - 1 / 298.257223563)


def fail(message):
    sys.exit(f"survey_reference.py: {message}")


def ensure_colmap():
    if shutil.which("colmap"):
        return
    if os.geteuid() != 0:
        fail("colmap is missing; install it with: sudo apt-get install colmap")
    print("[survey_reference] installing colmap", flush=True)
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    for command in (["apt-get", "update", "-qq"], ["apt-get", "install", "-y", "-qq", "--no-install-recommends", "colmap"]):
        if subprocess.run(command, env=env).returncode != 0:
            fail(f"{' '.join(command)} failed: colmap could not be installed")


def colmap(log, *args):
    """Runs one colmap command, its output in `log`; exits naming the step when it fails."""
    with open(log, "a") as f:
        f.write(f"$ colmap {' '.join(args)}\n")
        f.flush()
        if subprocess.run(["colmap", *args], stdout=f, stderr=subprocess.STDOUT).returncode != 0:
            fail(f"colmap {args[0]} failed (see {log})")


def ecef(lat, lon, alt):
    la, lo = np.radians(lat), np.radians(lon)
    n = WGS84_A / np.sqrt(1 - WGS84_E2 * np.sin(la) ** 2)
    return np.array([(n + alt) * np.cos(la) * np.cos(lo), (n + alt) * np.cos(la) * np.sin(lo),
                     (n * (1 - WGS84_E2) + alt) * np.sin(la)])


def largest_model(sparse):
    """The model holding the most photos (images.bin starts with their count)."""
    counts = {}
    for m in os.listdir(sparse):
        with open(os.path.join(sparse, m, "images.bin"), "rb") as f:
            counts[m] = int(np.frombuffer(f.read(8), dtype="<u8")[0])
    if not counts:
        fail("COLMAP registered no model (too little overlap or texture?)")
    return os.path.join(sparse, max(counts, key=counts.get))


def write_gps_enu(database, path, level):
    """The GPS COLMAP read from the photos' EXIF, as east/north/up metres from the first photo (by name);
    level: up 0 for every photo (a GPS altitude not to be trusted)."""
    rows = sqlite3.connect(database).execute(
        "select name, prior_tx, prior_ty, prior_tz from images order by name").fetchall()
    rows = [r for r in rows if all(v is not None and np.isfinite(v) for v in r[1:])]
    if len(rows) < 3:
        fail(f"only {len(rows)} photos carry a GPS position: the model cannot be put in metres")
    lat0, lon0, alt0 = rows[0][1:]
    la, lo = np.radians(lat0), np.radians(lon0)
    enu_from_ecef = np.array([[-np.sin(lo), np.cos(lo), 0],
                              [-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)],
                              [np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)]])
    origin = ecef(lat0, lon0, alt0)
    with open(path, "w") as f:
        for name, lat, lon, alt in rows:
            e, n, u = enu_from_ecef @ (ecef(lat, lon, alt0 if level else alt) - origin)
            u = 0.0 if level else u
            f.write(f"{name} {e:.4f} {n:.4f} {u:.4f}\n")
    return len(rows)


def rotation(qw, qx, qy, qz):
    return np.array([[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
                     [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
                     [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]])


def camera_centres(model):
    """name -> camera centre of every registered photo of a text model (images.txt: world-to-camera QW..TZ)."""
    with open(os.path.join(model, "images.txt")) as f:
        lines = [line for line in f if not line.startswith("#")]
    centres = {}
    for pose in lines[0::2]:
        v = pose.split()
        centres[v[9]] = -rotation(*map(float, v[1:5])).T @ np.array(list(map(float, v[5:8])))
    return centres, lines


def horizontal_scale(centres, gps_path):
    """The scale of the least-squares 2-D similarity from the aligned centres to every photo's GPS east/north."""
    gps = {}
    with open(gps_path) as f:
        for line in f:
            v = line.split()
            gps[v[0]] = np.array([float(v[1]), float(v[2])])
    names = [n for n in centres if n in gps]
    a = np.array([centres[n][:2] for n in names])
    b = np.array([gps[n] for n in names])
    za = (a[:, 0] - a[:, 0].mean()) + 1j * (a[:, 1] - a[:, 1].mean())
    zb = (b[:, 0] - b[:, 0].mean()) + 1j * (b[:, 1] - b[:, 1].mean())
    return abs(np.vdot(za, zb) / np.vdot(za, za))


def write_heights(model, poses, path, command, alignment, scale=1.0):
    """Each registered photo's camera centre minus the median height of the points it observes (a text model whose
    camera_centres are `poses`), times `scale`."""
    points = {}
    with open(os.path.join(model, "points3D.txt")) as f:
        for line in f:
            if not line.startswith("#"):
                v = line.split()
                points[int(v[0])] = float(v[3])
    centres, lines = poses
    rows = []
    for pose, observations in zip(lines[0::2], lines[1::2]):
        v = pose.split()
        centre = centres[v[9]]
        ids = [int(i) for i in observations.split()[2::3] if int(i) != -1]
        z = [points[i] for i in ids if i in points]
        if len(z) < 20:
            continue
        rows.append((v[9], scale * (centre[2] - float(np.median(z))), *centre, len(z)))
    if not rows:
        fail("no registered photo observes 20 or more 3-D points")
    with open(path, "w") as f:
        f.write("# heights above the ground each photo sees (camera centre minus the median height of its points),\n")
        f.write("# COLMAP model aligned to the photos' GPS (east/north/up m from the first photo), made by:\n")
        f.write(f"# {command}\n")
        with open(os.path.join(model, "cameras.txt")) as c:
            camera = [line.split() for line in c if not line.startswith("#")][0]
        f.write(f"# camera {camera[1]} {camera[2]} x {camera[3]}, parameters {' '.join(f'{float(p):.5g}' for p in camera[4:])}; "
                f"{len(rows)} photos; {alignment}\n")
        f.write("name\theight_m\teast_m\tnorth_m\tup_m\tpoints\n")
        for name, h, e, n, u, count in sorted(rows):
            f.write(f"{name}\t{h:.3f}\t{e:.3f}\t{n:.3f}\t{u:.3f}\t{count}\n")
    return rows


def link_photos(images, names, exclude, photos):
    """The photos COLMAP sees: links to all but the excluded ones."""
    shutil.rmtree(photos, ignore_errors=True)
    os.makedirs(photos)
    for n in names:
        if n not in exclude:
            os.symlink(os.path.abspath(os.path.join(images, n)), os.path.join(photos, n))


def reconstruct(photos, out, threads, log):
    """COLMAP's features, GPS-guided matching and mapping; the database and the largest model."""
    db = os.path.join(out, "colmap.db")
    for stale in (db, log):
        if os.path.exists(stale):
            os.remove(stale)
    t = str(threads)
    colmap(log, "feature_extractor", "--database_path", db, "--image_path", photos, "--ImageReader.single_camera", "1",
           "--ImageReader.camera_model", "RADIAL", "--SiftExtraction.use_gpu", "0", "--SiftExtraction.num_threads", t,
           "--SiftExtraction.max_num_features", "8000")
    colmap(log, "spatial_matcher", "--database_path", db, "--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads",
           t, "--SpatialMatching.is_gps", "1", "--SpatialMatching.max_num_neighbors", "25",
           "--SpatialMatching.max_distance", "200")
    sparse = os.path.join(out, "sparse")
    shutil.rmtree(sparse, ignore_errors=True)
    os.makedirs(sparse)
    colmap(log, "mapper", "--database_path", db, "--image_path", photos, "--output_path", sparse,
           "--Mapper.num_threads", t, "--Mapper.ba_refine_principal_point", "0")
    return db, largest_model(sparse)


def align(model, gps, out, max_error, level, log):
    """The model aligned to the GPS (east/north/up m) as a text model, its camera_centres, COLMAP's alignment error
    line, and the factor the heights take: with level GPS (one altitude for all), the scale of the least-squares fit
    of the centres to every photo's GPS east/north (COLMAP's 3-D fit shrinks a model whose photos climbed towards the
    level), else 1."""
    aligned = os.path.join(out, "aligned")
    os.makedirs(aligned, exist_ok=True)
    colmap(log, "model_aligner", "--input_path", model, "--output_path", aligned, "--ref_images_path", gps,
           "--ref_is_gps", "0", "--robust_alignment", "1", "--robust_alignment_max_error", str(max_error))
    with open(log) as f:
        text = f.read()
    errors = [line.strip("=> ") for line in text.splitlines() if "Alignment error" in line]
    if "Alignment succeeded" not in text or not errors:
        fail(f"the model could not be aligned to the GPS (see {log})")
    colmap(log, "model_converter", "--input_path", aligned, "--output_path", aligned, "--output_type", "TXT")
    poses = camera_centres(aligned)
    scale = horizontal_scale(poses[0], gps)
    line = "GPS alignment error" + errors[-1].split("Alignment error", 1)[1] + " m"
    if level:
        return aligned, poses, f"{line}; heights x {scale:.4f}, the least-squares scale to the GPS east/north", scale
    if abs(scale - 1) > 0.01:
        print(f"[survey_reference] warning: the least-squares fit of every photo's GPS scales the aligned model by "
              f"{scale:.4f}: the RANSAC alignment kept too few photos; give --alignment-max-error about 3x the GPS's "
              f"error", flush=True)
    return aligned, poses, line, 1.0


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("images")
    p.add_argument("out")
    p.add_argument("--exclude", action="append", default=[], help="photo left out (file name)")
    p.add_argument("--level-gps", action="store_true",
                   help="align on the GPS east/north only, every photo at one altitude (a GPS altitude that drifts)")
    p.add_argument("--alignment-max-error", type=float, default=5.0,
                   help="m, the GPS alignment's RANSAC inlier threshold (about 3x the GPS's horizontal error)")
    p.add_argument("--threads", type=int, default=2)
    a = p.parse_args()
    if not os.path.isdir(a.images):
        fail(f"{a.images}: not a folder of photos")
    names = sorted(n for n in os.listdir(a.images) if n.lower().endswith((".jpg", ".jpeg", ".png", ".tif", ".tiff")))
    unknown = [n for n in a.exclude if n not in names]
    if unknown:
        fail(f"--exclude {' '.join(unknown)}: no such photo in {a.images}")
    ensure_colmap()
    os.makedirs(a.out, exist_ok=True)
    photos, log = os.path.join(a.out, "photos"), os.path.join(a.out, "colmap.log")
    link_photos(a.images, names, a.exclude, photos)
    used = len(names) - len(a.exclude)
    print(f"[survey_reference] {used} photos: features, matching, mapping (log {log})", flush=True)
    db, model = reconstruct(photos, a.out, a.threads, log)
    gps = os.path.join(a.out, "gps_enu.txt")
    tagged = write_gps_enu(db, gps, a.level_gps)
    aligned, poses, alignment, scale = align(model, gps, a.out, a.alignment_max_error, a.level_gps, log)
    tsv = os.path.join(a.out, "reference_heights.tsv")
    rows = write_heights(aligned, poses, tsv, "scripts/survey_reference.py " + " ".join(sys.argv[1:]), alignment, scale)
    heights = np.array([r[1] for r in rows])
    print(f"[survey_reference] {len(rows)} of {used} photos registered ({tagged} with GPS), heights "
          f"{heights.min():.1f}-{heights.max():.1f} m (median {np.median(heights):.1f}): {tsv}")


if __name__ == "__main__":
    main()
