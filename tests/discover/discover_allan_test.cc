#include "discover/discover_allan.h"

#include <algorithm>
#include <fstream>

#include "calibration/allan.h"
#include "calibration/allan_io.h"
#include "core/rng.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// A white + rate-random-walk log: the default model (ARW + bias instability) must leave the curve
// at long tau and the extended fit must name rate_random_walk; a white-only log gives no departure.
TEST(DiscoverAllan, NamesMissingRateRandomWalk) {
  Rng rng(3);
  const double rate_hz = 10, n_arw = 1e-4, k_rrw = 2e-6;  // rad/s sqrt(s), rad/s/sqrt(s)
  std::vector<double> with_rrw, white;
  double walk = 0;
  for (int i = 0; i < 200000; ++i) {
    const double w = n_arw * std::sqrt(rate_hz) * rng.Normal();
    walk += k_rrw / std::sqrt(rate_hz) * rng.Normal();
    with_rrw.push_back(w + walk);
    white.push_back(w);
  }
  const auto d = CompareAllanToDefaultModel(OverlappingAllanDeviation(with_rrw, rate_hz), {});
  ASSERT_FALSE(d.departures_s.empty());
  EXPECT_GT(d.departures_s.back().second, 100.0);
  EXPECT_NE(std::find(d.missing_terms.begin(), d.missing_terms.end(), "rate_random_walk"), d.missing_terms.end());
  EXPECT_LT(d.chi2_per_dof_after, d.chi2_per_dof_before);
  EXPECT_NEAR(d.extended.rrw.value, k_rrw, 3 * d.extended.rrw.sigma);
  const auto c = CompareAllanToDefaultModel(OverlappingAllanDeviation(white, rate_hz), {});
  EXPECT_TRUE(c.missing_terms.empty());
  EXPECT_NEAR(c.base_arw, n_arw, 0.03 * n_arw);
}

