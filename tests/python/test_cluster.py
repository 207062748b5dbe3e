"""python3 -m ssiu.cluster on a local Dask cluster of 2 worker processes: the same JSON Lines as
solving each input in this process, in input order, with a bad input reported and the run going on."""
import json
import os
import subprocess
import sys

import ssiu

from test_ssiu import quat_angle_arcsec, run


def test_local_cluster_writes_the_same_json_lines(tmp_path):
    run("catalog", "build", "--fov-deg", "16.6", "--out", tmp_path / "cat")
    run("simulate", "frame", "--random", "--seed", "11", "--count", "5", "--out", tmp_path / "f")
    frames = [str(tmp_path / "f" / f"frame_{k:04d}.png") for k in range(5)]
    bad = str(tmp_path / "missing.png")
    inputs = frames[:2] + [bad] + frames[2:]
    cam = str(tmp_path / "f" / "camera.json")
    out = tmp_path / "out.jsonl"
    env = dict(os.environ)
    r = subprocess.run([sys.executable, "-m", "ssiu.cluster", "--scheduler", "local:2", "--camera", cam,
                        "--catalog", str(tmp_path / "cat"), "--jsonl", str(out), "--batch", "2", *inputs],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 1, r.stderr  # one input failed
    assert "1 failed" in r.stderr
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert [x["file"] for x in lines] == inputs
    assert lines[2]["status"] == "error" and "missing.png" in lines[2]["error"]
    for rec in lines[:2] + lines[3:]:
        here = ssiu.solve(rec["file"], cam, catalog=str(tmp_path / "cat"))
        assert rec["status"] == here["status"] == "solved"
        assert quat_angle_arcsec(rec["q"], here["q"]) < 0.01
        assert set(rec) == set(here) | {"file"}


def test_cluster_refuses_bad_arguments_with_exit_1(tmp_path):
    r = subprocess.run([sys.executable, "-m", "ssiu.cluster", "--scheduler", "local:1", "--camera",
                        str(tmp_path / "nope.json"), "--jsonl", str(tmp_path / "o.jsonl"), "x.png"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "nope.json" in r.stderr
