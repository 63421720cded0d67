#!/usr/bin/env bash
# Installs what StampScan needs from Debian's packages (idempotent) and builds it.
#   scripts/setup.sh [BUILD_DIR] [extra cmake options...]
# Environment: STAMPSCAN_BUILD_TYPE (default Release), STAMPSCAN_JOBS (default: all cores).
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${1:-build}
shift || true

packages=(build-essential cmake ninja-build pkg-config
          libeigen3-dev libnanoflann-dev libtbb-dev libcli11-dev libgtest-dev
          libzstd-dev liblz4-dev zlib1g-dev libopencv-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  if [ "$(id -u)" -ne 0 ]; then sudo=sudo; else sudo=; fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE="${STAMPSCAN_BUILD_TYPE:-Release}" "$@" >/dev/null
cmake --build "$build_dir" -j "${STAMPSCAN_JOBS:-$(nproc)}"
