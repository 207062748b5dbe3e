// The allan -> fuse chain (issue 18 item 3), shared by the CI test and the long test: a static
// calibration log through `ssiu allan --json` gives the noise file; constant-bias body-rate logs are
// fused with `ssiu fuse --noise` (and, for contrast, with the default unit's noise), and the bias
// errors are scored against the angle-random-walk (Cramer-Rao) bound and the reported sigma.
#pragma once

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "core/json.h"
#include "core/rng.h"
#include "testing/testing.h"

namespace ssiu::testing {

struct NoiseChainScore {
  double bias_rms_dph[3] = {0, 0, 0};          // over runs, --noise
  double default_bias_rms_dph[3] = {0, 0, 0};  // over runs, no --noise (the default unit's noise)
  double crb_dph = 0;                          // ARW / sqrt(T), per axis of an orthogonal triad
  double nees_mean = 0;                        // bias NEES (3 dof) averaged over runs, --noise
  Json noise;                                  // the "noise" object of the first run's fuse JSON
};

// Body rates wx,wy,wz of a static unit at `rate_hz` for `duration_s`: constant biases plus white rate
// noise of angle random walk `arw` (deg/sqrt(h)): per sample sigma = arw * 60 / sqrt(dt) deg/h (each
// row the mean rate over its interval).
inline void WriteStaticBodyRateLog(const std::string& path, double rate_hz, double duration_s, double arw,
                                   const double bias_dph[3], uint64_t seed) {
  Rng rng(seed);
  const double dt = 1.0 / rate_hz, sigma = arw * 60.0 / std::sqrt(dt);
  std::ofstream out(path);
  out << "t_s,wx_dph,wy_dph,wz_dph\n";
  char line[128];
  const long n = std::lround(duration_s * rate_hz);
  for (long k = 1; k <= n; ++k) {
    std::snprintf(line, sizeof line, "%.3f,%.6f,%.6f,%.6f\n", k * dt, bias_dph[0] + sigma * rng.Normal(),
                  bias_dph[1] + sigma * rng.Normal(), bias_dph[2] + sigma * rng.Normal());
    out << line;
  }
}

// Star-tracker log of the static (identity) attitude at 1 Hz, noise 5 arcsec cross-boresight (x, y)
// and 30 arcsec roll (z), the fuse defaults.
inline void WriteStaticStarLog(const std::string& path, double duration_s, uint64_t seed) {
  Rng rng(seed);
  const double as = 3.14159265358979324 / 180.0 / 3600.0;
  std::ofstream out(path);
  out << "t_s,qw,qx,qy,qz\n";
  char line[160];
  for (long k = 0; k <= std::lround(duration_s); ++k) {
    const double x = 5 * as * rng.Normal() / 2, y = 5 * as * rng.Normal() / 2, z = 30 * as * rng.Normal() / 2;
    std::snprintf(line, sizeof line, "%ld,%.15f,%.15f,%.15f,%.15f\n", k, std::sqrt(1 - x * x - y * y - z * z), x, y, z);
    out << line;
  }
}

// `with_default`: also fuse each run without --noise (the default unit's noise) for contrast.
// `calibration_s`: the calibration log's length (a 30-min one is where `ssiu allan` used to read a
// flicker floor out of white noise, docs/allan.md).
inline NoiseChainScore RunNoiseChain(int runs, const std::string& dir, bool with_default, double calibration_s = 7200) {
  constexpr double kArw = 0.01, kRateHz = 10, kDurationS = 1800;
  const double bias[3] = {2.0, -3.0, 1.5};
  NoiseChainScore s;
  // Calibration: a separate static log, one Allan report per axis, combined into an array.
  WriteStaticBodyRateLog(dir + "/cal.csv", kRateHz, calibration_s, kArw, bias, 999);
  Json reports = Json::array();
  for (const char* c : {"wx_dph", "wy_dph", "wz_dph"}) {
    const SsiuResult r = RunSsiu("allan " + dir + "/cal.csv --column " + c + " --json " + dir + "/a.json");
    EXPECT_EQ(r.status, 0) << r.output;
    reports.push_back(ReadJsonFile(dir + "/a.json"));
  }
  WriteJsonFile(dir + "/noise.json", reports);
  double sum2[3] = {0, 0, 0}, sum2_default[3] = {0, 0, 0}, nees = 0;
  for (int run = 0; run < runs; ++run) {
    WriteStaticBodyRateLog(dir + "/g.csv", kRateHz, kDurationS, kArw, bias, 100 + run);
    WriteStaticStarLog(dir + "/st.csv", kDurationS, 500 + run);
    const std::string fuse = "fuse --gyro " + dir + "/g.csv --st " + dir + "/st.csv --json " + dir + "/f.json";
    SsiuResult r = RunSsiu(fuse + " --noise " + dir + "/noise.json");
    EXPECT_EQ(r.status, 0) << r.output;
    const Json f = ReadJsonFile(dir + "/f.json");
    if (run == 0) s.noise = f.at("noise");
    for (int a = 0; a < 3; ++a) {
      const double e = f.at("bias_dph")[a].get<double>() - bias[a], sg = f.at("bias_sigma_dph")[a].get<double>();
      sum2[a] += e * e;
      nees += e * e / (sg * sg);
    }
    if (!with_default) continue;
    r = RunSsiu(fuse);
    EXPECT_EQ(r.status, 0) << r.output;
    const Json fd = ReadJsonFile(dir + "/f.json");
    for (int a = 0; a < 3; ++a) sum2_default[a] += std::pow(fd.at("bias_dph")[a].get<double>() - bias[a], 2);
  }
  // Cramer-Rao bound of a constant rate in white rate noise over T with the attitude known:
  // ARW sqrt(diag((H'H)^-1) / T), H = I for body rates (gyro_fusion_longtest.cc).
  s.crb_dph = kArw / std::sqrt(kDurationS / 3600.0);
  for (int a = 0; a < 3; ++a) {
    s.bias_rms_dph[a] = std::sqrt(sum2[a] / runs);
    s.default_bias_rms_dph[a] = std::sqrt(sum2_default[a] / runs);
    std::printf("axis %d: bias RMS over %d runs %.4f deg/h with --noise (%.2f x bound %.4f), %.4f (%.2f x) default\n",
                a, runs, s.bias_rms_dph[a], s.bias_rms_dph[a] / s.crb_dph, s.crb_dph, s.default_bias_rms_dph[a],
                s.default_bias_rms_dph[a] / s.crb_dph);
  }
  s.nees_mean = nees / runs;
  std::printf("bias NEES mean %.2f (3 dof); noise used %s\n", s.nees_mean, s.noise.dump().c_str());
  return s;
}

}  // namespace ssiu::testing
