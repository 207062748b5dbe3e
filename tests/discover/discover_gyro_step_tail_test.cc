// The p-value of the bias step's scan (StepScanLogP: James, James & Siegmund's tail capped by the
// Hunter-Worsley bound along the neighbouring positions) against the maximum of the change-point statistic
// simulated on white noise, and against the exact tail where the positions are independent.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "discover/discover_gyro_internal.h"

namespace ssiu::discover_internal {
namespace {

// A step in the mean of n white samples, split after k for k in [n/20, n - n/20): the statistic Z_k^2 with
// Z_k = (S_k - k S_n / n) / sqrt(k (n - k) / n) (the step projected off the mean), and the neighbours'
// correlation sqrt(k (n - k - 1) / ((k + 1) (n - k))).
std::vector<StepPoint> WhiteNoiseProfile(const std::vector<double>& x) {
  const int n = static_cast<int>(x.size());
  double total = 0;
  for (double v : x) total += v;
  std::vector<StepPoint> profile;
  double s = 0;
  for (int k = 1; k < n - n / 20; ++k) {
    s += x[k - 1];
    if (k < n / 20) continue;
    const double z = (s - k * total / n) / std::sqrt(k * (n - k) / static_cast<double>(n));
    const double rho = k == n / 20 ? StepPoint::kNoNeighbour : std::sqrt((k - 1.0) * (n - k) / (k * (n - k + 1.0)));
    profile.push_back({0, static_cast<double>(k), z * z, rho});
  }
  return profile;
}

double MaxW(const std::vector<StepPoint>& profile) {
  double w = 0;
  for (const auto& p : profile) w = std::max(w, p.w);
  return w;
}

// The most false alarms at level alpha that `runs` scans may give: alpha runs plus 3 binomial sigmas.
double FalseAlarmCeiling(double alpha, int runs) { return alpha * runs + 3 * std::sqrt(alpha * (1 - alpha) * runs); }

TEST(DiscoverGyroStepTail, FalseAlarmRateOfTheScanOnWhiteNoiseIsAtMostItsLevel) {
  // 3000 logs of 400 bins, no step: the fraction with p below alpha is the scan's false-alarm rate. It is at
  // most alpha (3 binomial sigmas of slack) and near it, where the Bonferroni count over the 360 positions
  // holds it more than five times below (the Hunter-Worsley bound alone, about 2.5 times below).
  std::mt19937_64 rng(20261130);
  std::normal_distribution<double> gauss;
  const int runs = 3000, n = 400;
  int below_05 = 0, below_01 = 0, bonferroni_05 = 0;
  for (int i = 0; i < runs; ++i) {
    std::vector<double> x(n);
    for (double& v : x) v = gauss(rng);
    const auto profile = WhiteNoiseProfile(x);
    const double w = MaxW(profile), p = std::exp(StepScanLogP(profile, w));
    below_05 += p < 0.05, below_01 += p < 0.01;
    bonferroni_05 += profile.size() * std::erfc(std::sqrt(w / 2)) < 0.05;
  }
  EXPECT_LE(below_05, FalseAlarmCeiling(0.05, runs));
  EXPECT_LE(below_01, FalseAlarmCeiling(0.01, runs));
  EXPECT_GE(below_05, 0.7 * 0.05 * runs);
  EXPECT_GE(below_01, 0.5 * 0.01 * runs);
  EXPECT_LT(bonferroni_05, 0.2 * below_05);
}

TEST(DiscoverGyroStepTail, FalseAlarmRateUnderAWanderIsAtMostItsLevel) {
  // The library's own scan (ScanStep, GLS-whitened by the noise model) on 1500 logs of 300 bins of white noise
  // plus a Gauss-Markov wander four times its variance, correlation 0.9 per bin, whitened by that model: the
  // whitened steps decorrelate (neighbours at rho 0.78 in the median, against 0.99 on white noise), so the tail
  // leans on the Hunter-Worsley cap: the false-alarm rate at most alpha and at least the Bonferroni count's
  // (measured 2.6 % and 2.3 % below 0.05: both conservative there).
  std::mt19937_64 rng(1130);
  std::normal_distribution<double> gauss;
  const int runs = 1500, m = 300;
  NoiseModel nm;
  nm.var_w = 1, nm.var_g = 4, nm.phi = 0.9;
  nm.Prepare(m);
  Design d;
  d.bins.resize(1);
  d.bins[0].bin_s = 10;
  for (int k = 0; k < m; ++k) d.bins[0].t_s.push_back(10.0 * k + 5);
  d.offset = {0};
  d.n = m;
  const MatrixXd bw = nm.Whiten(VectorXd::Ones(m));
  int below_05 = 0, below_01 = 0, bonferroni_05 = 0;
  double rho_median = 0;
  for (int i = 0; i < runs; ++i) {
    VectorXd y(m);
    double g = std::sqrt(nm.var_g) * gauss(rng);
    for (int k = 0; k < m; ++k) {
      if (k > 0) g = nm.phi * g + std::sqrt(nm.var_g * (1 - nm.phi * nm.phi)) * gauss(rng);
      y(k) = g + std::sqrt(nm.var_w) * gauss(rng);
    }
    VectorXd res = nm.Whiten(y);
    res -= (bw.col(0).dot(res) / bw.col(0).squaredNorm()) * bw.col(0);
    StepScan sc;
    ScanStep(d, {nm}, bw, res, 1.0, &sc);
    const double p = std::exp(StepScanLogP(sc.profile, sc.best_w));
    below_05 += p < 0.05, below_01 += p < 0.01;
    bonferroni_05 += sc.positions * std::erfc(std::sqrt(sc.best_w / 2)) < 0.05;
    if (i == 0) {
      std::vector<double> rho;
      for (const auto& pt : sc.profile)
        if (pt.rho_prev != StepPoint::kNoNeighbour) rho.push_back(pt.rho_prev);
      std::nth_element(rho.begin(), rho.begin() + rho.size() / 2, rho.end());
      rho_median = rho[rho.size() / 2];
    }
  }
  EXPECT_LT(rho_median, 0.9);
  EXPECT_LE(below_05, FalseAlarmCeiling(0.05, runs));
  EXPECT_LE(below_01, FalseAlarmCeiling(0.01, runs));
  EXPECT_GE(below_05, bonferroni_05);
  EXPECT_GE(below_05, 0.3 * 0.05 * runs);
}

TEST(DiscoverGyroStepTail, IndependentPositionsGiveTheBonferroniCountsBound) {
  // With uncorrelated neighbours the bound is sum_j P(|Z_j| >= b) minus nothing but the pairs' joint
  // exceedances: between the exact tail of the maximum of N independent chi^2_1, 1 - (1 - q)^N, and N q.
  for (double w : {9.0, 16.0, 30.0, 60.0}) {
    const int npos = 500;
    std::vector<StepPoint> profile(npos, StepPoint{0, 0.0, 1.0, 0.0});
    profile[0].rho_prev = StepPoint::kNoNeighbour;
    const double q = std::erfc(std::sqrt(w / 2)), log_p = StepScanLogP(profile, w);
    const double exact = -std::expm1(npos * std::log1p(-q));
    EXPECT_GE(log_p, std::log(exact) - 1e-6) << w;
    EXPECT_LE(log_p, std::min(0.0, std::log(npos * q)) + 1e-6) << w;
  }
  // Far in the tail (w = 2000, where phi(b) underflows a double) it stays finite and follows ln(N q).
  std::vector<StepPoint> far(10, StepPoint{0, 0.0, 1.0, 0.0});
  far[0].rho_prev = StepPoint::kNoNeighbour;
  const double b = std::sqrt(2000.0), ln_q = -1000 - std::log(b) + 0.5 * std::log(2 / kPi);
  EXPECT_NEAR(StepScanLogP(far, 2000), std::log(10.0) + ln_q, 1e-3);
}

}  // namespace
}  // namespace ssiu::discover_internal
