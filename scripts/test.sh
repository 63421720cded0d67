#!/usr/bin/env bash
# Sets up, builds and runs every test suite (GoogleTest through CTest).
#   scripts/test.sh [--sanitize]   --sanitize builds with AddressSanitizer and UBSan in build-asan/
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = "--sanitize" ]; then
  build_dir=build-asan
  # Warnings are not errors here: the sanitizers' instrumentation makes GCC 12 warn falsely
  # (-Wmaybe-uninitialized inside std::regex).
  STAMPSCAN_BUILD_TYPE=RelWithDebInfo scripts/setup.sh "$build_dir" -DSTAMPSCAN_SANITIZE=ON -DSTAMPSCAN_WERROR=OFF
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  export LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp"
else
  build_dir=build
  scripts/setup.sh "$build_dir"
fi
ctest --test-dir "$build_dir" --output-on-failure -j "$(nproc)" --timeout 900
