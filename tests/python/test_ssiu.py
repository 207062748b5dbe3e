"""The Python module against the CLI (same answers) and against the simulator's truth.

Frames, catalogs and gyro logs are made by the `ssiu` program of the same build (SSIU_BINARY_DIR).
"""
import json
import math
import os
import subprocess

import numpy as np
import pytest

import ssiu

BIN = os.path.join(os.environ.get("SSIU_BINARY_DIR", "build"), "ssiu")


def run(*args):
    r = subprocess.run([BIN, *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r


def quat_angle_arcsec(a, b):
    """Rotation angle between two [w, x, y, z] quaternions."""
    d = abs(float(np.dot(np.asarray(a), np.asarray(b))))
    return 2 * math.degrees(math.acos(min(1.0, d))) * 3600


@pytest.fixture(scope="module")
def sky(tmp_path_factory):
    """A solver catalog for the default 16.6-deg camera and three simulated frames with their truth."""
    d = tmp_path_factory.mktemp("sky")
    run("catalog", "build", "--fov-deg", "16.6", "--out", d / "cat")
    run("simulate", "frame", "--random", "--seed", "77", "--count", "3", "--out", d / "f")
    return d


def frame(sky, k):
    return str(sky / "f" / f"frame_{k:04d}.png")


def truth_q(sky, k):
    return json.loads((sky / "f" / f"frame_{k:04d}.json").read_text())["q"]


def cli_solve(sky, k):
    out = sky / f"cli_{k}.json"
    run("solve", frame(sky, k), "--camera", sky / "f" / "camera.json", "--catalog", sky / "cat", "--json", out)
    return json.loads(out.read_text())


def test_solve_of_a_frame_equals_the_cli_and_the_truth(sky):
    cam = str(sky / "f" / "camera.json")
    for k in range(3):
        cli = cli_solve(sky, k)
        py = ssiu.solve(frame(sky, k), cam, catalog=str(sky / "cat"))
        assert py["status"] == cli["status"] == "solved"
        assert quat_angle_arcsec(py["q"], cli["q"]) < 0.01
        assert [m["star_id"] for m in py["matches"]] == [m["star_id"] for m in cli["matches"]]
        assert set(py) == set(cli)
        assert quat_angle_arcsec(py["q"], truth_q(sky, k)) < 60


def test_array_input_is_read_in_place_with_any_row_stride(sky):
    cam = json.loads((sky / "f" / "camera.json").read_text())
    img, info = ssiu.read_frame(frame(sky, 0))
    assert img.dtype == np.uint16 and img.shape == (cam["height"], cam["width"])
    assert info["bit_depth"] == 16
    solver = ssiu.Solver(cam, catalog=str(sky / "cat"))
    a = solver.solve(img)
    # The same pixels inside a wider buffer: a view whose rows are not adjacent.
    wide = np.zeros((img.shape[0], img.shape[1] + 7), dtype=np.uint16)
    wide[:, 3:3 + img.shape[1]] = img
    b = solver.solve(wide[:, 3:3 + img.shape[1]])
    assert a["status"] == b["status"] == "solved"
    assert quat_angle_arcsec(a["q"], b["q"]) < 1e-6
    assert quat_angle_arcsec(a["q"], cli_solve(sky, 0)["q"]) < 0.01


def test_centroid_list_solves_and_detect_matches_the_cli(sky):
    cam = str(sky / "f" / "camera.json")
    det = ssiu.detect(frame(sky, 1), cam)
    out = sky / "det.json"
    run("detect", frame(sky, 1), "--camera", cam, "--json", out)
    cli = json.loads(out.read_text())
    assert len(det["stars"]) == len(cli["stars"]) > 10
    xy = np.array([[s["x_px"], s["y_px"], s["flux_adu"]] for s in det["stars"]])
    r = ssiu.solve(xy, cam, catalog=str(sky / "cat"))
    assert r["status"] == "solved"
    assert quat_angle_arcsec(r["q"], truth_q(sky, 1)) < 60
    # Without the flux column the rows are taken in the given order (here brightest first).
    r2 = ssiu.solve(xy[:, :2], cam, catalog=str(sky / "cat"))
    assert r2["status"] == "solved"
    assert quat_angle_arcsec(r2["q"], truth_q(sky, 1)) < 60
    # The work budget: the search that solved with h hypotheses gives up with h - 1, as `--max-hypotheses`.
    h = r["hypotheses"]
    assert r["search_stop"] == "accepted"
    short = ssiu.solve(xy, cam, catalog=str(sky / "cat"), max_hypotheses=h - 1) if h > 1 else None
    if short is not None:
        assert short["status"] == "no_match"
        assert short["search_stop"] == "hypothesis_budget"
    assert ssiu.solve(xy, cam, catalog=str(sky / "cat"), max_hypotheses=h)["q"] == r["q"]


def test_tracker_locks_then_tracks(sky):
    cam = str(sky / "f" / "camera.json")
    img, _ = ssiu.read_frame(frame(sky, 2))
    t = ssiu.Tracker(cam, catalog=str(sky / "cat"))
    assert not t.locked
    first = t.update(img, 0.0)
    assert first["status"] == "solved" and first["mode"] == "lost_in_space" and t.locked
    second = t.update(img, 1.0)
    assert second["status"] == "solved" and second["mode"] == "tracking"
    assert quat_angle_arcsec(second["q"], truth_q(sky, 2)) < 60


def test_bad_input_is_a_clear_error(sky):
    cam = str(sky / "f" / "camera.json")
    with pytest.raises(TypeError, match="did you mean 'max_false_prob'"):
        ssiu.solve(frame(sky, 0), cam, catalog=str(sky / "cat"), max_false_probb=1e-3)
    with pytest.raises(TypeError, match="uint8 or uint16"):
        ssiu.detect(np.zeros((64, 64), dtype=np.int32))
    with pytest.raises(ValueError, match="2-D"):
        ssiu.detect(np.zeros((64, 64, 3), dtype=np.uint16))
    with pytest.raises(ValueError, match="N x 2..4"):
        ssiu.solve(np.zeros((5, 7)), cam, catalog=str(sky / "cat"))
    with pytest.raises(ssiu.InputError, match="nope.png"):
        ssiu.read_frame(str(sky / "nope.png"))
    with pytest.raises(ValueError, match="camera says"):
        ssiu.Solver(cam, catalog=str(sky / "cat")).solve(np.zeros((32, 32), dtype=np.uint16))


def test_allan_recovers_the_angle_random_walk_of_white_noise():
    # White rate noise of sigma deg/h at fs Hz has ARW N = sigma / sqrt(fs) deg/h/sqrt(Hz), i.e.
    # sigma / sqrt(fs) / 60 deg/sqrt(h) (IEEE 952, Annex C).
    fs, sigma_dph = 100.0, 3.0
    rate = np.random.default_rng(5).normal(0.0, sigma_dph, 360_000)
    r = ssiu.allan(rate, fs, "deg/h")
    arw = r["terms"]["arw_deg_per_sqrt_h"]["value"] if "terms" in r else None
    expected = sigma_dph / math.sqrt(fs) / 60
    assert arw is not None, sorted(r)
    assert abs(arw / expected - 1) < 0.05
    with pytest.raises(TypeError, match="unknown option"):
        ssiu.allan(rate, fs, confidenc=0.9)


def test_fuse_equals_the_cli(tmp_path):
    run("simulate", "gyro", "--duration-s", "60", "--seed", "3", "--out", tmp_path / "g")
    g, st = tmp_path / "g" / "gyro.csv", tmp_path / "g" / "st.csv"
    out = tmp_path / "fuse.json"
    run("fuse", "--gyro", g, "--st", st, "--json", out)
    cli = json.loads(out.read_text())
    py = ssiu.fuse(str(g), str(st))
    assert py["status"] == cli["status"]
    np.testing.assert_allclose(py["bias_dph"], cli["bias_dph"], rtol=1e-9, atol=1e-12)
    assert py["q"].shape == (len(py["t_s"]), 4)
    assert np.all(py["sigma_arcsec"] > 0)


def test_fuse_noise_options_equal_the_cli_flags(tmp_path):
    # A body-rate log with its own noise: the keyword arguments take the CLI's flags' place, with the
    # same precedence and the same noise source in the result.
    run("simulate", "gyro", "--duration-s", "60", "--seed", "4", "--out", tmp_path / "g")
    g, st = tmp_path / "g" / "gyro.csv", tmp_path / "g" / "st.csv"
    out = tmp_path / "fuse.json"
    run("fuse", "--gyro", g, "--st", st, "--json", out, "--arw-deg-per-sqrt-h", "0.02",
        "--bias-instability-dph", "0.1")
    cli = json.loads(out.read_text())
    py = ssiu.fuse(str(g), str(st), arw_deg_per_sqrt_h=0.02, bias_instability_dph=0.1)
    assert py["noise"]["source"] == cli["noise"]["source"] == "flags"
    assert py["noise"]["arw_deg_per_sqrt_h"] == pytest.approx(0.02)
    np.testing.assert_allclose(py["bias_dph"], cli["bias_dph"], rtol=1e-9, atol=1e-12)
    default = ssiu.fuse(str(g), str(st))
    assert default["noise"]["source"] == "default_unit"
    assert default["noise"]["arw_deg_per_sqrt_h"] != pytest.approx(0.02)
    with pytest.raises(ValueError, match="arw_deg_per_sqrt_h: must be a finite number > 0"):
        ssiu.fuse(str(g), str(st), arw_deg_per_sqrt_h=-1.0)


def test_unknown_field_of_view_equals_the_cli(sky, tmp_path):
    cam = json.loads((sky / "f" / "camera.json").read_text())
    f_true = cam.pop("focal_length_px")
    nofocal = tmp_path / "nofocal.json"
    nofocal.write_text(json.dumps(cam))
    out = tmp_path / "cli.json"
    run("solve", frame(sky, 1), "--camera", nofocal, "--fov-range-deg", "14,20", "--json", out)
    cli = json.loads(out.read_text())
    py = ssiu.Solver(cam, fov_range_deg=(14, 20)).solve(frame(sky, 1))
    assert py["status"] == cli["status"] == "solved"
    assert abs(py["focal_length_px"] / f_true - 1) < 0.002
    assert py["focal_length_px"] == pytest.approx(cli["focal_length_px"], rel=1e-9)
    assert quat_angle_arcsec(py["q"], cli["q"]) < 0.01
    assert quat_angle_arcsec(py["q"], truth_q(sky, 1)) < 60
    with pytest.raises(ValueError, match="focal_length_px"):
        ssiu.Solver(cam)
    with pytest.raises(ValueError, match="fov_range_deg"):
        ssiu.Tracker(cam, fov_range_deg=(14, 20))


def test_camera_vignetting_and_hot_pixels_are_used_as_by_the_cli(sky):
    """camera.json's `vignetting`, `hot_pixels` and `psf_sigma_px` (a fitted camera of `discover frames`): the Solver,
    the Tracker and detect use them as the CLI does (same photometric factor, same matches, the same
    rejections), and they change the answer."""
    cam = json.loads((sky / "f" / "camera.json").read_text())
    truth = json.loads((sky / "f" / "frame_0000.json").read_text())
    model = dict(cam, vignetting=0.5, psf_sigma_px=1.25,
                 hot_pixels=[[round(a["x_px"]), round(a["y_px"])] for a in truth["artefacts"]
                             if a["type"] == "hot_pixel"])
    path = sky / "cam_model.json"
    path.write_text(json.dumps(model))
    out = sky / "cli_model.json"
    run("solve", frame(sky, 0), "--camera", path, "--catalog", sky / "cat", "--json", out)
    cli = json.loads(out.read_text())
    py = ssiu.Solver(model, catalog=str(sky / "cat")).solve(frame(sky, 0))
    plain = ssiu.Solver(cam, catalog=str(sky / "cat")).solve(frame(sky, 0))
    assert py["status"] == cli["status"] == plain["status"] == "solved"
    assert py["photometric_factor"] == pytest.approx(cli["photometric_factor"], rel=1e-9)
    assert [m["star_id"] for m in py["matches"]] == [m["star_id"] for m in cli["matches"]]
    assert py["photometric_factor"] != pytest.approx(plain["photometric_factor"], rel=1e-3)
    img, _ = ssiu.read_frame(frame(sky, 0))
    tr = ssiu.Tracker(model, catalog=str(sky / "cat")).update(img, 0.0)
    assert tr["photometric_factor"] == pytest.approx(cli["photometric_factor"], rel=1e-9)
    # ssiu.detect with the camera: the listed hot pixels are the defect map's, as with `ssiu detect`.
    det_out = sky / "det_model.json"
    run("detect", frame(sky, 0), "--camera", path, "--json", det_out)
    cli_det = json.loads(det_out.read_text())
    py_det = ssiu.detect(frame(sky, 0), model)
    reasons = [r["reason"] for r in py_det["rejected"]]
    assert reasons.count("defect_map") >= len(model["hot_pixels"]) - 1
    assert reasons == [r["reason"] for r in cli_det["rejected"]]
    # Its psf_sigma_px is the detector's expected PSF in both (the frame's own estimate otherwise).
    assert py_det["psf_sigma_px"] == cli_det["psf_sigma_px"] == 1.25
    assert ssiu.detect(frame(sky, 0), cam)["psf_sigma_px"] != pytest.approx(1.25, abs=1e-3)
