#!/usr/bin/env bash
# Builds the flight core (stages core, detect, identify, attitude, inertial, flight), its tests and the
# flight demo for an ARM target with Debian's cross compilers, runs the tests under qemu-user, and, when
# examples/flight exists, checks that the demo gives the x86-64 answers frame by frame.
# Usage: scripts/cross-test.sh aarch64|armhf [--ci] [--no-install]
#   --ci          run the CI subset of the tests (CI_EXCLUDE below)
#   --no-install  do not check/install the cross packages (they must be there)
# Installs what it needs (as root, idempotent: a second run only asks dpkg). Exits non-zero on any failure.
# Environment: SSIU_CROSS_BUILD_DIR (default build-<arch>), SSIU_NATIVE_BUILD_DIR (default build).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)

ARCH=${1:-}
shift || true
CI_SUBSET=0
INSTALL=1
for a in "$@"; do
  case "$a" in
    --ci) CI_SUBSET=1 ;;
    --no-install) INSTALL=0 ;;
    *) echo "cross-test: unknown argument '$a'" >&2; exit 2 ;;
  esac
done
case "$ARCH" in
  aarch64) DEB_ARCH=arm64; TRIPLET=aarch64-linux-gnu; SSIU_CROSS_QEMU_BIN=qemu-aarch64 ;;
  armhf) DEB_ARCH=armhf; TRIPLET=arm-linux-gnueabihf; SSIU_CROSS_QEMU_BIN=qemu-arm ;;
  *) echo "usage: scripts/cross-test.sh aarch64|armhf [--ci] [--no-install]" >&2; exit 2 ;;
esac
BUILD=${SSIU_CROSS_BUILD_DIR:-build-$ARCH}
NATIVE=${SSIU_NATIVE_BUILD_DIR:-build}
JOBS=$(nproc)
now() { date +%s; }
T0=$(now)

