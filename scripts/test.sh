#!/usr/bin/env bash
# Installs what is missing, configures, builds and runs every test.
#   scripts/test.sh [ctest args...]      e.g. scripts/test.sh -L unit
# Build directory: $VLOC_BUILD_DIR or build/.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${VLOC_BUILD_DIR:-$root/build}"
jobs="$(nproc)"
start=$(date +%s)

bash "$root/scripts/install_deps.sh"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DVLOC_ONLY_DIRS= >/dev/null
echo "[test] building in $build with $jobs jobs"
cmake --build "$build" -j "$jobs"
echo "[test] built in $(( $(date +%s) - start )) s; running tests"
cd "$build"
ctest --output-on-failure -j "$jobs" --timeout 600 "$@"
echo "[test] all passed in $(( $(date +%s) - start )) s"
