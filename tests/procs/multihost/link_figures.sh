#!/usr/bin/env bash
# Figures for a group split across machines (issue 18), measured on two
# network namespaces joined by a veth pair (MTU 1500), as multihost_proc_test
# builds them: image-sized LCM messages at 10 per second (one stereo pair of
# two 1 MB images = 2 MB) from the "vehicle" to the "ground" at 0, 0.1, 1
# and 5 % packet loss, and with ttl=0 instead of ttl=1. Needs root.
#
#   tests/procs/multihost/link_figures.sh [BUILD_DIR] [COUNT]
#
# Loss: tc netem where the kernel has it, else an nftables random drop of
# frames at each end's ingress (IP fragments, as a radio loses them).
set -euo pipefail
build="${1:-build}"
count="${2:-100}"
probe="$build/bin/vloc_lcm_probe"
[ -x "$probe" ] || { echo "link_figures.sh: $probe not built (cmake --build $build --target vloc_lcm_probe)" >&2; exit 1; }
[ "$(id -u)" = 0 ] || { echo "link_figures.sh: needs root for ip netns" >&2; exit 1; }
V=lfig_v G=lfig_g
cleanup() { ip netns del $V 2>/dev/null || true; ip netns del $G 2>/dev/null || true; }
trap cleanup EXIT
cleanup
ip netns add $V; ip netns add $G
ip link add lfig-v type veth peer name lfig-g
ip link set lfig-v netns $V; ip link set lfig-g netns $G
ip -n $V addr add 10.219.0.1/24 dev lfig-v; ip -n $G addr add 10.219.0.2/24 dev lfig-g
for nd in $V:lfig-v $G:lfig-g; do
  ns=${nd%%:*}; dev=${nd##*:}
  ip -n "$ns" link set lo up
  ip -n "$ns" link set "$dev" up multicast on
  ip -n "$ns" route add 224.0.0.0/4 dev "$dev"
done

loss_kind=""
set_loss() {  # percent
  for nd in $V:lfig-v:10.219.0.2 $G:lfig-g:10.219.0.1; do
    ns=${nd%%:*}; rest=${nd#*:}; dev=${rest%%:*}; peer=${rest#*:}
    ip netns exec "$ns" tc qdisc del dev "$dev" root 2>/dev/null || true
    ip netns exec "$ns" nft delete table netdev vloc_loss 2>/dev/null || true
    [ "$1" = 0 ] && continue
    if ip netns exec "$ns" tc qdisc add dev "$dev" root netem loss "$1%" delay 20ms 2>/dev/null; then
      loss_kind="tc netem loss $1% delay 20ms"
    else
      per_mille=$(awk -v p="$1" 'BEGIN { printf "%d", p * 10 + 0.5 }')
      printf 'table netdev vloc_loss {\n chain ingress {\n  type filter hook ingress device %s priority 0;\n  ip saddr %s numgen random mod 1000 < %d counter drop\n }\n}\n' \
        "$dev" "$peer" "$per_mille" | ip netns exec "$ns" nft -f -
      loss_kind="nftables drop of $1% of the frames from the other end at ingress (own looped-back multicast spared; no sch_netem in this kernel)"
    fi
  done
}

run() {  # url size rate
  local rx
  rx=$(mktemp)
  ip netns exec $G "$probe" receive --count "$count" --timeout $(( count / 10 + 8 )) --lcm-url "$1" >"$rx" 2>/dev/null &
  local pid=$!
  sleep 1
  ip netns exec $V "$probe" send --count "$count" --size "$2" --rate "$3" --lcm-url "$1" >/dev/null 2>&1
  wait $pid || true
  awk '/^received:/ { r = $2 } /^lost:/ { l = $2 } END { printf "%s received, %s lost", r, l }' "$rx"
  rm -f "$rx"
}

url1="udpm://239.255.76.67:7991?ttl=1&recv_buf_size=33554432"
url0="udpm://239.255.76.67:7992?ttl=0&recv_buf_size=33554432"
echo "| link | message | rate | result |"
echo "|---|---|---|---|"
echo "| clean, ttl=0 | 2 MB | 10/s | $(run "$url0" 2000000 10) of $count |"
for loss in 0 0.1 1 5; do
  set_loss "$loss"
  # Fragments of a lost datagram fill the reassembly buffer for
  # net.ipv4.ipfrag_time (30 s): let it drain between measurements.
  ip netns exec $G sysctl -qw net.ipv4.ipfrag_time=1
  sleep 2
  echo "| ${loss} % loss | 2 MB (stereo pair) | 10/s | $(run "$url1" 2000000 10) of $count |"
  echo "| ${loss} % loss | 10 kB | 10/s | $(run "$url1" 10000 10) of $count |"
  echo "| ${loss} % loss | 500 B (pose, status) | 100/s | $(run "$url1" 500 100) of $count |"
done
echo
echo "loss applied with: ${loss_kind:-none}"
