#!/usr/bin/env bash
# Re-measures the headline table of docs/results.md (the rows that fit in a few minutes on 2 cores)
# and prints it beside the figures the page states:
#   scripts/results.sh [--list] [--only REGEX] [BUILD_DIR]      (BUILD_DIR default: build)
# Assumes the Release build with the long tests
#   cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DSSIU_BUILD_LONGTESTS=ON && ninja -C build
# and the real data in $SSIU_SHARED_DIR (default: ../shared beside the repository).
#   --list        print each row and the command it runs (nothing is run); exit 1 when a program
#                 a row needs is not in BUILD_DIR
#   --only REGEX  run only the rows whose capability matches REGEX (grep -E)
#   --keep DIR    keep each row's output there (N.txt, N the row's place in the printed table)
# Rows are run one after another; some run a reduced size of the page's command, which the printed
# command shows. Rows too long for the budget are printed as skipped with their full command.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
LIST=0
ONLY=""
KEEP=""
BUILD=build
while [ $# -gt 0 ]; do
  case "$1" in
    --list) LIST=1 ;;
    --only) ONLY=$2; shift ;;
    --keep) KEEP=$2; shift ;;
    -h | --help) sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "scripts/results.sh: unknown option $1 (see --help)" >&2; exit 1 ;;
    *) BUILD=$1 ;;
  esac
  shift
done
if [ ! -d "$BUILD" ]; then
  echo "scripts/results.sh: no build directory $BUILD (cmake -S . -B $BUILD -G Ninja -DCMAKE_BUILD_TYPE=Release -DSSIU_BUILD_LONGTESTS=ON && ninja -C $BUILD)" >&2
  exit 1
fi
B=$(cd "$BUILD" && pwd)
[ -z "$KEEP" ] || { mkdir -p "$KEEP" && KEEP=$(cd "$KEEP" && pwd); }
export SSIU_SHARED_DIR=${SSIU_SHARED_DIR:-$(cd "$ROOT/.." && pwd)/shared}

# row CAPABILITY COMMAND PARSER: COMMAND is run with bash in a scratch directory, $B the build
# directory; PARSER (a function of the Python below) reads its output and prints the figure.
# skip CAPABILITY MINUTES COMMAND: too long for the budget, printed with its command.
ROWS=()
row() { ROWS+=("run"$'\t'"$1"$'\t'"$2"$'\t'"$3"); }
skip() { ROWS+=("skip"$'\t'"$1"$'\t'"$3"$'\t'"$2"); }

row "detection, simulated frames" \
  "\$B/tests/sim/sim_test --gtest_filter='FrameDetect.*' --gtest_output=json:g.json" detect_sim
row "detection, real frames" \
  "\$B/tests/detect/detect_test --gtest_filter='RealFrames.*' --gtest_output=json:g.json" detect_real
row "detection speed" \
  "taskset -c 1 \$B/bench/detect_bench --benchmark_filter=BM_Detect1024 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true --benchmark_format=json" \
  detect_speed
row "lost in space, ESA false-star scenes" \
  "\$B/bench/identify_bench --benchmark_filter='BM_EsaScenes/0/0/0/0/-1/-1/1/' --benchmark_format=json" esa
row "lost in space, simulated 16.6-deg frames" \
  "\$B/bench/identify_bench --benchmark_filter=BM_LostInSpaceFromCentroids --benchmark_format=json" lis_sim
row "tracking update" \
  "\$B/bench/identify_memory_bench --benchmark_filter='BM_Identify/1/1' --benchmark_format=json" tracking
row "unknown field of view 8-25 deg" \
  "UFOV_FRAMES=1000 \$B/tests/identify/identify_longtest --gtest_filter='UnknownFovLong.Frames*'" ufov
row "false-match calibration" \
  "LIS_TRIALS=1000 \$B/tests/sim/sim_longtest --gtest_filter='LostInSpaceLong.CalibrationRandomCentroids:LostInSpaceLong.CalibrationWrongFocalLength'; UFOV_TRIALS=1000 \$B/tests/identify/identify_longtest --gtest_filter='UnknownFovLong.Calibration*'; LIS_TRIALS=1000 LIS_ALPHA=1e-4 \$B/tests/sim/sim_longtest --gtest_filter='LostInSpaceLong.CalibrationStarFreeFrames'" \
  false_match
