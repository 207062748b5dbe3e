#!/usr/bin/env bash
# Runs every test: set-up and build (warnings are errors), ctest; then the same tests under
# AddressSanitizer + UndefinedBehaviorSanitizer. Idempotent; for a fresh Debian machine as root.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
bash scripts/setup.sh build
ctest --test-dir build --output-on-failure -j"$jobs" -LE long
if [ "${SSIU_SKIP_ASAN:-0}" != "1" ]; then
  # -O1 -g1: sanitizer builds of the template-heavy files (FLANN, Eigen) compile several times faster.
  bash scripts/setup.sh build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" \
    -DSSIU_SANITIZE=ON -DSSIU_BUILD_BENCH=OFF -DSSIU_BUILD_LONGTESTS=OFF
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j"$jobs" -LE 'long|no_asan'
fi