// The real KVH 1750 curve (docs/discrepancy.md): the default model misses the rate random walk.
TEST(DiscoverAllan, Kvh1750MissesRateRandomWalk) {
  SSIU_REQUIRE_SHARED(path, "gyro/smac-avar/kvh1750_av.csv");
  CurveFileOptions co;
  co.channel = "Gyro. X";
  co.unit = "deg/s";
  const auto d = CompareAllanToDefaultModel(ReadAllanCurveFile(path, co).curve, {});
  EXPECT_EQ(d.missing_terms, std::vector<std::string>{"rate_random_walk"});
  EXPECT_GT(d.chi2_per_dof_before, 4 * d.chi2_per_dof_after);
  // Stepwise: the short-tau rise first (quantization), then the random walk; nothing departs after them.
  ASSERT_EQ(d.steps.size(), 2u);
  EXPECT_EQ(d.steps[1].term, "rate_random_walk");
  EXPECT_EQ(d.left, "none");
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// A curve that is zero at some tau cannot weight the base model there: exit 1 naming the file
// (was exit 0 with every figure null).
TEST(DiscoverAllan, ZeroAdevIsBadInput) {
  const std::string dir = testing::TempDir("zero_adev");
  std::ofstream(dir + "/zero.csv") << "tau_s,adev_dph\n1,0.1\n2,0\n4,0.05\n8,0.035\n16,0.025\n";
  std::string out;
  EXPECT_EQ(testing::Run(testing::SsiuProgram() + " discover allan --curve " + dir + "/zero.csv --json -", &out), 1)
      << out;
  EXPECT_THAT(out, ::testing::HasSubstr("zero.csv: ADEV is zero at tau 2"));
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
}

// A negative or NaN length/rate behind the curve was silently ignored; a hex number was read as one;
// an unwritable --json came after the summary line (two lines). Each is now one line, exit 1.
TEST(DiscoverAllan, BadFlagsHexAndUnwritableOutputAreOneLine) {
  const std::string dir = testing::TempDir("allan_flags");
  std::ofstream(dir + "/c.csv") << "tau_s,adev_dph\n1,0.1\n2,0.07\n4,0.05\n8,0.035\n16,0.025\n";
  std::ofstream(dir + "/hex.csv") << "tau_s,adev_dph\n1,0.1\n0x2,0.07\n4,0.05\n8,0.035\n16,0.025\n";
  const std::string run = testing::SsiuProgram() + " discover allan --curve ";
  struct Case {
    std::string args, needle;
  } cases[] = {{dir + "/c.csv --duration-s -5", "c.csv: duration (--duration-s) must be a finite number >= 0"},
               {dir + "/c.csv --duration-s inf", "duration (--duration-s) must be"},
               {dir + "/c.csv --sample-rate-hz nan", "sample rate (--sample-rate-hz) must be"},
               {dir + "/hex.csv", "hex.csv"},
               {dir + "/c.csv --json /nonexistent_dir/out.json", "/nonexistent_dir/out.json"}};
  for (const auto& c : cases) {
    std::string out;
    EXPECT_EQ(testing::Run(run + c.args, &out), 1) << c.args << "\n" << out;
    EXPECT_THAT(out, ::testing::HasSubstr(c.needle)) << c.args;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  }
  std::string out;  // the same curve with sane flags runs
  EXPECT_EQ(testing::Run(run + dir + "/c.csv --duration-s 3600 --json " + dir + "/ok.json", &out), 0) << out;
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// Stepwise extension (issue 31): a log with white noise, a rate random walk and angle quantization (a
// pulse-counting output: the integrated angle read in steps of q, quantization noise Q = q / sqrt(12),
// IEEE 952 C.2) names both missing terms, each with its joint-fit value within 3 sigma of the truth, and
// leaves nothing; white noise alone names nothing.
TEST(DiscoverAllan, StepwiseNamesQuantizationAndRandomWalk) {
  Rng rng(11);
  const double rate_hz = 100, n_arw = 2e-5, k_rrw = 2e-6, q_step = 2e-6;  // rad/s sqrt(s), rad/s/sqrt(s), rad
  std::vector<double> both, white;
  double walk = 0, angle = 0, read_prev = 0;
  for (int i = 0; i < 400000; ++i) {
    const double w = n_arw * std::sqrt(rate_hz) * rng.Normal();
    walk += k_rrw / std::sqrt(rate_hz) * rng.Normal();
    angle += (w + walk) / rate_hz;
    const double read = q_step * std::round(angle / q_step);
    both.push_back((read - read_prev) * rate_hz);
    read_prev = read;
    white.push_back(w);
  }
  const AllanCurve curve = OverlappingAllanDeviation(both, rate_hz);
  const auto d = CompareAllanToDefaultModel(curve, {});
  std::vector<std::string> named;
  double rms_pct = d.residual_rms_pct_before;
  for (const auto& st : d.steps) {
    named.push_back(st.term);
    EXPECT_GT(st.gain, 1) << st.term;
    EXPECT_LT(st.p_value, 0.01) << st.term;
    EXPECT_LT(st.residual_rms_pct, rms_pct) << st.term;  // each term brings the model closer to the curve
    rms_pct = st.residual_rms_pct;
  }
  // The last step's residual is the final model's ADEV against the curve, point by point, each point weighted
  // by its precision (its edf and the 2 % model-error floor), and lies at the points' own scatter.
  double ss = 0, sw = 0;
  for (size_t i = 0; i < curve.tau_s.size(); ++i) {
    const double rel_sigma = std::hypot(std::sqrt(2 / curve.edf[i]) / 2, NoiseFitOptions{}.model_error);
    ss += std::pow((d.final_adev[i] / curve.adev[i] - 1) / rel_sigma, 2), sw += std::pow(rel_sigma, -2);
  }
  EXPECT_NEAR(rms_pct, 100 * std::sqrt(ss / sw), 1e-6 * rms_pct);
  EXPECT_LT(rms_pct, 1.5 * d.point_sigma_rms_pct);
  EXPECT_GT(d.residual_rms_pct_before, 2 * d.point_sigma_rms_pct);  // ARW + B alone misses the two terms
  std::sort(named.begin(), named.end());
  ASSERT_EQ(named, (std::vector<std::string>{"quantization", "rate_random_walk"}));
  EXPECT_NEAR(d.joint.rrw.value, k_rrw, 3 * d.joint.rrw.sigma);
  EXPECT_NEAR(d.joint.quantization.value, q_step / std::sqrt(12.0), 3 * d.joint.quantization.sigma);
  EXPECT_NEAR(d.joint.arw.value, n_arw, 3 * d.joint.arw.sigma);
  EXPECT_EQ(d.left, "none");
  const auto c = CompareAllanToDefaultModel(OverlappingAllanDeviation(white, rate_hz), {});
  EXPECT_TRUE(c.steps.empty());
  EXPECT_EQ(c.left, "none");
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// Through the command, an exact curve of white noise and a rate random walk (IEEE 952 C.2: avar = N^2 / tau
// + K^2 tau / 3): the chain's JSON names the walk with K, and its residual goes from the default model's
// misfit, beyond the points' own errors, to nothing (the model is the curve's own).
TEST(DiscoverAllan, ChainJsonCarriesTheResidualAfterEachStep) {
  const std::string dir = testing::TempDir("allan_chain_json");
  const double n_arw = 0.1, k_rrw = 0.002;  // deg/h sqrt(s), deg/h / sqrt(s)
  {
    std::ofstream f(dir + "/c.csv");
    f << "tau_s,adev_dph\n";
    for (double tau = 1; tau < 2e4; tau *= std::pow(10.0, 0.25)) {
      f << tau << "," << std::sqrt(n_arw * n_arw / tau + k_rrw * k_rrw * tau / 3) << "\n";
    }
  }
  std::string out;
  ASSERT_EQ(testing::Run(testing::SsiuProgram() + " discover allan --curve " + dir + "/c.csv --json " + dir + "/o.json",
                         &out),
            0)
      << out;
  const Json j = Json::parse(std::ifstream(dir + "/o.json"));
  ASSERT_EQ(j["causes"].size(), 1u) << j.dump(1);
  const Json& c = j["causes"][0];
  EXPECT_EQ(c["cause"], "rate_random_walk");
  // K in deg/h/sqrt(h): 60 x the deg/h/sqrt(s) figure.
  EXPECT_NEAR(c["parameters"]["rrw_deg_per_h_per_sqrt_h"].get<double>(), 60 * k_rrw, 1e-3 * 60 * k_rrw);
  EXPECT_GT(j["residual_rms_pct_before"].get<double>(), 2 * j["point_sigma_rms_pct"].get<double>());
  EXPECT_LT(c["residual_rms_pct"].get<double>(), 0.01);
  EXPECT_EQ(j["residual_rms_pct_after"], c["residual_rms_pct"]);
  EXPECT_EQ(j["left"], "none");
  EXPECT_THAT(out, ::testing::HasSubstr("cause rate_random_walk; residual rms "));
}

}  // namespace
}  // namespace ssiu
