#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs every Debian 12 package scanmesh needs to build, test and run its demo.
# Idempotent: packages already present are left alone. Run as root (or via sudo).
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake ninja-build ccache pkg-config clang libclang-rt-14-dev
  # geometry core, CLI, tests
  libeigen3-dev catch2 nlohmann-json3-dev libcli11-dev
  # the bulk's planar Delaunay triangulation (header-only; GMP/MPFR for its exact predicates)
  libcgal-dev libgmp-dev libmpfr-dev
  # images (preview and deviation pictures): only the OpenCV modules we link; PNG via libpng
  libopencv-core-dev libopencv-imgproc-dev libpng-dev
  # camera + line-laser profiler (drivers/profiler): chessboards, image files, cameras
  libopencv-calib3d-dev libopencv-imgcodecs-dev libopencv-videoio-dev
  # device layer and daemon
  libboost-dev libboost-system-dev libmodbus-dev libserialport-dev libusb-1.0-0-dev
  libsystemd-dev systemd libtomlplusplus-dev libsqlite3-dev
  # scan journal: CRC-32 of its chunks (ISA-L's folding CRC; zlib to combine CRCs)
  zlib1g-dev libisal-dev
  # benchmarks only: Embree, to compare the simulator's own BVH against (bench/bench_bvh)
  libembree-dev
)

# The journal tests' independent MCAP reader (@mcap/core from the npm registry, installed by
# tests/journal/mcap-reader/install.sh) runs on Debian's Node.js. A machine whose Node.js already
# brings npm (NodeSource's nodejs conflicts with Debian's npm) keeps it.
if ! command -v npm >/dev/null 2>&1; then
  PACKAGES+=(nodejs npm)
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages already installed"
  exit 0
fi

echo "setup: installing ${missing[*]}"
if [ "$(id -u)" -eq 0 ]; then
  SUDO=()
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  SUDO=(sudo -n)
else
  echo "setup: these Debian packages are missing and I am not root: ${missing[*]}" >&2
  echo "setup: run 'sudo scripts/setup.sh' (or apt-get install -y them) and try again" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -qq
"${SUDO[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup: done"
