#!/usr/bin/env bash
# The cooperative run (issue 20): the simulated UAV flies over the rover's area first and its
# mosaic is the rover's map. Both halves run through vloc_launch over real LCM:
#   1. vloc_render_map: the rover simulator's terrain from above under the map's sun (azimuth 60,
#      elevation 50), 5 cm/px, as the UAV simulator's ground (world frame = rover site 0's, ENU)
#   2. group uav_coop: sim_uav (lawnmower at 40 m, RTK GPS 5 cm) + uav_mosaicker (GPS-tied mosaic,
#      10 cm/px, PNG + lon/lat world file, rewritten every 10 s) + logger
#   3. group rover_coop: the rover pipeline (Navcam under the rover's sun, azimuth 135, elevation 30)
#      with map_localizer on that mosaic + logger
#   4. vloc_eval on the rover log, scripts/coop_eval.py: fixes vs truth, the mosaic's georeferencing
#      error (mosaic vs the rendered orthomap), the picture of the traverse over the mosaic
#
#   scripts/coop_demo.sh [--sites N] [--out DIR] [--flight-seconds S] [--uav-only] [--together]
# VLOC_UAV_GPS_SIGMA=M sets the UAV's horizontal GPS sigma (0.05 m, RTK; 1.5 = consumer GNSS);
# --uav-only stops after the mosaic and its georeferencing error. --together runs both groups at
# once (each on its own LCM bus, the map passing through the mosaic file as it is rewritten): the
# UAV still flying while the rover drives, on the same 2 cores.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${VLOC_BUILD_DIR:-$root/build}"
out="$root/out/coop"
sites=11
flight_s=0
uav_only=0
together=0
while [ $# -gt 0 ]; do
  case "$1" in
    --sites) sites="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --flight-seconds) flight_s="$2"; shift 2 ;;
    --uav-only) uav_only=1; shift ;;
    --together) together=1; shift ;;
    *) echo "coop_demo.sh: unknown option $1 (use --sites N, --out DIR, --flight-seconds S, --uav-only, --together)" >&2
       exit 2 ;;
  esac
done
for exe in vloc_launch vloc_render_map sim_uav uav_mosaicker sim_rover dead_reckoning feature_frontend crosssite_ba \
           traverse_graph map_localizer vloc_logger vloc_eval; do
  [ -x "$build/bin/$exe" ] || { echo "coop_demo.sh: $build/bin/$exe missing: cmake --build build" >&2; exit 1; }
done
t0=$(date +%s)
say() { printf '[coop %4ds] %s\n' "$(( $(date +%s) - t0 ))" "$*"; }
rm -rf "$out"; mkdir -p "$out"
out="$(cd "$out" && pwd)"
export VLOC_BIN="$build/bin" VLOC_ROOT="$root"
export VLOC_LCM_URL="${VLOC_LCM_URL:-udpm://239.255.76.67:7951?ttl=0&recv_buf_size=33554432}"

run_group() {  # $1 group [$2 LCM URL]; extra environment from the caller
  say "group $1"
  if ! "$build/bin/vloc_launch" --config "$root/config/groups/$1.yaml" --log-dir "$out" \
       --lcm-url "${2:-$VLOC_LCM_URL}" --exit-when-done > "$out/vloc_launch_$1.out" 2>&1; then
    echo "coop_demo.sh: group $1 failed; process logs in $out" >&2
    tail -n 20 "$out/vloc_launch_$1.out" >&2
    exit 1
  fi
}

say "rendering the UAV's ground (the rover terrain under the map's sun)"
"$build/bin/vloc_render_map" --config "$root/config/procs/sim_rover.yaml" --out "$out/coop_orthomap.png" \
  --res 0.05 --sun-azimuth 60 --sun-elevation 50 --region -40,-100,80,40
if [ "$together" = 1 ]; then
  # The UAV on a bus of its own (its images stay out of the rover's log); map_localizer waits for
  # the first mosaic (wait_for_map_s) and re-reads it each time the mosaicker rewrites it.
  uav_url="${VLOC_LCM_URL/:7951/:7952}"
  VLOC_SIM_UAV_SECONDS="$flight_s" run_group uav_coop "$uav_url" &
  uav_pid=$!
  VLOC_SIM_SITES="$sites" run_group rover_coop
  wait "$uav_pid" || exit 1
else
  VLOC_SIM_UAV_SECONDS="$flight_s" run_group uav_coop
fi
[ -f "$out/uav_mosaic.pgw" ] || { echo "coop_demo.sh: the mosaic is not georeferenced (no $out/uav_mosaic.pgw)" >&2; exit 1; }
say "mosaic: $(grep -h 'mosaic written' "$out/uav_mosaicker.log" | tail -n 1 | sed 's/.*uav_mosaicker: mosaic written to //')"
if [ "$uav_only" = 1 ]; then
  /usr/bin/python3 "$root/scripts/coop_eval.py" --dir "$out"
  say "done (UAV only)"
  exit 0
fi
[ "$together" = 1 ] || VLOC_SIM_SITES="$sites" run_group rover_coop
say "map_localizer: $(grep -hE 'fixes, [0-9]+ sites without' "$out/map_localizer.log" | tail -n 1 | sed 's/.*map_localizer: //' | cut -c1-120)"
[ "$together" = 0 ] || say "map_localizer re-read the mosaic $(grep -c 'map reloaded' "$out/map_localizer.log" || true) times as the UAV flew"
"$build/bin/vloc_eval" "$out/rover_coop.lcmlog" --out "$out/eval" --quiet --no-plots > /dev/null
/usr/bin/python3 "$root/scripts/coop_eval.py" --dir "$out"
say "done"
