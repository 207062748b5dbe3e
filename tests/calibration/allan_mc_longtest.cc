// Monte Carlo of the noise-term fit (label `long`): 50 one-hour 100 Hz logs of white rate noise plus
// rate random walk of known strength. Reports bias, scatter and how the reported sigma compares with
// the scatter; asserts the acceptance (ARW within 10%, RRW within 30%) in at least 95% of runs.
#include <cmath>
#include <cstdio>

#include "calibration/allan.h"
#include "core/rng.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(AllanMonteCarlo, ArwAndRrwAcceptanceAndSigmaCalibration) {
  const double fs = 100, n = 1.0, k = std::sqrt(3.0) * n / 20;  // lines cross at 20 s
  const int runs = 50;
  int arw_ok = 0, rrw_ok = 0;
  double sn = 0, snn = 0, sk = 0, skk = 0, sig_n = 0, sig_k = 0;
  for (int run = 0; run < runs; ++run) {
    Rng rng(1000 + run);
    std::vector<double> r(360000);
    double b = 0;
    for (double& v : r) {
      b += k / std::sqrt(fs) * rng.Normal();
      v = n * std::sqrt(fs) * rng.Normal() + b;
    }
    const NoiseFit f = FitNoiseTerms(OverlappingAllanDeviation(r, fs));
    ASSERT_EQ(f.status, FitStatus::kFitted);
    const double en = f.arw.value / n, ek = f.rrw.value / k;
    arw_ok += std::abs(en - 1) <= 0.10;
    rrw_ok += std::abs(ek - 1) <= 0.30;
    sn += en;
    snn += en * en;
    sk += ek;
    skk += ek * ek;
    sig_n += f.arw.sigma / n / runs;
    sig_k += f.rrw.sigma / k / runs;
  }
  const double mn = sn / runs, mk = sk / runs;
  const double sdn = std::sqrt(snn / runs - mn * mn), sdk = std::sqrt(skk / runs - mk * mk);
  std::printf("ARW: mean ratio %.4f, scatter %.4f, mean reported sigma %.4f; within 10%%: %d/%d\n", mn, sdn, sig_n,
              arw_ok, runs);
  std::printf("RRW: mean ratio %.4f, scatter %.4f, mean reported sigma %.4f; within 30%%: %d/%d\n", mk, sdk, sig_k,
              rrw_ok, runs);
  EXPECT_GE(arw_ok, runs * 95 / 100);
  EXPECT_GE(rrw_ok, runs * 95 / 100);
  EXPECT_NEAR(mn, 1.0, 0.02);
  EXPECT_NEAR(mk, 1.0, 0.10);
}

TEST(AllanMonteCarlo, BiasInstabilityOfFlickerOverSeeds) {
  // Flicker of known B as Gauss-Markov processes with correlation times 0.3..3000 s a factor
  // sqrt(10) apart, each of variance B^2 ln(sqrt(10)) / pi (PSD sum ~ B^2 / (2 pi f)), plus white
  // noise crossing it near 1 s; 20 one-hour 100 Hz logs.
  const double fs = 100, b = 1.0, n = 0.5, q = std::sqrt(10.0);
  const int runs = 20;
  double sb = 0, sbb = 0, sf = 0, sig = 0;
  int order_ok = 0;
  for (int run = 0; run < runs; ++run) {
    Rng rng(2000 + run);
    std::vector<double> r(360000, 0.0);
    const double var = b * b * std::log(q) / M_PI;
    for (double t = 0.3; t <= 3000 * 1.0001; t *= q) {
      const double phi = std::exp(-1 / (fs * t)), drive = std::sqrt(var * (1 - phi * phi));
      double x = std::sqrt(var) * rng.Normal();
      for (double& v : r) {
        x = phi * x + drive * rng.Normal();
        v += x;
      }
    }
    for (double& v : r) v += n * std::sqrt(fs) * rng.Normal();
    const NoiseFit f = FitNoiseTerms(OverlappingAllanDeviation(r, fs));
    ASSERT_EQ(f.status, FitStatus::kFitted);
    const double e = f.bias_instability.value / b;
    order_ok += e > 0.5 && e < 2;
    sb += e / runs;
    sbb += e * e / runs;
    sf += f.adev_min / 0.664 / b / runs;
    sig += f.bias_instability.sigma / b / runs;
  }
  std::printf(
      "B (fit) / truth: mean %.3f, scatter %.3f, mean reported sigma %.3f, within a factor 2: %d/%d; "
      "floor reading / truth: mean %.3f\n",
      sb, std::sqrt(sbb - sb * sb), sig, order_ok, runs, sf);
  EXPECT_EQ(order_ok, runs);
}

}  // namespace
}  // namespace ssiu
