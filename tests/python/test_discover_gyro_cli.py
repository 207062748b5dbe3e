"""`ssiu discover gyro` on bench logs from a generator written here in Python, independently of the C++
test generator (tests/discover/discover_gyro_generator.h) the library's tests were developed on: a 12 h
static turntable run at 0.1 Hz (Earth rate at 50 deg latitude, a 45 deg turn every 45 min, a thermal
programme) with white noise and Gauss-Markov wander, plus one effect. Drifts of a shape in time that the
vocabulary does not hold (an ageing ramp, a warm-up) must be `unexplained` with the residual described as
a trend; causes of the vocabulary keep their names; a clean log is `none`.
"""
import json
import math
import os
import random
import subprocess

BIN = os.path.join(os.environ.get("SSIU_BINARY_DIR", "build"), "ssiu")


def write_log(path, seed, effect=None, size=0.0, when_s=0.0, humidity_period_s=0.0):
    """A static run; effect: None, "ageing" (size deg/h over the 12 h, linear), "warm_up" (size deg/h at the
    start, decaying with time constant when_s), "bias_step" (size deg/h at when_s), "temperature" (size deg/h
    per 10 C from 20 C), "humidity" (size deg/h per 15 % of a logged humidity_pct column that cycles with
    humidity_period_s)."""
    rng = random.Random(seed)
    dt, arw, wander, tau = 10.0, 0.3, 0.005, 900.0  # s, deg/h sqrt(s), deg/h, s
    earth_h = 15.041067 * math.cos(math.radians(50))
    bias, psi0, x = 0.2, rng.uniform(0, 360), 0.0
    phi = math.exp(-dt / tau)
    humid = effect == "humidity"
    rows = ["t_s,w_dph,ref_dph,temp_c,azimuth_deg" + (",humidity_pct" if humid else "")]
    for k in range(4320):
        t = k * dt
        # 20 C, +0.2 C/min for 75 min (35 C), hold 1.5 h, -0.15 C/min back to 18 C, hold.
        if t < 4500:
            temp = 20 + 0.2 * t / 60
        elif t < 9900:
            temp = 35.0
        else:
            temp = max(18.0, 35 - 0.15 * (t - 9900) / 60)
        psi = math.radians((psi0 + 45 * math.floor(t / 2700)) % 360)
        ref = earth_h * math.cos(psi)
        w = ref + bias
        if effect == "ageing":
            w += size * (t / 43200 - 0.5)
        elif effect == "warm_up":
            w += size * math.exp(-t / when_s)
        elif effect == "bias_step":
            w += size if t >= when_s else 0.0
        elif effect == "temperature":
            w += size * (temp - 20) / 10
        if humid:  # (its own draw only here: the other logs keep their data)
            humidity = 40 + 15 * math.sin(2 * math.pi * t / humidity_period_s) + 0.3 * rng.gauss(0, 1)
            w += size * (humidity - 40) / 15
        x = phi * x + wander * math.sqrt(1 - phi * phi) * rng.gauss(0, 1)
        w += x + arw / math.sqrt(dt) * rng.gauss(0, 1)
        row = f"{t:.1f},{w:.6f},{ref:.6f},{temp + 0.02 * rng.gauss(0, 1):.4f},{math.degrees(psi):.3f}"
        rows.append(row + (f",{humidity:.3f}" if humid else ""))
    path.write_text("\n".join(rows) + "\n")


