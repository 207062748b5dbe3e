// Monte Carlo of the noise-term fit (label `long`): 50 one-hour 100 Hz logs of white rate noise plus
// rate random walk of known strength. Reports bias, scatter and how the reported sigma compares with
// the scatter; asserts the acceptance (ARW within 10%, RRW within 30%) in at least 95% of runs.
#include <cmath>
#include <cstdio>

#include "analysis/allan.h"
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
    ASSERT_EQ(f.status, "fitted");
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

}  // namespace
}  // namespace ssiu
