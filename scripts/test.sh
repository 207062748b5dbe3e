#!/usr/bin/env bash
# Runs every test: set-up and build (warnings are errors), ctest; then the same tests built by clang
# under AddressSanitizer + UndefinedBehaviorSanitizer (with float-cast-overflow); then each libFuzzer
# harness (fuzz/) for a bounded time from its seed corpus. Idempotent; for a fresh Debian machine as root.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
bash scripts/setup.sh --all build
ctest --test-dir build --output-on-failure -j"$jobs" -LE long
# The sanitizer build also makes the fuzzers, so that the stages they call are compiled once for both (only
# those carry libFuzzer's coverage counters there: CMakeLists.txt, SSIU_FUZZ).
fuzz_in_asan=OFF
if [ "${SSIU_SKIP_ASAN:-0}" != "1" ] && [ "${SSIU_SKIP_FUZZ:-0}" != "1" ]; then
  fuzz_in_asan=ON
fi
if [ "${SSIU_SKIP_ASAN:-0}" != "1" ]; then
  # clang refuses a precompiled header built before a system header it read was replaced, even by an older
  # file (dpkg keeps the package's times, so ninja sees nothing newer): the ARM leg's multiarch packages can
  # update the host's own (linux-libc-dev), and the next run's sanitizer build failed. Such headers are built
  # again when dpkg has installed anything since.
  if [ -d build-asan ]; then
    find build-asan -name '*.pch' ! -newer /var/lib/dpkg/status -delete
  fi
  # clang: its UBSan also checks out-of-range double-to-int conversions (float-cast-overflow), which
  # GCC's lacks. -O1: sanitizer builds of the template-heavy files (FLANN, Eigen) compile faster. No debug
  # information: a report names the functions (symbol table) but not the lines; the line tables (-g1) cost
  # about a fifth more compile time (the inertial library's largest batch: 118 s against 97 s), so add
  # them when reproducing a finding (SSIU_ASAN_FLAGS="-O1 -g1"). The test programs at -O1 too (SSIU_TEST_OPT
  # empty): some compute their reference in their own code (sim_test's fusion scenarios), which ASan at -O0
  # made six times slower; the 469 tests took about 95 s longer, nearly what the compile saved.
  bash scripts/setup.sh --all build-asan -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=${SSIU_ASAN_FLAGS:--O1}" -DSSIU_TEST_OPT= \
    -DSSIU_SANITIZE=ON -DSSIU_FUZZ=$fuzz_in_asan -DSSIU_BUILD_BENCH=OFF -DSSIU_BUILD_LONGTESTS=OFF
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j"$jobs" -LE 'long|no_asan'
fi
if [ "${SSIU_SKIP_FUZZ:-0}" != "1" ]; then
  # clang + libFuzzer, ASan, UBSan and float-cast-overflow (which GCC lacks); only the readers' stages
  # and the flight interface are built. SSIU_FUZZ_SECONDS per harness (default 10 s; the 6 harnesses run nproc
  # at a time: three rounds on 2 cores).
  fuzz_build=build-asan
  if [ "$fuzz_in_asan" != "ON" ]; then
    fuzz_build=build-fuzz
    CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" -DSSIU_FUZZ=ON -DSSIU_BUILD_TESTS=OFF -DSSIU_BUILD_BENCH=OFF \
      -DSSIU_BUILD_LONGTESTS=OFF -DSSIU_WERROR=OFF >/dev/null
  fi
  cmake --build $fuzz_build -j"$jobs" --target fuzz_image fuzz_csv fuzz_json fuzz_centroids fuzz_flight fuzz_flight_cfg fuzz_adm
  # One harness a core at a time (each runs in one process), each one's output printed when it ends.
  fuzz() {
    local work rc
    work=$(mktemp -d)  # new inputs go here, the corpus in the repository stays as it is
    UBSAN_OPTIONS=halt_on_error=1 $fuzz_build/fuzz/fuzz_$1 -max_total_time="${SSIU_FUZZ_SECONDS:-10}" -timeout=10 \
      -rss_limit_mb=2048 -print_final_stats=1 "$work" fuzz/corpus/$1 >"$work.log" 2>&1 && rc=0 || rc=$?
    echo "== fuzz_$1 (exit $rc)"
    cat "$work.log"
    rm -rf "$work" "$work.log"
    return $rc
  }
  harnesses=(image csv json centroids flight flight_cfg adm)
  failed=""
  for ((i = 0; i < ${#harnesses[@]}; i += jobs)); do
    pids=()
    for h in "${harnesses[@]:i:jobs}"; do
      fuzz "$h" &
      pids+=("$!:$h")
    done
    for p in "${pids[@]}"; do
      wait "${p%%:*}" || failed="$failed fuzz_${p#*:}"
    done
  done
  if [ -n "$failed" ]; then
    echo "test.sh:$failed failed (output above)" >&2
    exit 1
  fi
fi
if [ "${SSIU_SKIP_CROSS:-0}" != "1" ]; then
  # The flight core built for aarch64 and its CI subset of tests run under qemu-user, plus the flight
  # demo's frame-by-frame comparison with x86-64 (scripts/cross-test.sh, docs/flight.md, "ARM").
  bash scripts/cross-test.sh aarch64 --ci
fi