def discover(tmp_path, name, writer=None, **kw):
    """`ssiu discover gyro` on a log written by writer (write_log by default) with kw; its JSON."""
    log = tmp_path / f"{name}.csv"
    (writer or write_log)(log, **kw)
    out = tmp_path / f"{name}.json"
    r = subprocess.run([BIN, "discover", "gyro", str(log), "--json", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return json.loads(out.read_text())


def test_clean_logs_are_none(tmp_path):
    # Each clean log has about residual_alpha + alpha (2 %) of a false finding: 3 of 4 at least.
    causes = [discover(tmp_path, f"clean{seed}", seed=seed)["cause"] for seed in (11, 12, 13, 14)]
    assert causes.count("none") >= 3, causes


def test_ageing_ramp_is_unexplained_and_described_as_a_trend(tmp_path):
    for seed in (21, 22):
        d = discover(tmp_path, f"ageing{seed}", seed=seed, effect="ageing", size=0.07)
        assert d["cause"] == "unexplained", (seed, d["cause"])
        r = d["residual"]
        assert r["finding"] == "trend" and r["trend_p"] < 1e-3
        # The ramp is P1 over the log (Legendre, -1..1 over the 12 h): its coefficient is half the ramp.
        assert abs(r["trend_coefficients_dph"]["time (P1)"] - 0.035) < 0.015


def test_warm_up_is_unexplained_with_its_time_constant(tmp_path):
    d = discover(tmp_path, "warm_up", seed=31, effect="warm_up", size=0.12, when_s=2400.0)
    assert d["cause"] == "unexplained"
    r = d["residual"]
    assert r["finding"] == "trend" and r["trend_p"] < 1e-3
    assert 1200 <= r["warm_up_tau_s"] <= 4800


def test_drift_following_a_cycling_logged_column_is_not_a_periodic_drift(tmp_path):
    # A humidity that cycles every 3 h: a periodic drift fits the drift as well, but the log says what it
    # follows (periodic_drift 4 of 4 before the logged-column check).
    d = discover(tmp_path, "humidity", seed=61, effect="humidity", size=0.06, humidity_period_s=10800.0)
    assert d["cause"] == "unexplained", d["cause"]
    assert d["residual"]["follows_column"] == "humidity_pct"
    refused = [c for c in d["candidates"] if c["cause"] == "periodic_drift" and "logged column" in c.get("verdict", "")]
    assert refused


def test_causes_of_the_vocabulary_keep_their_names(tmp_path):
    d = discover(tmp_path, "step", seed=41, effect="bias_step", size=0.06, when_s=20000.0)
    assert d["cause"] == "bias_step"
    assert abs(d["parameters"]["step_dph"] - 0.06) < 0.02
    assert abs(d["parameters"]["step_time_s"] - 20000) < 1800
    d = discover(tmp_path, "temperature", seed=51, effect="temperature", size=0.05)
    assert d["cause"] == "temperature"
    assert abs(d["parameters"]["K10_dph"] - 0.05) < 0.015


def write_rate_table_log(path, seed, tone_dph=0.0, tone_hz=0.0):
    """A 20 min rate-table run at 100 Hz: 2 min levels up to 20 deg/s, white noise 0.3 deg/h sqrt(s), and a
    tone (a vibration pickup) that the 1.2 s bins average away."""
    rng = random.Random(seed)
    dt, sigma = 0.01, 0.3 / math.sqrt(0.01)
    levels = [rng.uniform(-20, 20) * 3600 for _ in range(10)]
    earth_v = 15.041067 * math.sin(math.radians(50))
    rows = ["t_s,w_dph,ref_dph,temp_c"]
    for k in range(120000):
        t = k * dt
        ref = levels[(int(t / 120) // 2) % 10] + earth_v
        w = ref + 0.3 + sigma * rng.gauss(0, 1) + tone_dph * math.sin(2 * math.pi * tone_hz * t)
        rows.append(f"{t:.2f},{w:.5f},{ref:.5f},{24 + 0.02 * rng.gauss(0, 1):.3f}")
    path.write_text("\n".join(rows) + "\n")


def test_tone_above_the_bins_is_unexplained_with_its_frequency(tmp_path):
    d = discover(tmp_path, "rt_clean", write_rate_table_log, seed=1)
    assert d["cause"] == "none" and d["residual"]["line_p"] > 0.01
    d = discover(tmp_path, "rt_tone", write_rate_table_log, seed=2, tone_dph=0.5, tone_hz=2.0)
    assert d["cause"] == "unexplained" and d["residual"]["finding"] == "spectral_line"
    assert abs(d["residual"]["line_frequency_hz"] - 2.0) < 1 / 1200
    assert abs(d["residual"]["line_amplitude_dph"] - 0.5) < 0.1
