#!/usr/bin/env bash
# Saves sample renderings of the simulated worlds as PNG in out/samples/.
#   scripts/render_samples.sh            (build directory: $VLOC_BUILD_DIR or build/)
# Each helper appends one block below: build its target, write its PNG.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${VLOC_BUILD_DIR:-$root/build}"
out="$root/out/samples"
mkdir -p "$out"
cd "$root"
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
fi
build_target() { cmake --build "$build" --target "$1" -j "$(nproc)" >/dev/null; }

# --- simulated UAV: a nadir frame at t = 30 s (about 60 m up: fields, trees, a road
# with cars), and the calibration hover over the 1 m ArUco marker at 15 m (t = 1 s).
build_target sim_uav
"$build/bin/sim_uav" --config config/procs/sim_uav.yaml --snapshot "$out/uav_frame.png" --at 30
"$build/bin/sim_uav" --config config/procs/sim_uav.yaml --snapshot "$out/uav_calibration.png" --at 1
echo "wrote $out/uav_frame.png $out/uav_calibration.png"

# --- simulated rover: the middle Navcam pair of site 0 (pan 0, tilt 25 deg, 1024 x 1024)
# -> navcam_left.png, navcam_right.png, plus terrain_ortho.png (40 m x 40 m around it).
build_target sim_rover
"$build/bin/sim_rover" --config config/procs/sim_rover.yaml --render-sample "$out"
