#!/usr/bin/env bash
# Re-runs the cross-site BA on the tie points of a recorded rover run, with
# another crosssite_ba config, and evaluates the result against the log's
# ground truth: what a BA setting changes, without matching again.
#   scripts/replay_ba.sh LOG.lcmlog OUT_DIR [crosssite_ba.yaml] [speed]
# Plays TIE_POINTS, SITE_POSE_DR and SITE_POSE_GT of LOG on a private port
# (lcm-logplayer) into crosssite_ba, records them with its SITE_POSE_VISUAL
# (vloc_logger) and runs vloc_eval on that into OUT_DIR/eval.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${VLOC_BUILD:-$root/build}"
[ $# -ge 2 ] || { echo "usage: scripts/replay_ba.sh LOG.lcmlog OUT_DIR [crosssite_ba.yaml] [speed]" >&2; exit 2; }
log="$1" out="$2" config="${3:-$root/config/procs/crosssite_ba.yaml}" speed="${4:-10}"
[ -f "$log" ] || { echo "replay_ba.sh: no log $log" >&2; exit 2; }
mkdir -p "$out"
url="udpm://239.255.76.67:7952?ttl=0&recv_buf_size=8388608"
channels="TIE_POINTS|SITE_POSE_DR|SITE_POSE_GT"
"$build/bin/vloc_logger" --out "$out/replay.lcmlog" --channels "$channels|SITE_POSE_VISUAL" --lcm-url "$url" \
    > "$out/logger.log" 2>&1 &
logger=$!
(cd "$root" && exec "$build/bin/crosssite_ba" --config "$config" --lcm-url "$url" --state-dir "$out") \
    > "$out/crosssite_ba.log" 2>&1 &
ba=$!
trap 'kill $logger $ba 2>/dev/null || true' EXIT
sleep 1
lcm-logplayer --speed "$speed" --regexp "^($channels)\$" --lcm-url "$url" "$log"
sleep 2
kill -INT $ba $logger; wait $ba $logger 2>/dev/null || true
trap - EXIT
"$build/bin/vloc_eval" "$out/replay.lcmlog" --out "$out/eval" --terrain "$root/config/sim/terrain.yaml" \
    --navcam "$root/config/navcam.yaml" --no-plots --quiet
