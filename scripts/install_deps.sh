#!/usr/bin/env bash
# Installs every Debian 12 package vloc needs; skips what is already there.
# Used by scripts/test.sh and scripts/demo.sh. Safe to run repeatedly.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config git ccache   # ccache: rebuilds of a new clone hit the cache (CMakeLists.txt)
  liblcm-dev liblcm-bin liblcm-java libglib2.0-dev
  libeigen3-dev libopencv-dev opencv-doc
  libceres-dev libsuitesparse-dev libgoogle-glog-dev libgflags-dev
  libmrpt-graphslam-dev libmrpt-graphs-dev libmrpt-poses-dev mrpt-common
  libyaml-cpp-dev
  googletest libgtest-dev libgmock-dev libbenchmark-dev
  default-jdk-headless libjchart2d-java
  python3-numpy python3-matplotlib python3-opencv   # python3-opencv: scripts/coop_eval.py
  libzip-dev python3-skimage   # scikit-image ships Middlebury 2014 Motorcycle (stereo with sub-pixel truth)
  libexiv2-dev exiv2 libgdal-dev gdal-bin
  iproute2 procps nftables
  libwebsocketpp-dev libasio-dev nlohmann-json3-dev chromium chromium-driver   # vloc_console and its browser test
  libzmq3-dev cppzmq-dev   # vloc_lcm_tunnel: LCM buses joined over a reliable link (ZeroMQ)
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "[deps] all ${#PACKAGES[@]} packages present"
else
  echo "[deps] installing: ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# Transport: images over LCM need a large socket receive buffer, and LCM needs a
# multicast route. Both need root; without it we say what to run instead.
if [ "$(id -u)" -eq 0 ]; then
  cur=$(sysctl -n net.core.rmem_max 2>/dev/null || echo 0)
  if [ "$cur" -lt 33554432 ]; then
    sysctl -q -w net.core.rmem_max=33554432 || echo "[deps] could not raise net.core.rmem_max (container?)"
  fi
  routes=$(ip route show table all 2>/dev/null || true)   # (grep -q on a pipe would SIGPIPE ip under pipefail)
  if ! grep -q "224.0.0.0/4" <<<"$routes"; then
    ip route add 224.0.0.0/4 dev lo 2>/dev/null || echo "[deps] could not add multicast route (container?)"
  fi
else
  echo "[deps] not root: run 'sudo sysctl -w net.core.rmem_max=33554432' and 'sudo ip route add 224.0.0.0/4 dev lo' if LCM images drop or LCM cannot start"
fi
