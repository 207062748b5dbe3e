// Bench calibration of the FOG temperature drift against simulated runs with known K_ij.
#include "calibration/fog_thermal.h"

#include <cmath>

#include "core/csv.h"
#include "core/error.h"
#include "core/types.h"
#include "fog_thermal_mc.h"
#include "sim/fog_bench_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

ThermalRun ToRun(const ThermalBenchRun& sim, const std::string& name) {
  return ThermalRun{name, sim.t_s, sim.w_dph, sim.ref_dph, sim.temp_c};
}

TEST(FogThermal, RateFromNoisyTemperatureMatchesTruth) {
  ThermalBenchOptions o;
  o.seed = 3;
  const ThermalBenchRun sim = SimulateThermalRun(o);
  std::vector<double> at;
  for (size_t i = 600; i + 600 < sim.t_s.size(); i += 97) at.push_back(sim.t_s[i]);
  const TemperatureEstimate te = EstimateTemperatureRate(sim.t_s, sim.temp_c, at, TemperatureRateOptions{});
  double max_rate_err = 0, max_temp_err = 0, max_rate = 0;
  for (size_t q = 0; q < at.size(); ++q) {
    const size_t i = static_cast<size_t>(at[q]);
    max_rate_err = std::max(max_rate_err, std::abs(te.rate_c_per_min[q] - sim.true_rate_c_per_min[i]));
    max_temp_err = std::max(max_temp_err, std::abs(te.temp_c[q] - sim.true_temp_c[i]));
    max_rate = std::max(max_rate, std::abs(sim.true_rate_c_per_min[i]));
  }
  // A sample-to-sample difference of the 0.02 C noise would carry 1.7 C/min of noise; the local
  // cubic stays within 0.01 C/min (4 % of 0.25 C/min) everywhere, corners of the programme included.
  EXPECT_GT(max_rate, 0.15);
  EXPECT_LT(max_rate_err, 0.01);
  EXPECT_LT(max_temp_err, 0.01);
}

TEST(FogThermal, SelectsPaperTermsAndCompensatesHeldOutRun10x) {
  ThermalBenchOptions o;
  o.drift = CampaignDriftModel();
  std::vector<ThermalRun> fit_runs;
  for (uint64_t seed : {101, 102}) {
    o.seed = seed;
    fit_runs.push_back(ToRun(SimulateThermalRun(o), "run" + std::to_string(seed)));
  }
  const ThermalFitOptions opts;
  const ThermalFitResult fit = FitThermalDrift(fit_runs, opts);
  for (int k = 0; k < ThermalDriftModel::kNumTerms; ++k) {
    const bool truth = o.drift.k_dph[k] != 0;
    EXPECT_EQ(fit.kept[k], truth) << ThermalDriftModel::TermName(k);
    if (fit.kept[k]) {
      EXPECT_NEAR(fit.model.k_dph[k], o.drift.k_dph[k], 3 * fit.sigma_dph[k]) << ThermalDriftModel::TermName(k);
    }
  }
  EXPECT_TRUE(fit.validation_agrees);
  o.seed = 103;  // a run the model was not fitted on
  const ThermalEvaluation held = EvaluateThermalModel({ToRun(SimulateThermalRun(o), "held")}, fit.model, opts);
  EXPECT_GT(held.before.peak_dph, 0.8);
  EXPECT_GE(held.gain, 10.0) << "before " << held.before.peak_dph << " after " << held.after.peak_dph;
  EXPECT_LT(held.angle_error_after_deg, 0.1 * held.angle_error_before_deg);
}

TEST(FogThermal, CompensationPerSampleRemovesTrueDrift) {
  ThermalBenchOptions o;
  o.drift = CampaignDriftModel();
  o.seed = 7;
  o.white_noise_dph = 0;
  o.wander_sigma_dph = 0;
  const ThermalBenchRun sim = SimulateThermalRun(o);
  const ThermalCompensation c = CompensateThermalRun(ToRun(sim, "c"), o.drift, TemperatureRateOptions{});
  double worst = 0, ss = 0, ss_drift = 0;
  size_t n = 0;
  for (size_t i = 300; i + 300 < sim.t_s.size(); ++i) {
    const double e = c.w_comp_dph[i] - sim.ref_dph[i];
    worst = std::max(worst, std::abs(e));
    ss += e * e;
    ss_drift += sim.true_drift_dph[i] * sim.true_drift_dph[i];
    ++n;
  }
  // What is left comes from the rate estimate's smoothing at the programme's corners.
  EXPECT_LT(std::sqrt(ss / n), 0.02 * std::sqrt(ss_drift / n));
  EXPECT_LT(worst, 0.1);
}

