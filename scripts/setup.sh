#!/usr/bin/env bash
# Idempotent set-up of a fresh Debian machine (run as root): packages, catalogs, build.
# Usage: scripts/setup.sh [--all] [build-dir] [cmake args...]
# Without --all (the README's first command): the packages that configure and build ssiu, and only the
# `ssiu` program built (not the modules it loads on use, libssiu_tools.so with the tool commands and
# libssiu_opencv.so, which draws; docs/design.md "The program"). With --all (scripts/test.sh): also
# the test tools (clang, valgrind, pytest, dask, xmllint), every target built (tests, benchmarks, Python
# module) and the Python module installed. Both configure the build directory the same way, so either
# builds on what the other built and neither reconfigures it.
set -euo pipefail
cd "$(dirname "$0")/.."
all=0
if [ "${1:-}" = "--all" ]; then
  all=1
  shift
fi
PKGS="build-essential cmake ninja-build pkg-config libopencv-dev libpng-dev libtiff-dev libturbojpeg0-dev libeigen3-dev libflann-dev \
libapriltag-dev libboost-dev libcfitsio-dev libdeflate-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev nlohmann-json3-dev liberfa-dev xplanet \
python3-dev python3-pybind11"
if [ "$all" = 1 ]; then
  PKGS="$PKGS python3-numpy python3-pytest python3-dask python3-distributed clang libclang-rt-dev valgrind libxml2-utils"
fi
missing=""
# With foreign architectures added (scripts/cross-test.sh), a name installed for both is ambiguous to
# dpkg: ask for the native one then.
native=$(dpkg --print-architecture)
for p in $PKGS; do
  dpkg -s "$p" >/dev/null 2>&1 || dpkg -s "$p:$native" >/dev/null 2>&1 || missing="$missing $p"
done
if [ -n "$missing" ]; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends $missing >/dev/null
fi
# Hipparcos/Tycho star catalog: only stars.dat out of kstars-data (the package itself pulls in Qt).
if [ ! -s /usr/share/kstars/stars.dat ]; then
  tmp=$(mktemp -d)
  (cd "$tmp" && apt-get download -qq kstars-data >/dev/null 2>&1 && dpkg-deb -x kstars-data_*.deb x)
  install -D -m 644 "$tmp/x/usr/share/kstars/stars.dat" /usr/share/kstars/stars.dat
  rm -rf "$tmp"
fi
BUILD=${1:-build}; shift || true
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
if [ "$all" = 1 ]; then
  cmake --build "$BUILD" -j"$(nproc)"
  # The Python module (docs/python.md) into Debian's python3, when this build made it (not the sanitizer build).
  if ls "$BUILD"/python/ssiu/_ssiu*.so >/dev/null 2>&1; then
    cmake --install "$BUILD" --component python >/dev/null
  fi
else
  cmake --build "$BUILD" -j"$(nproc)" --target ssiu
fi
