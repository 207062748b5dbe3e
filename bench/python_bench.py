"""Python call overhead and throughput (docs/results.md, issue 17).

    PYTHONPATH=build/python SSIU_BINARY_DIR=build python3 bench/python_bench.py [WORKDIR]

Overhead: a call whose work is nil (an empty centroid list -> too_few_stars) through Solver.solve and
through ssiu.solve (which also looks up its cached Solver), against the same solve of a real frame
through the CLI-equivalent path. Median of 2000 calls after 200 warm-up calls.
"""
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import ssiu


def median_us(f, n=2000, warm=200):
    for _ in range(warm):
        f()
    t = []
    for _ in range(n):
        t0 = time.perf_counter()
        f()
        t.append(time.perf_counter() - t0)
    return statistics.median(t) * 1e6


def main():
    work = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp()
    binary = os.path.join(os.environ.get("SSIU_BINARY_DIR", "build"), "ssiu")
    if not os.path.isdir(os.path.join(work, "cat")):
        subprocess.run([binary, "catalog", "build", "--fov-deg", "16.6", "--out", f"{work}/cat"], check=True,
                       capture_output=True)
        subprocess.run([binary, "simulate", "frame", "--random", "--seed", "5", "--out", f"{work}/f"], check=True,
                       capture_output=True)
    cam = f"{work}/f/camera.json"
    solver = ssiu.Solver(cam, catalog=f"{work}/cat")
    empty = np.zeros((0, 2))
    img, _ = ssiu.read_frame(f"{work}/f/frame_0000.png")
    det = ssiu.detect(img, cam)
    xy = np.array([[s["x_px"], s["y_px"], s["flux_adu"]] for s in det["stars"]])
    print(f"Solver.solve(empty centroids): {median_us(lambda: solver.solve(empty)):.1f} us")
    print(f"ssiu.solve(empty centroids):   {median_us(lambda: ssiu.solve(empty, cam, catalog=f'{work}/cat')):.1f} us")
    print(f"Solver.solve({len(xy)} centroids):    {median_us(lambda: solver.solve(xy), n=300, warm=30):.1f} us")
    print(f"Solver.solve(1024x1024 frame):  {median_us(lambda: solver.solve(img), n=100, warm=10):.1f} us")


if __name__ == "__main__":
    main()
