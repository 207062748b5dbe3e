#!/usr/bin/env bash
# Instructions per call of the flight interface (flight/ssiu_flight.h), counted by valgrind's
# callgrind: a count of executed instructions, the same on a loaded or a faster machine of the same
# architecture (unlike seconds), on the built-in default mission (two 512x512 heads, four FOGs at
# 100 Hz) replayed by examples/flight's demo.
#   bash bench/flight_instructions.sh [BUILD_DIR] [FRAMES]
# Prints instructions of the first frame set (lost in space on both heads), the mean of a tracking
# frame set, and of a gyro sample. docs/flight.md keeps the figures.
set -euo pipefail
build=${1:-build}
frames=${2:-30}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
"$build/ssiu" run --out "$dir/m" --write-frames >/dev/null
# Inclusive instructions of one function over a demo run of n frame sets.
count() {
  local fn=$1 n=$2
  valgrind --tool=callgrind --callgrind-out-file="$dir/cg" --toggle-collect="$fn" \
    "$build/ssiu-flight-demo" "$dir/m" --frames "$n" >"$dir/out" 2>/dev/null
  # awk reads to the end: stopping early would end callgrind_annotate with SIGPIPE (pipefail).
  callgrind_annotate "$dir/cg" 2>/dev/null | awk '/PROGRAM TOTALS/ && !n {gsub(",", "", $1); n = $1} END {print n}'
}
lis=$(count ssiu_flight_frames 1)
all=$(count ssiu_flight_frames "$frames")
gyro=$(count ssiu_flight_gyro "$frames")
samples=$(sed -n 's/.*, \([0-9]*\) gyro samples.*/\1/p' "$dir/out")
awk -v lis="$lis" -v all="$all" -v n="$frames" -v gyro="$gyro" -v s="$samples" 'BEGIN {
  printf "frame set, lost in space (first):  %.3g instructions\n", lis
  printf "frame set, tracking (mean of %d): %.3g instructions\n", n - 1, (all - lis) / (n - 1)
  printf "gyro sample (mean of %d):        %.3g instructions\n", s, gyro / s
}'