# --- packages ---------------------------------------------------------------------------------------
# Host side: the cross compilers, qemu-user, the build tools and the architecture-independent headers
# (Eigen, nlohmann-json; FLANN's headers from the host's libflann-dev: FLANN is used header-only in the
# cross build, because libflann-dev is not co-installable for two architectures: its
# /usr/lib/cmake/flann files name the architecture's library path, and it pulls in libhdf5-mpi-dev).
HOST_PKGS="cmake ninja-build pkg-config python3 qemu-user gcc-$TRIPLET g++-$TRIPLET libeigen3-dev nlohmann-json3-dev libflann-dev"
# Target side: the runtime the programs run with under qemu (cmake/toolchain-common.cmake says why not
# the cross toolchain's own) and the multiarch -dev packages of everything the flight stages and their
# tests link or load.
TARGET_PKGS="libc6 libstdc++6 libgtest-dev libgmock-dev libpng-dev libdeflate-dev liberfa-dev libcfitsio-dev libtiff-dev liblz4-dev"
installed() { [ "$(dpkg-query -W -f='${Status}' "$1" 2>/dev/null)" = "install ok installed" ]; }
# When the target's packages cannot be installed beside the host's (multiarch needs the same version of
# a library for every architecture, and the target's index can lag the host's: e.g. the armhf
# bookworm-security index failing to download while amd64 has the security updates installed), they
# are unpacked, with what they depend on, into a sysroot in the build directory instead: the compiler
# and pkg-config look there (cmake/toolchain-common.cmake, SSIU_CROSS_SYSROOT) and qemu runs with it as
# its root (-L).
SYSROOT="$ROOT/$BUILD/sysroot"
sysroot_ready() { [ -f "$SYSROOT/.complete" ] && [ "$(cat "$SYSROOT/.complete")" = "$TARGET_PKGS" ]; }
make_sysroot() {
  echo "cross-test: unpacking the $DEB_ARCH packages and what they depend on into $SYSROOT"
  local deb_dir="$ROOT/$BUILD/sysroot-debs" names=()
  rm -rf "$SYSROOT" "$deb_dir"
  mkdir -p "$SYSROOT" "$deb_dir"
  local p
  for p in $TARGET_PKGS; do names+=("$p:$DEB_ARCH"); done
  # The target's packages apt would install (the closure also names virtual packages, <name>, other
  # architectures' alternatives and architecture-independent packages, which nothing here needs), each in
  # the version this index has.
  mapfile -t closure < <(apt-cache depends --recurse --no-recommends --no-suggests --no-conflicts --no-breaks \
    --no-replaces --no-enhances "${names[@]}" | grep -v '^[ <]' | grep ":$DEB_ARCH\$" | sort -u)
  (cd "$deb_dir" && apt-get download -qq "${closure[@]}" >/dev/null)
  for d in "$deb_dir"/*.deb; do dpkg-deb -x "$d" "$SYSROOT"; done
  rm -rf "$deb_dir"
  echo "$TARGET_PKGS" >"$SYSROOT/.complete"
}
USE_SYSROOT=0
if [ "$INSTALL" = 1 ]; then
  missing=""
  for p in $HOST_PKGS; do installed "$p" || missing="$missing $p"; done
  target_missing=""
  for p in $TARGET_PKGS; do installed "$p:$DEB_ARCH" || target_missing="$target_missing $p:$DEB_ARCH"; done
  if [ -n "$missing$target_missing" ] && ! { [ -z "$missing" ] && sysroot_ready; }; then
    echo "cross-test: installing$missing$target_missing"
    if [ "$(id -u)" != 0 ]; then
      echo "cross-test: packages missing and not root: run as root (apt-get install$missing$target_missing)" >&2
      exit 1
    fi
    if ! dpkg --print-foreign-architectures | grep -qx "$DEB_ARCH"; then
      dpkg --add-architecture "$DEB_ARCH"
    fi
    export DEBIAN_FRONTEND=noninteractive
    # A mirror in the middle of a sync fails one index now and then: try again, then go on with the
    # lists there are (the install below says clearly if something is really missing).
    apt-get update -qq || { sleep 10; apt-get update -qq; } || echo "cross-test: apt-get update failed; going on" >&2
    # --no-remove: a target package whose version differs from the host's must never make apt remove a
    # host package (with -y it would, to resolve the conflict); it fails instead and the sysroot serves.
    if [ -n "$missing" ]; then
      apt-get install -y -qq --no-remove --no-install-recommends $missing >/dev/null
    fi
    if [ -n "$target_missing" ] && ! apt-get install -y -qq --no-remove --no-install-recommends $target_missing >/dev/null 2>&1; then
      echo "cross-test: the $DEB_ARCH packages cannot be installed beside the host's (versions differ between" \
        "the architectures' indexes): a sysroot instead"
      make_sysroot
    fi
  fi
fi
# A sysroot made by this or an earlier run is used while the multiarch packages are not all installed.
for p in $TARGET_PKGS; do
  if ! installed "$p:$DEB_ARCH"; then
    sysroot_ready || { echo "cross-test: $p:$DEB_ARCH not installed and no sysroot (run without --no-install)" >&2; exit 1; }
    USE_SYSROOT=1
    break
  fi
done
QEMU=("$SSIU_CROSS_QEMU_BIN")
sysroot_arg=()
if [ "$USE_SYSROOT" = 1 ]; then
  QEMU+=(-L "$SYSROOT")
  sysroot_arg=(-DSSIU_CROSS_SYSROOT="$SYSROOT")
fi
T_INSTALL=$(( $(now) - T0 ))
echo "cross-test: $ARCH packages ready (${T_INSTALL} s)"

# --- build -------------------------------------------------------------------------------------------
T1=$(now)
launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
# The test programs with the build's flags (SSIU_TEST_OPT empty): under qemu, their own code at -O0 cost the
# aarch64 tests about 130 CPU-s more than it saved in compiling them (90 s).
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_TOOLCHAIN_FILE="$ROOT/cmake/toolchain-$ARCH.cmake" \
  -DSSIU_FLIGHT_ONLY=ON -DSSIU_TEST_OPT= "${sysroot_arg[@]}" "${launcher[@]}" >/dev/null
cmake --build "$BUILD" -j"$JOBS"
T_BUILD=$(( $(now) - T1 ))
echo "cross-test: $ARCH build (${T_BUILD} s)"

# --- tests under qemu-user (CMAKE_CROSSCOMPILING_EMULATOR of the toolchain file) ----------------------
T2=$(now)
# --ci leaves out the slowest statistical tests (each 15-60 s of emulated time, about half of the whole
# run): what they check does not depend on the processor beyond what the rest checks.
CI_EXCLUDE='^(SimulatedFrames\.FiftyRandomFramesSolvedCorrectly|UnknownFov\.ChanceProbabilityIsCalibratedOnRandomCentroids|Calibrate\..*|MultiHeadFrames\..*|RealFrames\.DeepSearchFindsTheFaintAstrometryNetStars|RealFrames\.OpenStarTrackerWithinTenArcsecOfAstrometryNet|RealFrames\.OpenStarTrackerNominalFocalLengthIsRefinedByDefault|SkyMotion\.NonSquarePixelsDistortionProperMotionAndAberrationTogether|PixelAspect\.CrossBoresightErrorAcrossAspects)$'
select=()
if [ "$CI_SUBSET" = 1 ]; then
  select=(-E "$CI_EXCLUDE")
fi
# The tests' catalog cache: the target's own, so that its catalogs are built (and checked) on the target.
export SSIU_CATALOG_DIR="$ROOT/$BUILD/catalog-cache"
ctest --test-dir "$BUILD" --output-on-failure -j"$JOBS" "${select[@]}"
T_TEST=$(( $(now) - T2 ))
echo "cross-test: $ARCH tests under qemu (${T_TEST} s)"

# --- the flight demo on the default mission: the same answers as x86-64 -------------------------------
# Per frame set (--csv: t_s,status,heads_solved,head<k>_status,head<k>_matches,...,qw,qx,qy,qz) the
# statuses, solved heads and matched-star counts must be equal and the attitudes agree within 0.001 arcsec.
T3=$(now)
DEMO_NOTE="skipped"
if [ ! -f examples/flight/CMakeLists.txt ]; then
  echo "cross-test: examples/flight does not exist yet: the demo comparison is skipped"
else
  arm_demo=$(find "$BUILD" -type f -name ssiu-flight-demo -perm -u+x | head -n1)
  [ -n "$arm_demo" ] || { echo "cross-test: $BUILD has no ssiu-flight-demo" >&2; exit 1; }
  # The x86-64 build: configured as scripts/setup.sh does when absent, and only these two targets built.
  if [ ! -f "$NATIVE/build.ninja" ]; then
    cmake -S . -B "$NATIVE" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
  fi
  cmake --build "$NATIVE" -j"$JOBS" --target ssiu ssiu-flight-demo
  native_demo=$(find "$NATIVE" -type f -name ssiu-flight-demo -perm -u+x | head -n1)
  work="$BUILD/demo-check"
  rm -rf "$work"
  mkdir -p "$work"
  "$NATIVE/ssiu" run --out "$work/mission" --write-frames >"$work/run.log" 2>&1 ||
    { cat "$work/run.log" >&2; echo "cross-test: ssiu run --write-frames failed" >&2; exit 1; }
  "$native_demo" "$work/mission" --csv "$work/x86_64.csv" --json "$work/x86_64.json" >"$work/x86_64.log" 2>&1 ||
    { cat "$work/x86_64.log" >&2; echo "cross-test: the x86-64 demo failed" >&2; exit 1; }
  "${QEMU[@]}" "$arm_demo" "$work/mission" --csv "$work/$ARCH.csv" \
    --json "$work/$ARCH.json" >"$work/$ARCH.log" 2>&1 ||
    { cat "$work/$ARCH.log" >&2; echo "cross-test: the $ARCH demo failed" >&2; exit 1; }
  python3 - "$work/x86_64.csv" "$work/$ARCH.csv" "$ARCH" <<'PY'
import csv, math, sys

def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))

ref, arm, arch = rows(sys.argv[1]), rows(sys.argv[2]), sys.argv[3]
TOL_ARCSEC = 0.001
if not ref:
    sys.exit("cross-test: the x86-64 demo wrote no frame set")
if len(ref) != len(arm):
    sys.exit(f"cross-test: {len(ref)} frame sets on x86-64, {len(arm)} on {arch}")
exact = [c for c in ref[0] if c in ("status", "heads_solved") or c.endswith("_status") or c.endswith("_matches")]
quat = ["qw", "qx", "qy", "qz"]
for c in ["t_s"] + exact + quat:
    if c not in ref[0] or c not in arm[0]:
        sys.exit(f"cross-test: column {c} missing")

def q(row):
    try:
        v = [float(row[c]) for c in quat]
    except ValueError:
        return None
    return v if all(math.isfinite(x) for x in v) else None

bad, worst = 0, 0.0
for i, (a, b) in enumerate(zip(ref, arm)):
    msgs = []
    if float(a["t_s"]) != float(b["t_s"]):
        msgs.append(f"t_s {a['t_s']} vs {b['t_s']}")
    msgs += [f"{c} {a[c]} vs {b[c]}" for c in exact if a[c] != b[c]]
    qa, qb = q(a), q(b)
    if (qa is None) != (qb is None):
        msgs.append("attitude present on one side only")
    elif qa is not None:
        # Angle of conj(qa) * qb: 2 atan2(|vector part|, |scalar part|) (exact for small angles).
        w1, x1, y1, z1 = qa
        w2, x2, y2, z2 = qb
        w = w1 * w2 + x1 * x2 + y1 * y2 + z1 * z2
        x = w1 * x2 - w2 * x1 - (y1 * z2 - z1 * y2)
        y = w1 * y2 - w2 * y1 - (z1 * x2 - x1 * z2)
        z = w1 * z2 - w2 * z1 - (x1 * y2 - y1 * x2)
        err = math.degrees(2 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w))) * 3600
        worst = max(worst, err)
        if err > TOL_ARCSEC:
            msgs.append(f"attitudes differ by {err:.6f} arcsec")
    if msgs:
        bad += 1
        if bad <= 10:
            print(f"cross-test: frame set {i} (t_s {a['t_s']}): " + "; ".join(msgs))
print(f"cross-test: demo on {len(ref)} frame sets: {bad} differ from x86-64; "
      f"largest attitude difference {worst:.3g} arcsec (tolerance {TOL_ARCSEC})")
sys.exit(1 if bad else 0)
PY
  DEMO_NOTE="passed"
fi
T_DEMO=$(( $(now) - T3 ))

echo "cross-test: $ARCH passed: packages ${T_INSTALL} s, build ${T_BUILD} s, tests ${T_TEST} s, demo ${T_DEMO} s ($DEMO_NOTE)"
