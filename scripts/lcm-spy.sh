#!/usr/bin/env bash
# Starts lcm-spy with vloc's message types (and jchart2d for its plots) on
# Java 17, where Debian's /usr/bin/lcm-spy does not start (-Xincgc).
#   scripts/lcm-spy.sh [LCM_URL] [BUILD_DIR]
# URL default: $LCM_DEFAULT_URL, else vloc's default with a receive buffer
# large enough for images.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
url="${1:-${LCM_DEFAULT_URL:-udpm://239.255.76.67:7667?ttl=0&recv_buf_size=33554432}}"
build="${2:-${VLOC_BUILD_DIR:-$root/build}}"
jar="$build/vloc_lcmtypes.jar"
if [ ! -f "$jar" ]; then
  echo "lcm-spy.sh: $jar not found; build first (scripts/test.sh or cmake --build $build --target vloc_lcmtypes_jar)" >&2
  exit 1
fi
case "$url" in
  udpm://*recv_buf_size*) ;;
  udpm://*\?*) url="$url&recv_buf_size=33554432" ;;
  udpm://*) url="$url?recv_buf_size=33554432" ;;
esac
cp="/usr/share/java/lcm.jar:$jar"
for j in /usr/share/java/jchart2d.jar; do [ -f "$j" ] && cp="$cp:$j"; done
if [ "${VLOC_SPY_CHECK:-0}" = "1" ]; then
  # Headless: list which vloc types lcm-spy's class-path scan finds.
  classes=$(unzip -Z1 "$jar" | grep -E '^vloc/[a-z_]+_t\.class$' | sed 's/\.class$//; s#/#.#g')
  exec java -Djava.awt.headless=true -cp "$cp:$build/java_check" SpyTypeCheck $classes
fi
exec java -Djava.net.preferIPv4Stack=true -Xmx512m -cp "$cp" lcm.spy.Spy --lcm-url="$url"