// The acceptance Monte Carlo, small version (the 100-case run is fog_thermal_longtest.cc).
TEST(FogThermal, TermSelectionMonteCarlo15Cases) {
  const ThermalMcSummary s = RunThermalSelectionMc(15, 5000);
  std::cout << s.Describe() << "\n";
  EXPECT_GE(s.exact_selection, 13);  // 90 % of 15 is 13.5
  EXPECT_GE(s.coefficients_within_3sigma_fraction, 0.95);
}

TEST(FogThermal, ModelJsonRoundTrip) {
  ThermalFitResult fit;
  fit.model = CampaignDriftModel();
  for (int k = 0; k < ThermalDriftModel::kNumTerms; ++k) fit.kept[k] = fit.model.k_dph[k] != 0;
  ThermalFitOptions opts;
  opts.rate.window_s = 420;
  const ThermalModelFile m = ThermalModelFromJson(ThermalFitToJson(fit, opts), "model.json");
  for (int k = 0; k < ThermalDriftModel::kNumTerms; ++k) EXPECT_EQ(m.model.k_dph[k], fit.model.k_dph[k]);
  EXPECT_EQ(m.rate.window_s, 420);
  EXPECT_THROW(ThermalModelFromJson(Json{{"terms", {{"K44", 1.0}}}}, "m.json"), InputError);
}

TEST(FogThermal, BadInputIsInputError) {
  ThermalBenchOptions o;
  o.duration_s = 3600;
  ThermalRun run = ToRun(SimulateThermalRun(o), "bad.csv");
  ThermalRun unsorted = run;
  std::swap(unsorted.t_s[5], unsorted.t_s[6]);
  EXPECT_THROW(FitThermalDrift({unsorted}, ThermalFitOptions{}), InputError);
  ThermalRun nan_row = run;
  nan_row.w_dph[7] = std::nan("");
  EXPECT_THROW(FitThermalDrift({nan_row}, ThermalFitOptions{}), InputError);
  ThermalRun short_run = run;
  for (auto* v : {&short_run.t_s, &short_run.w_dph, &short_run.ref_dph, &short_run.temp_c}) v->resize(1200);
  EXPECT_THROW(FitThermalDrift({short_run}, ThermalFitOptions{}), InputError);  // 20 bins < 40
  // A 1e12 s gap between two rows: refused by name, not bins allocated over the whole span (ASan:
  // out of memory, 133 GB).
  ThermalRun gap = run;
  for (size_t i = gap.t_s.size() / 2; i < gap.t_s.size(); ++i) gap.t_s[i] += 1e12;
  try {
    FitThermalDrift({gap}, ThermalFitOptions{});
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("bad.csv: column 't_s': gap of"));
  }
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

TEST(FogThermal, ReferenceFromLatitudeAndAxisWhenNoRefColumn) {
  const std::string dir = testing::TempDir("ref");
  ThermalBenchOptions o;
  o.duration_s = 600;
  const ThermalBenchRun sim = SimulateThermalRun(o);
  WriteCsv(dir + "/noref.csv", {"t_s", "w_dph", "temp_c"}, {sim.t_s, sim.w_dph, sim.temp_c});
  const ThermalRun up = ReadThermalRun(dir + "/noref.csv", 50.05, "up");
  EXPECT_NEAR(up.ref_dph.front(), 15.041067 * std::sin(50.05 * kDegToRad), 1e-9);
  EXPECT_NEAR(up.ref_dph.front(), sim.ref_dph.front(), 1e-9);  // the simulator's axis is "up"
  const ThermalRun north = ReadThermalRun(dir + "/noref.csv", 50.05, "north");
  EXPECT_NEAR(north.ref_dph.front(), 15.041067 * std::cos(50.05 * kDegToRad), 1e-9);
  EXPECT_THROW(ReadThermalRun(dir + "/noref.csv", std::nan(""), "up"), InputError);
  EXPECT_THROW(ReadThermalRun(dir + "/noref.csv", 50.05, "sideways"), InputError);
}

}  // namespace
}  // namespace ssiu