row "attitude, 1000 simulated frames" "\$B/tests/attitude/attitude_longtest" attitude
row "focal length refined by default" \
  "ctest --test-dir \$B -R 'RefineFocal|RefinePrincipal|GranasatPrincipal|OpenStarTrackerNominal' -V" focal
row "fusion, bias estimate" \
  "\$B/tests/sim/sim_longtest --gtest_filter='GyroFusionMonteCarlo.FiftyOneHourSlewsTurnOnBiasAndArw'" fusion
row "FDI, 48 gyro faults" "\$B/tests/sim/sim_longtest --gtest_filter='GyroFaultSweep.*'" fdi
row "unit processor (\`ssiu run\`)" "\$B/ssiu run --json run.json" run
row "FOG thermal drift" \
  "for s in 1 2 3; do \$B/ssiu simulate fog-thermal --seed \$s --out run\$s.csv; done && \$B/ssiu fog thermal run1.csv run2.csv --holdout run3.csv --json model.json && \$B/ssiu fog compensate run3.csv --model model.json --out run3_comp.csv --json comp.json" \
  fog_thermal
row "FOG unit calibration" "\$B/tests/calibration/calibration_longtest --gtest_filter='FogUnitLong.*'" fog_unit
row "in-flight unit calibration" "\$B/tests/sim/sim_longtest --gtest_filter='UnitInflightLong.*'" inflight
row "Allan analysis" \
  "\$B/tests/calibration/calibration_longtest --gtest_filter='AllanMonteCarlo.ArwAndRrwAcceptanceAndSigmaCalibration'" allan
# Their run times as measured for docs/discrepancy.md: DiscoverGyroLong* 16-82 min for the telegraph oracle
# (82 on one core shared with other jobs), 20 for the residual test's power and about 60 in all; DiscoverGyroMultiLong.TwoCauses* three
# 60-case draws of 10-13 min each.
skip "discovery, gyro logs" "about 60" "\$B/tests/discover/discover_longtest --gtest_filter='DiscoverGyroLong*'"
skip "discovery, two causes in a gyro log" "30-40" \
  "\$B/tests/discover/discover_longtest --gtest_filter='DiscoverGyroMultiLong.TwoCauses*'"
row "discovery, frames" \
  "\$B/tests/discover/discover_longtest --gtest_filter='DiscoverFramesLong.SeveralEffectsTogether'" discover_frames
row "ground test, virtual stand" \
  "\$B/tests/groundtest/groundtest_longtest --gtest_filter='GroundtestMonteCarlo.MisalignmentRecoveryCoverage'" groundtest
row "ECSS performance report" \
  "\$B/tests/groundtest/groundtest_test --gtest_filter='Performance.*Recovered*'" performance
row "CCSDS ADM" "ctest --test-dir \$B -R 'AdmSamples|AdmSchemas' -V" adm
row "frame to quaternion" \
  "taskset -c 1 \$B/bench/solve_bench --benchmark_filter=FrameToQuaternion --benchmark_format=json" frame_to_quat
row "single-frame process" \
  "\$B/ssiu catalog build --fov-deg 16.6 --out cat && \$B/ssiu simulate frame --random --seed 100 --out f1 && perf stat -r 20 -e task-clock \$B/ssiu solve f1/frame_0000.png --camera f1/camera.json --catalog cat --json one.json && perf stat -r 20 -e task-clock \$B/ssiu --help && taskset -c 1 \$B/bench/catalog_bench --benchmark_filter=Stored --benchmark_repetitions=10 --benchmark_report_aggregates_only=true --benchmark_format=json" \
  single_frame
row "flight core" \
  "\$B/bench/flight_memory_bench --benchmark_format=json; \$B/bench/mission_bench --benchmark_filter='BM_FlightFrameSetTracking' --benchmark_format=json" \
  flight
row "robustness" "ctest --test-dir \$B -R FlightAllocation -V" robustness

