#!/bin/sh
# Batch vs one process per frame (issue 17): `ssiu solve` of the 50-frame simulated set as one batch
# (--threads 0 = all cores) and as 50 processes run one after another, as a shell loop would.
#   bench/batch_bench.sh [BUILD_DIR] [WORK_DIR]      (defaults: build, a fresh temporary directory)
# Prints the wall and CPU seconds of both and their ratio; figures in docs/results.md.
set -eu
BUILD=$(cd "${1:-build}" && pwd)
WORK=${2:-$(mktemp -d)}
SSIU="$BUILD/ssiu"
cd "$WORK"
[ -d cat ] || "$SSIU" catalog build --fov-deg 16.6 --out cat >/dev/null 2>&1
[ -d f50 ] || "$SSIU" simulate frame --random --seed 100 --count 50 --out f50 >/dev/null 2>&1
# wall and CPU (user + sys of the command and its children) seconds of a shell command
timed() {
  python3 - "$1" <<'PY'
import os, subprocess, sys, time
t0 = time.monotonic()
subprocess.run(sys.argv[1], shell=True, check=True, stderr=subprocess.DEVNULL)
wall = time.monotonic() - t0
c = os.times()
print(f"{wall:.3f} {c.children_user + c.children_system:.3f}")
PY
}
# warm the file cache once, then time each way
"$SSIU" solve f50/*.png --camera f50/camera.json --catalog cat --jsonl batch.jsonl 2>/dev/null
B=$(timed "'$SSIU' solve f50/*.png --camera f50/camera.json --catalog cat --jsonl batch.jsonl")
P=$(timed "for f in f50/*.png; do '$SSIU' solve \$f --camera f50/camera.json --catalog cat --json one.json; done")
echo "batch (1 process):   wall $(echo $B | cut -d' ' -f1) s, cpu $(echo $B | cut -d' ' -f2) s"
echo "50 processes:        wall $(echo $P | cut -d' ' -f1) s, cpu $(echo $P | cut -d' ' -f2) s"
python3 -c "import sys; b, p = [list(map(float, s.split())) for s in sys.argv[1:]]; print(f'speed-up: wall {p[0]/b[0]:.1f}x, cpu {p[1]/b[1]:.1f}x')" "$B" "$P"
