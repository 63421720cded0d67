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
          libzstd-dev liblz4-dev zlib1g-dev libopencv-dev libmodbus-dev mbpoll
          libcgal-demo nlohmann-json3-dev libusb-1.0-0-dev libumockdev-dev umockdev
          libtomlplusplus-dev libaravis-dev aravis-tools aravis-tools-cli iproute2 libcairo2-dev
          fonts-dejavu-core libsqlitecpp-dev libsqlite3-dev libpqxx-dev postgresql
          libcpp-httplib-dev libssl-dev libsodium-dev libjs-three libjs-chart.js chromium stress-ng nginx openssl
          systemd lintian
          libocct-foundation-dev libocct-modeling-data-dev libocct-modeling-algorithms-dev libocct-data-exchange-dev
          libembree-dev libfcl-dev)
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
  # nginx is the panel's TLS front (station hmi --front-config); the tests run their own. Debian
  # starts its default site on port 80 when installing it: stopped here, the integrator enables the
  # front with its site file.
  if [[ " ${missing[*]} " == *" nginx "* ]]; then
    $sudo systemctl disable --now nginx >/dev/null 2>&1 || $sudo service nginx stop >/dev/null 2>&1 || true
  fi
fi

# The MCAP interoperability test (tests/acquisition/test_mcap_interop.cpp) reads our traces with the
# reference reader, @mcap/core, under node; the npm packages are pinned in its package-lock.json.
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  echo "setup: installing nodejs npm"
  if [ "$(id -u)" -ne 0 ]; then sudo=sudo; else sudo=; fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends nodejs npm >/dev/null
fi
# The panel's browser test (tests/station/hmi/browser) drives Debian's chromium with puppeteer-core, pinned
# the same way. Each folder is installed again only when its lockfile is newer than its install.
for node_dir in tests/acquisition/interop tests/station/hmi/browser; do
  if [ ! -d "$node_dir/node_modules" ] || [ "$node_dir/package-lock.json" -nt "$node_dir/node_modules/.package-lock.json" ]; then
    echo "setup: npm ci in $node_dir"
    npm ci --prefix "$node_dir" --no-audit --no-fund --loglevel=error
  fi
done

# Warnings are errors in every build, so that `scripts/test.sh` after this finds the same
# configuration and builds nothing again.
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE="${STAMPSCAN_BUILD_TYPE:-Release}" -DSTAMPSCAN_WERROR=ON "$@" >/dev/null
cmake --build "$build_dir" -j "${STAMPSCAN_JOBS:-$(nproc)}"