# The programs a command names ($B/...; ctest's tests are the build's).
programs() { grep -oE '\$B/[A-Za-z0-9_/.-]+' <<<"$1" | sed "s|^\\\$B/||" | sort -u; }

missing=()
for r in "${ROWS[@]}"; do
  IFS=$'\t' read -r kind cap cmd _ <<<"$r"
  for p in $(programs "$cmd"); do
    [ -x "$B/$p" ] || [[ " ${missing[*]} " == *" $BUILD/$p "* ]] || missing+=("$BUILD/$p")
  done
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "scripts/results.sh: not built: ${missing[*]} (cmake -S . -B $BUILD -G Ninja -DCMAKE_BUILD_TYPE=Release -DSSIU_BUILD_LONGTESTS=ON && ninja -C $BUILD)" >&2
  exit 1
fi

if [ "$LIST" = 1 ]; then
  for r in "${ROWS[@]}"; do
    IFS=$'\t' read -r kind cap cmd extra <<<"$r"
    shown=${cmd//\$B/$BUILD}
    if [ "$kind" = skip ]; then echo "$cap | skipped ($extra min) | $shown"; else echo "$cap | $shown"; fi
  done
  exit 0
fi

WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cat >"$WORK/parse.py" <<'PY'
# parse.py PARSER OUTPUT: the figure of one row from its command's output (the scratch directory is
# the working directory, for the files the command wrote). parse.py table DOC RESULTS: the table.
import json
import re
import sys


def gtest_properties(path="g.json"):
    props = {}
    for suite in json.load(open(path))["testsuites"]:
        for t in suite["testsuite"]:
            props.update({k: v for k, v in t.items() if k not in ("name", "status", "result", "timestamp", "time",
                                                                     "classname", "failures", "file", "line")})
    return props


def benchmarks(text):
    """Every benchmark of the Google Benchmark JSON documents in text."""
    out, dec, i = [], json.JSONDecoder(), 0
    while True:
        i = text.find("{", i)
        if i < 0:
            return out
        try:
            doc, end = dec.raw_decode(text, i)
        except ValueError:
            i += 1
            continue
        if isinstance(doc, dict) and "benchmarks" in doc:
            out += doc["benchmarks"]
        i = end


def bench(text, name):
    return next(b for b in benchmarks(text) if re.search(name, b["name"]))


def find(pattern, text, last=False):
    m = re.findall(pattern, text, re.M)
    if not m:
        raise SystemExit(f"no line matching {pattern!r}")
    return m[-1] if last else m[0]


def detect_sim(out):
    p = gtest_properties()
    return (f"recall {100 * float(p['recall']):.1f}% of SNR >= 10 stars, {p['false_detections']} false, "
            f"centroid RMS / Cramer-Rao {float(p['crb_ratio']):.2f}")


def detect_real(out):
    p = gtest_properties()
    return f"{p['recall']} astrometry.net stars within 1 px ({p['deep_recall']} with a deep search)"


def detect_speed(out):
    t = [b["cpu_time"] for b in benchmarks(out) if b.get("aggregate_name") == "median"]
    return f"{min(t):.3g}-{max(t):.3g} ms CPU per frame (seeds 1-3, median of 3)"


def esa(out):
    c = bench(out, "BM_EsaScenes")
    return (f"{c['solved_4plus']:.0f}/{c['scenes_4plus']:.0f} with >= 4 stars solved "
            f"({100 * c['solved_4plus'] / c['scenes_4plus']:.1f}%), {c['wrong']:.0f} wrong; "
            f"median {c['median_cpu_ms']:.2f} ms, p99 {c['p99_cpu_ms']:.1f} ms CPU")


def lis_sim(out):
    c = bench(out, "BM_LostInSpaceFromCentroids")
    n = c["iterations"]
    return (f"{c['solved_frac'] * n:.0f}/{n} solved, {c['wrong']:.0f} wrong, median {c['median_cpu_ms']:.2f} ms CPU, "
            f"p99 {c['p99_cpu_ms']:.2f} ms")


def tracking(out):
    c = bench(out, "BM_Identify/1/1")
    return (f"{1e3 / c['items_per_second']:.3f} ms CPU per update (workspace, {c['allocs_per_call']:.0f} allocations; "
            f"{c['solved_frac'] * 100:.0f}% matched)")


def ufov(out):
    n, v, s, pct, w, mx = find(r"(\d+) frames of 10-20 deg, stars to V ([\d.]+): (\d+) solved \(([\d.]+)%\), (\d+) wrong"
                               r".*? max ([\d.]+) %", out)
    return f"{s}/{n} solved ({pct}%), {w} wrong, focal length within {mx}% (stars to V {v}; {n} frames)"


def false_match(out):
    r = dict(re.findall(r"^random centroids at ([\de.-]+): (\d+) false of \d+", out, re.M))
    t = dict(re.findall(r"^focal length 5-15 % wrong, tolerance 15 %, at ([\de.-]+): (\d+) wrong of", out, re.M))
    u = dict(re.findall(r"^unknown FOV 8-25 deg, random centroids at ([\de.-]+): (\d+) false of", out, re.M))
    f = find(r"^star-free frames at 0.0001: (\d+) false of", out)
    n = find(r"random centroids at [\de.-]+: \d+ false of (\d+)", out)
    return (f"at 1e-4: random sets {r['0.0001']}, tolerance mode {t['0.0001']}, unknown FOV {u['0.0001']}, star-free "
            f"frames {f} of {n} each (at 1e-3: {r['0.001']}, {t['0.001']}, {u['0.001']})")


def attitude(out):
    s, n, w, e, nees, lo, hi = find(r"solved (\d+)/(\d+), wrong (\d+), median cross error at 16.6 deg ([\d.]+) arcsec"
                                    r".*?mean NEES ([\d.]+) \(95% bounds ([\d.]+)\.\.([\d.]+)\)", out)
    return f"{s}/{n} solved, {w} wrong, median boresight error {e} arcsec at 16.6 deg, mean NEES {nees} (bounds {lo}..{hi})"


def focal(out):
    ost_refined, ost_n = find(r"focal length refined in (\d+) of (\d+) frames", out)
    err = [float(x) for x in re.findall(r"img[02346]\.png: \d+ stars, f [\d.]+ \+- [\d.]+ px \(p [^)]*\), ([\d.]+) arcsec",
                                        out)]
    pp_t, pp_r, pp_w = find(r"principal point 30 px off: tested (\d+), refined (\d+), within 3 sigma (\d+)", out)
    rc_t, rc_r = find(r"right camera: tested (\d+), refined (\d+)", out)
    g_r, g_n, g_w = find(r"principal point refined in (\d+) of (\d+) frames, within 3 sigma of the calibration's (\d+)",
                         out)
    return (f"openstartracker {ost_refined}/{ost_n} refined; cross-boresight {min(err):.1f}-{max(err):.1f} arcsec from "
            f"astrometry.net; principal point: 30 px off found {pp_r}/{pp_t} (within 3 sigma {pp_w}/{pp_r}), right camera "
            f"kept {int(rc_t) - int(rc_r)}/{rc_t}, GranaSAT single frames within 3 sigma of `ssiu calibrate`'s "
            f"{g_w}/{g_r} ({g_r} of {g_n} refined)")


def fusion(out):
    ax = re.findall(r"axis \d: bias RMS ([\d.]+) deg/h, Cramer-Rao bound ([\d.]+) deg/h, ratio ([\d.]+)", out)
    return (f"bias RMS {' / '.join(a[0] for a in ax)} deg/h at 30 min = {' / '.join(a[2] for a in ax)} x Cramer-Rao "
            f"({ax[0][1]})")


def fdi(out):
    shares = [(float(s), n.strip()) for n, s in re.findall(r"^(.+?)\s+trustworthy\s+([\d.]+)%", out, re.M)]
    cases, bad = find(r"(\d+) cases, (\d+) below their bound or not isolated", out)
    low = min(shares)
    return (f"{cases} faults, {bad} not isolated on the right gyro or below their bound; lowest trustworthy share "
            f"{low[0]:.2f}% ({low[1]})")


def run(out):
    j = json.load(open("run.json"))
    heads = ", ".join(f"{h['solved']}/{h['frames']}" for h in j["heads"])
    e = j["fused_error"]
    return (f"{j['frames_solved']}/{j['frames']} frame sets (heads {heads}), fused cross RMS "
            f"{e['cross_rms_arcsec']:.2f} arcsec, NEES {e['nees_mean']:.2f}, status {j['status']}")


def fog_thermal(out):
    c = json.load(open("comp.json"))
    return (f"held-out run {c['drift_before_dph']['peak']:.3f} -> {c['drift_after_dph']['peak']:.3f} deg/h "
            f"(gain {c['gain']:.1f})")


def fog_unit(out):
    w = find(r"(\d+/\d+) parameters within 3 sigma", out)
    n, c = find(r"RMS outage error nominal ([\d.]+) arcsec, calibrated ([\d.]+) arcsec", out)
    return f"parameters within 3 sigma {w}; outage error {n} -> {c} arcsec"


def inflight(out):
    w = find(r"(\d+/\d+) within 3 sigma", out)
    n, c = find(r"outage error RMS nominal ([\d.]+) arcsec, calibrated ([\d.]+)", out)
    ow = find(r"online: (\d+/\d+) within 3 sigma", out)
    on, oc = find(r"outage error RMS without ([\d.]+) arcsec, with ([\d.]+)", out)
    return (f"within 3 sigma {w}; outage error {float(n):.0f} -> {float(c):.0f} arcsec ({float(n) / float(c):.0f}x); "
            f"processor: within 3 sigma {ow}, outage error {float(on):.0f} -> {float(oc):.0f} arcsec "
            f"({float(on) / float(oc):.1f}x)")


def allan(out):
    m, s, w = find(r"ARW: mean ratio ([\d.]+), scatter ([\d.]+), .*?within 10%: (\d+/\d+)", out)
    return f"ARW estimate / truth {m} (scatter {s}), {w} within 10%"


def discover_frames(out):
    sets, alln, wrong = find(r"(\d+) sets: all injected named (\d+), .*?a cause not injected (\d+)", out)
    return f"several causes: every injected cause named {alln}/{sets}, a cause not injected {wrong}/{sets}"


def groundtest(out):
    w, z = find(r"misalignment: (\d+/\d+) axes within 3 sigma, z-score RMS ([\d.]+)", out)
    return f"{w} misalignment axes within 3 sigma, z-score RMS {z}"


def performance(out):
    alone = "recovered within 10%" if re.search(r"\[\s+OK \] Performance.EachContributionAlone", out) else "FAILED"
    t, f = find(r"^\s+bias\s+[-\d.]+\s+[-\d.]+\s+([-\d.]+)\s+[-\d.]+\s+[-\d.]+\s+([-\d.]+)\s*$", out, last=True)
    return f"each contribution injected alone {alone}; all together, bias roll {f} against {t} arcsec"


def adm(out):
    r, f = find(r"samples: (\d+) read, (\d+) refused", out)
    tests = find(r"tests passed, (\d+) tests failed out of (\d+)", out)
    return (f"{r} quaternion histories of {int(r) + int(f)} sample messages read, {f} refused with file, line, keyword; "
            f"{int(tests[1]) - int(tests[0])}/{tests[1]} tests passed")


def frame_to_quat(out):
    png, fits = bench(out, "fits:0"), bench(out, "fits:1")
    return f"{png['median_cpu_ms']:.2f} ms CPU (PNG), {fits['median_cpu_ms']:.2f} ms (FITS)"


def single_frame(out):
    t = re.findall(r"([\d.,]+) msec task-clock", out)
    load = next(b for b in benchmarks(out) if b.get("aggregate_name") == "median")
    return (f"`ssiu solve frame.png` {float(t[0].replace(',', '')):.1f} ms CPU; `ssiu --help` "
            f"{float(t[1].replace(',', '')):.1f} ms; catalog load {load['cpu_time']:.2f} ms")


def flight(out):
    mem = [b for b in benchmarks(out) if "init_heap_bytes" in b]
    init = [b["init_heap_bytes"] / 1e6 for b in mem]
    frame = max(b["frame_heap_bytes"] for b in mem)
    trk = bench(out, "BM_FlightFrameSetTracking")
    return (f"{frame:.0f} heap bytes per frame set after init; heap at init {min(init):.2f}-{max(init):.2f} MB; "
            f"{trk['cpu_time']:.2f} ms per tracking frame set")


def robustness(out):
    fs, fa, gs, ga, sr, sa, ex = find(r"flight calls after init: (\d+) frame sets \((\d+) allocations.*?(\d+) gyro samples "
                                      r"\((\d+),.*?(\d+) state reads \((\d+),.*?exceptions (\d+)", out)
    allocs = int(fa) + int(ga) + int(sa)
    return (f"{allocs} allocations and {ex} exceptions after init ({fs} frame sets, {gs} gyro samples, {sr} state reads); "
            f"fuzzing (30 min per harness) and ARM (`scripts/cross-test.sh`) not run")


def cell(s):
    return s.replace("|", "\\|").replace("\n", " ")


def table(doc, results):
    rows = {}
    lines = open(doc).read().split("## Headline table", 1)[1].split("\n## ", 1)[0].splitlines()
    for line in lines:
        if line.startswith("| ") and not line.startswith("| capability"):
            c = [x.strip() for x in re.split(r"(?<!\\)\|", line)[1:-1]]
            rows[c[0]] = c
    print("| capability | measured now | in docs/results.md | target | command |")
    print("|---|---|---|---|---|")
    for line in open(results).read().splitlines():
        cap, figure, command = line.split("\t")
        d = rows.get(cap, [cap, "(no such row)", "", "", ""])
        print(f"| {cap} | {cell(figure)} | {d[1]} ({d[4]}) | {d[2]} | {cell(command) or d[3]} |")


if __name__ == "__main__":
    if sys.argv[1] == "table":
        table(sys.argv[2], sys.argv[3])
    else:
        print(globals()[sys.argv[1]](open(sys.argv[2], errors="replace").read()))
PY

RESULTS=$WORK/results.tsv
: >"$RESULTS"
t_start=$(date +%s)
for r in "${ROWS[@]}"; do
  IFS=$'\t' read -r kind cap cmd extra <<<"$r"
  if [ -n "$ONLY" ] && ! grep -qE "$ONLY" <<<"$cap"; then continue; fi
  shown=${cmd//\$B/$BUILD}
  if [ "$kind" = skip ]; then
    printf '%s\t%s\t%s\n' "$cap" "skipped ($extra min; run: \`$shown\`)" "" >>"$RESULTS"
    continue
  fi
  dir=$WORK/row$(wc -l <"$RESULTS")
  mkdir -p "$dir"
  printf '%s ... ' "$cap" >&2
  t0=$(date +%s)
  status=0
  (cd "$dir" && B="$B" bash -c "set -o pipefail; $cmd") >"$dir/out.txt" 2>"$dir/err.txt" </dev/null || status=$?
  cat "$dir/err.txt" >>"$dir/out.txt"  # after the output, not inside a JSON document
  secs=$(($(date +%s) - t0))
  if ! figure=$(cd "$dir" && python3 "$WORK/parse.py" "$extra" out.txt 2>&1); then
    figure="no figure in the output ($(tail -1 <<<"$figure"))"
  fi
  if [ "$status" != 0 ]; then
    figure="$figure (exit status $status)"
  elif grep -q '^\[  FAILED  \]' "$dir/out.txt"; then
    figure="$figure (a test failed)"
  fi
  echo "${secs} s" >&2
  printf '%s\t%s\t%s\n' "$cap" "$figure" "\`$shown\` (${secs} s)" >>"$RESULTS"
  [ -z "$KEEP" ] || cp "$dir/out.txt" "$KEEP/$(wc -l <"$RESULTS").txt"
done
python3 "$WORK/parse.py" table "$ROOT/docs/results.md" "$RESULTS"
echo
echo "Measured $(date -u +%Y-%m-%d) in $(($(date +%s) - t_start)) s of wall time ($(nproc) cores)."
