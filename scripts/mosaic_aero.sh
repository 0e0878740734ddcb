#!/usr/bin/env bash
# The UAV mosaicker on real aerial imagery: OpenCV's aero1.jpg and aero3.jpg
# (Debian package opencv-doc).
#   scripts/mosaic_aero.sh [--out DIR]        (default out/aero)
# 1. aero1 + aero3 as a two-frame sequence -> DIR/aero_mosaic.png (+ an 800 px
#    preview DIR/aero_mosaic_preview.png). The two oblique photos show one town
#    from different directions and distances: the nadir A-KAZE matcher finds
#    no consistent set (frame 2 LOST), so uav_mosaic_files falls back to the
#    affine-invariant RegisterOblique (ASIFT, MAGSAC++ homography, photometric
#    check) and mosaics aero3 into aero1's frame with multi-band blending.
# 2. Each photo cut into two overlapping views related by a known similarity
#    (12 deg, view 2 from 1.18x higher) -> registered, the measured scale
#    change compared with the truth, and mosaicked: DIR/aero1_split_mosaic.png,
#    DIR/aero3_split_mosaic.png (+ 480 px previews *_split_preview.png).
# Needs a build: $VLOC_BUILD_DIR (default build/) with target uav_mosaic_files.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${VLOC_BUILD_DIR:-$root/build}"
out="$root/out/aero"
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    *) echo "mosaic_aero.sh: unknown option $1 (use --out DIR)" >&2; exit 2 ;;
  esac
done
data=/usr/share/doc/opencv-doc/examples/data
tool="$build/bin/uav_mosaic_files"
for f in "$data/aero1.jpg" "$data/aero3.jpg"; do
  [ -f "$f" ] || { echo "mosaic_aero.sh: $f missing; install it with: sudo apt-get install opencv-doc" >&2; exit 1; }
done
if [ ! -x "$tool" ]; then
  echo "mosaic_aero.sh: $tool missing; build it: cmake --build $build --target uav_mosaic_files" >&2
  exit 1
fi
mkdir -p "$out"
export GLOG_minloglevel=1
echo "== aero1 + aero3 as a sequence"
status=0
"$tool" --out "$out/aero_mosaic.png" --preview "$out/aero_mosaic_preview.png" --preview-side 800 \
  "$data/aero1.jpg" "$data/aero3.jpg" || status=$?
[ "$status" -eq 2 ] && echo "(aero3 could not be registered to aero1: see the reason above)"
for img in aero1 aero3; do
  echo "== $img cut into two views with a known similarity"
  "$tool" --split --out "$out/${img}_split_mosaic.png" --preview "$out/${img}_split_preview.png" \
    --preview-side 480 "$data/$img.jpg"
done
echo "mosaics in $out"
