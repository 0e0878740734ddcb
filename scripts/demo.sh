#!/usr/bin/env bash
# vloc's main job, on a fresh Debian 12 machine:
#   installs what is missing, builds, runs the simulated rover traverse
#   (group rover_sim) and the simulated UAV flight (group uav_sim) through
#   vloc_launch over real LCM, records both runs, evaluates them against
#   their ground truth, prints the accuracy and writes plots and the mosaic.
#
#   scripts/demo.sh [--sites N] [--flight-seconds S] [--profile default|hard|extreme] [--seed S] [--out DIR]
#
# A second run reinstalls and rebuilds nothing.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${VLOC_BUILD_DIR:-$root/build}"
out="$root/out/demo"
sites=12
flight_s=70
profile=default   # rover simulator profile: config/procs/sim_rover.yaml, or sim_rover_<profile>.yaml
seed=-1          # traverse seed (-1 = the profile's)
while [ $# -gt 0 ]; do
  case "$1" in
    --sites) sites="$2"; shift 2 ;;
    --profile) profile="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --flight-seconds) flight_s="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    *) echo "demo.sh: unknown option $1 (use --sites N, --flight-seconds S, --profile NAME, --seed S, --out DIR)" >&2; exit 2 ;;
  esac
done
t0=$(date +%s)
say() { printf '[demo %4ds] %s\n' "$(( $(date +%s) - t0 ))" "$*"; }

say "checking packages"
bash "$root/scripts/install_deps.sh"
if [ ! -f "$build/CMakeCache.txt" ]; then
  say "configuring $build"
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DVLOC_ONLY_DIRS= -DVLOC_CCACHE=ON >/dev/null
fi
say "building (incremental)"
cmake --build "$build" -j "$(nproc)" 2>&1 | grep -vE '^\[ *[0-9]+%\] (Built target|Building|Linking)' || true
for exe in vloc_launch sim_rover dead_reckoning feature_frontend crosssite_ba traverse_graph sim_uav uav_mosaicker vloc_eval; do
  [ -x "$build/bin/$exe" ] || { echo "demo.sh: $build/bin/$exe was not built; see the build output above" >&2; exit 1; }
done
build_done=$(date +%s)

rm -rf "$out"; mkdir -p "$out/rover" "$out/uav"
export VLOC_BIN="$build/bin" VLOC_ROOT="$root"
# A port of its own so the demo neither hears nor disturbs other LCM traffic.
export VLOC_LCM_URL="udpm://239.255.76.67:7950?ttl=0&recv_buf_size=33554432"

# Runs one group until its simulator ends, printing progress: the newest
# line matching $4 in process log $3. $1 group, $2 log dir.
run_group() {
  local group="$1" dir="$2" log="$3" pattern="$4" last=""
  "$build/bin/vloc_launch" --config "$root/config/groups/$group.yaml" --log-dir "$dir" \
      --lcm-url "$VLOC_LCM_URL" --exit-when-done > "$dir/vloc_launch.out" 2>&1 &
  local pid=$!
  while kill -0 "$pid" 2>/dev/null; do
    sleep 3
    local line
    line=$(grep -hoE "$pattern" "$dir/$log" 2>/dev/null | tail -n 1 || true)
    if [ -n "$line" ] && [ "$line" != "$last" ]; then say "$group: $line"; last="$line"; fi
  done
  if ! wait "$pid"; then
    echo "demo.sh: group $group failed; process logs in $dir" >&2
    tail -n 20 "$dir/vloc_launch.out" >&2
    exit 1
  fi
}

sim_config=config/procs/sim_rover.yaml
[ "$profile" = default ] || sim_config="config/procs/sim_rover_$profile.yaml"
[ -f "$root/$sim_config" ] || { echo "demo.sh: no profile '$profile' ($sim_config)" >&2; exit 2; }
say "rover_sim: $sites sites, profile $profile (simulator, dead reckoning, front end, BA, pose graph, logger)"
VLOC_SIM_CONFIG="$sim_config" VLOC_SIM_SITES="$sites" VLOC_SIM_SEED="$seed" run_group rover_sim "$out/rover" feature_frontend.log \
  "sites [0-9]+ -> [0-9]+: front end: [a-z ]+, [0-9]+ tie points in [0-9.]+ s"
say "uav_sim: ${flight_s} s flight (simulator, mosaicker, logger)"
VLOC_SIM_UAV_SECONDS="$flight_s" run_group uav_sim "$out/uav" uav_mosaicker.log \
  "height [0-9.]+ m, route [-0-9.]+, [-0-9.]+ m; frames [0-9]+"

say "evaluating against ground truth"
"$build/bin/vloc_eval" "$out/rover/rover_sim.lcmlog" --out "$out/rover/eval" --terrain "$root/config/sim/terrain.yaml" \
    --navcam "$root/config/navcam.yaml"
"$build/bin/vloc_eval" "$out/uav/uav_sim.lcmlog" --out "$out/uav/eval"

echo
echo "== rover: $sites sites =="
cat "$out/rover/eval/summary.md" 2>/dev/null || true
echo
echo "== UAV: ${flight_s} s flight =="
cat "$out/uav/eval/summary.md" 2>/dev/null || true
echo
say "done: run took $(( $(date +%s) - build_done )) s after the build"
echo "plots:  $(ls "$out"/rover/eval/*.png "$out"/uav/eval/*.png 2>/dev/null | tr '\n' ' ')"
echo "mosaic: $out/uav/uav_mosaic.png (world file uav_mosaic.pgw)"
echo "logs:   $out/rover/rover_sim.lcmlog $out/uav/uav_sim.lcmlog (replay: lcm-logplayer --lcm-url=URL FILE)"
