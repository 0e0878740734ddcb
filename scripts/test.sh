#!/usr/bin/env bash
# Installs what is missing, configures, builds and runs every test.
#   scripts/test.sh [ctest args...]      e.g. scripts/test.sh -L unit
# Build directory: $VLOC_BUILD_DIR or build/.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${VLOC_BUILD_DIR:-$root/build}"
jobs="$(nproc)"
start=$(date +%s)

phase=$start
# Prints how long the phase that just ended took.
lap() { local now; now=$(date +%s); echo "[test] $1: $(( now - phase )) s"; phase=$now; }

bash "$root/scripts/install_deps.sh"
lap "packages"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DVLOC_ONLY_DIRS= -DVLOC_CCACHE=ON >/dev/null
lap "configure"
echo "[test] building in $build with $jobs jobs"
if command -v ccache >/dev/null; then ccache --zero-stats >/dev/null 2>&1 || true; fi
cmake --build "$build" -j "$jobs"
lap "build"
if command -v ccache >/dev/null; then ccache --show-stats 2>/dev/null | grep -iE "hits|misses" | head -3 | sed 's/^/[test] ccache: /' || true; fi
cd "$build"
ctest --output-on-failure -j "$jobs" --timeout 600 "$@"
lap "tests"
echo "[test] all passed in $(( $(date +%s) - start )) s"
