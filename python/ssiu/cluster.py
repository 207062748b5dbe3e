"""Solve many frames on a Dask cluster: ``python3 -m ssiu.cluster``.

    python3 -m ssiu.cluster --scheduler local:2 --camera cam.json --jsonl out.jsonl frames/*.png
    python3 -m ssiu.cluster --scheduler tcp://10.0.0.5:8786 --camera cam.json --jsonl out.jsonl --list files.txt

Each input (frame: PNG/TIFF/FITS/JPEG/BMP, or a centroid .csv) is solved independently; every worker process
loads the camera's catalog once and keeps it (``ssiu.solve`` keeps its Solver) for all the frames it
is given. One JSON object per input is written to --jsonl in input order: the fields of
``ssiu solve --json`` plus ``"file"`` (the records of ``ssiu solve --jsonl``); an input that cannot be
read gives ``{"file", "status": "error", "error", "message"}`` and the run goes on (exit status 1
when any input failed). With --ship-frames the client reads the frames and sends the pixels (workers
without shared storage); otherwise the workers open the paths themselves (shared storage). docs/scale.md has the measured throughput.
"""
import argparse
import json
import os
import sys
import time

# Solver options: flag -> (keyword, type), as `ssiu solve`.
_OPTIONS = {
    "--catalog": ("catalog", str),
    "--fov-tolerance-pct": ("fov_tolerance_pct", float),
    "--max-false-prob": ("max_false_prob", float),
    "--centroid-sigma-px": ("centroid_sigma_px", float),
    "--systematic-px": ("systematic_px", float),
    "--threshold-sigma": ("threshold_sigma", float),
    "--mag-max": ("mag_max", float),
    "--source": ("source", str),
}


def _solve_one(item, camera, options):
    """One input -> its JSON line. Runs on a worker; the Solver (catalog) stays loaded there."""
    import ssiu

    name, pixels = item
    try:
        r = ssiu.solve(name if pixels is None else pixels, camera, **options)
    except (ValueError, TypeError, OSError) as e:  # bad input: a record, not the end of the run
        # The record `ssiu solve --jsonl` writes for a bad input (message = error, as the CLI).
        return json.dumps({"file": name, "status": "error", "error": str(e), "message": str(e)})
    r["file"] = name
    return json.dumps(r)


def _solve_batch(items, camera, options):
    return [_solve_one(item, camera, options) for item in items]


def _read_item(path, ship):
    if not ship or path.lower().endswith(".csv"):
        return (path, None)
    import ssiu

    try:
        pixels, info = ssiu.read_frame(path)
    except ValueError:
        return (path, None)  # the worker reports the same error for the path
    return (path, pixels)


def _client(scheduler):
    from dask.distributed import Client, LocalCluster

    if scheduler.startswith("local:"):
        n = int(scheduler.split(":", 1)[1])
        if n < 1:
            raise ValueError("--scheduler local:N needs N >= 1")
        # One single-threaded worker process per core: the solver is single-threaded, and separate
        # processes keep the catalog per worker, as on a real cluster.
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
        return Client(cluster), cluster
    return Client(scheduler), None


def _progress(done, total, t0):
    if not sys.stderr.isatty():
        return
    rate = done / max(time.monotonic() - t0, 1e-9)
    left = (total - done) / rate if rate > 0 else 0
    sys.stderr.write(f"\r{done}/{total} frames, {rate:.1f}/s, {left:.0f} s left ")
    if done == total:
        sys.stderr.write("\n")
    sys.stderr.flush()


def main(argv=None):
    p = argparse.ArgumentParser(prog="python3 -m ssiu.cluster", description=__doc__.split("\n\n")[0])
    p.add_argument("inputs", nargs="*", help="frames (PNG/TIFF/FITS/JPEG/BMP) or centroid CSVs")
    p.add_argument("--list", help="file with one input path per line")
    p.add_argument("--scheduler", required=True, help="Dask scheduler address, or local:N for N local worker processes")
    p.add_argument("--camera", required=True, help="camera.json (read here and sent to the workers)")
    p.add_argument("--jsonl", required=True, help="output JSON Lines, one object per input in input order")
    p.add_argument("--batch", type=int, default=8, help="inputs per task (default 8)")
    p.add_argument("--ship-frames", action="store_true", help="read frames here and send the pixels to the workers")
    for flag, (_, typ) in _OPTIONS.items():
        p.add_argument(flag, type=typ)
    a = p.parse_args(argv)

    inputs = list(a.inputs)
    if a.list:
        try:
            with open(a.list) as f:
                inputs += [line.strip() for line in f if line.strip() and not line.startswith("#")]
        except OSError as e:
            p.exit(1, f"{a.list}: {e.strerror}\n")
    if not inputs:
        p.exit(1, "ssiu.cluster: no inputs (give paths or --list FILE)\n")
    if a.batch < 1:
        p.exit(1, "--batch: must be >= 1\n")
    try:
        with open(a.camera) as f:
            camera = json.load(f)
    except (OSError, ValueError) as e:
        p.exit(1, f"{a.camera}: {e}\n")
    options = {kw: getattr(a, flag[2:].replace("-", "_")) for flag, (kw, _) in _OPTIONS.items()}
    options = {k: v for k, v in options.items() if v is not None}
    # Bad options or camera fail here, once, rather than on every worker.
    import ssiu

    try:
        ssiu.Solver(camera, **options)
    except (ValueError, TypeError) as e:
        p.exit(1, f"{a.camera}: {e}\n")

    client, cluster = _client(a.scheduler)
    failed = 0
    t0 = time.monotonic()
    tmp = a.jsonl + ".tmp"
    try:
        batches = [inputs[i:i + a.batch] for i in range(0, len(inputs), a.batch)]
        futures = [client.submit(_solve_batch, [_read_item(x, a.ship_frames) for x in b], camera, options, pure=False)
                   for b in batches]
        done = 0
        with open(tmp, "w") as out:
            for fut in futures:  # in input order; later batches keep running meanwhile
                for line in fut.result():
                    out.write(line + "\n")
                    failed += '"status": "error"' in line
                done += 1
                _progress(min(done * a.batch, len(inputs)), len(inputs), t0)
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, a.jsonl)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
        if os.path.exists(tmp):
            os.remove(tmp)
    dt = time.monotonic() - t0
    print(f"ssiu.cluster: {len(inputs)} inputs in {dt:.2f} s ({len(inputs) / dt:.1f}/s), {failed} failed",
          file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
