#!/usr/bin/env bash
# The front end on the simulated 10 m test pair under the hard profile's
# photometry and camera effects, for a grid of sun elevations and sun moves
# between the sites (issue 16: 0-90 deg of azimuth, elevation down to 10 deg).
# Prints one row per case: status, tie points, wrong (> 2 px from the truth).
#   scripts/frontend_sun_sweep.sh [ELEVATIONS] [AZIMUTH_STEPS]   (defaults "30 20 10" "0 30 60 90")
# Renders are cached in $VLOC_SIM_CACHE (default /tmp/vloc_sun_sweep).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${VLOC_BUILD_DIR:-$root/build}"
elevations="${1:-30 20 10}"
steps="${2:-0 30 60 90}"
cache="${VLOC_SIM_CACHE:-/tmp/vloc_sun_sweep}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$cache"
cd "$root"
[ -x "$build/tests/crosssite_frontend_sim_test" ] || { echo "frontend_sun_sweep: build crosssite_frontend_sim_test first" >&2; exit 1; }
echo "| sun elevation | sun moves (azimuth) | status | tie points | wrong (> 2 px) |"
echo "|---|---|---|---|---|"
for e in $elevations; do
  for a in $steps; do
    profile="$work/sun_e${e}_a${a}.yaml"
    printf 'include: %s\nterrain:\n  sun_elevation_deg: %s\nlighting:\n  azimuth_step_deg: %s\n' \
      "$root/config/procs/sim_rover_hard.yaml" "$e" "$a" > "$profile"
    out="$(VLOC_SIM_CACHE="$cache" VLOC_TEST_SIM_PROFILE="$profile" \
      "$build/tests/crosssite_frontend_sim_test" --gtest_filter='FrontendSim.SitePairMeets*' 2>&1 || true)"
    status="$(grep -o 'front end: [a-z ]*' <<<"$out" | head -1 | sed 's/front end: //')"
    points="$(grep -o '^tie points [0-9][0-9]*' <<<"$out" | head -1 | grep -o '[0-9]*$' || echo 0)"
    wrong="$(grep -o 'wrong [0-9][0-9]*' <<<"$out" | head -1 | grep -o '[0-9]*$' || echo -)"
    echo "| $e deg | $a deg | ${status:-?} | ${points:-0} | ${wrong:-—} |"
  done
done
