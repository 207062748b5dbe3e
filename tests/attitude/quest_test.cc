#include "attitude/quest.h"

#include <cmath>
#include <memory>

#include "core/attitude.h"
#include "core/catalog.h"
#include "core/rng.h"
#include "identify/synthetic.h"
#include "identify/wahba_svd.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// Star-tracker-like observations: directions within `half_fov` of +Z in the sensor frame.
std::vector<WahbaObservation> MakeObs(const Quat& q, int n, double sigma_rad, double half_fov, Rng* rng,
                                      bool noisy = true) {
  std::vector<WahbaObservation> obs;
  const Mat3 r = q.toRotationMatrix();
  for (int i = 0; i < n; ++i) {
    const double th = half_fov * std::sqrt(rng->Uniform()), ph = 2 * kPi * rng->Uniform();
    const Vec3 b(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
    Vec3 bn = b;
    if (noisy) bn = (b + sigma_rad * Vec3(rng->Normal(), rng->Normal(), rng->Normal())).normalized();
    obs.push_back({bn, r * b, sigma_rad});
  }
  return obs;
}

// Error rotation in the sensor frame: q_est = q_true * [1, dtheta / 2].
Vec3 SensorError(const Quat& q_est, const Quat& q_true) {
  Quat d = q_true.conjugate() * q_est;
  if (d.w() < 0) d.coeffs() = -d.coeffs();
  return 2 * d.vec();
}

TEST(Quest, AgreesWithDavenportAndSvd) {
  for (int i = 0; i < 200; ++i) {
    Rng rng(10 + i);
    const Quat q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
    const auto obs = MakeObs(q, 3 + i % 20, 1e-4 * (1 + i % 3), 0.15, &rng);
    const AttitudeSolution s = SolveQuest(obs);
    std::vector<VectorPair> pairs;
    for (const auto& o : obs) pairs.push_back({o.b_sensor, o.r_inertial, 1 / (o.sigma_rad * o.sigma_rad)});
    EXPECT_THAT(s.q_inertial_from_sensor, QuaternionNear(SolveDavenport(obs), 1e-3)) << "case " << i;
    EXPECT_THAT(s.q_inertial_from_sensor, QuaternionNear(SolveWahbaSvd(pairs), 1e-3)) << "case " << i;
    EXPECT_THAT(s.q_inertial_from_sensor, QuaternionNear(q, 5 * std::sqrt(s.covariance_rad2.trace()) * kRadToArcsec));
  }
}

TEST(Quest, HandlesRotationsNear180Degrees) {
  Rng rng(3);
  for (const Vec3& axis : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(1, 2, 3).normalized()}) {
    const Quat q(Eigen::AngleAxisd(kPi - 1e-9, axis));
    const auto obs = MakeObs(q, 10, 1e-5, 0.15, &rng, /*noisy=*/false);
    EXPECT_THAT(SolveQuest(obs).q_inertial_from_sensor, QuaternionNear(q, 1e-4));
  }
}

TEST(Quest, CovarianceMatchesMonteCarloAndNeesIsConsistent) {
  // 2000 noisy solves of one geometry: sample covariance of the sensor-frame error vs Shuster's P,
  // and the mean NEES against its chi-square spread (6000 dof: mean 3, sd 0.077).
  Rng geo(1);
  const Quat q = QuatFromRaDecRoll(2.0, -0.5, 1.0);
  const auto obs0 = MakeObs(q, 12, 5e-5, 0.14, &geo, false);
  const int kTrials = 2000;
  Mat3 sample = Mat3::Zero();
  double nees = 0;
  Rng rng(2);
  Mat3 p = Mat3::Identity();
  for (int t = 0; t < kTrials; ++t) {
    auto obs = obs0;
    for (auto& o : obs) o.b_sensor = (o.b_sensor + o.sigma_rad * Vec3(rng.Normal(), rng.Normal(), rng.Normal())).normalized();
    const AttitudeSolution s = SolveQuest(obs);
    p = s.covariance_rad2;
    const Vec3 e = SensorError(s.q_inertial_from_sensor, q);
    sample += e * e.transpose() / kTrials;
    nees += e.dot(p.inverse() * e) / kTrials;
  }
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(std::sqrt(sample(i, i)), std::sqrt(p(i, i)), 0.06 * std::sqrt(p(i, i))) << i;
  EXPECT_GT(nees, 3 - 2.5 * 0.077);
  EXPECT_LT(nees, 3 + 2.5 * 0.077);
  // A star tracker is weak in roll: sigma_roll >> sigma_cross for a 16 deg field.
  const AttitudeSolution s = SolveQuest(obs0);
  EXPECT_GT(s.sigma_roll_rad, 4 * s.sigma_cross_rad);
}

TEST(MultiHead, TwoOrthogonalHeadsRemoveTheRollWeakness) {
  Rng rng(9);
  const Quat q_body = QuatFromRaDecRoll(0.7, 0.2, 0.3);
  const Quat m1 = Quat::Identity();
  const Quat m2(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX()));  // head 2 looks along body -Y
  std::vector<Identification> heads(2);
  for (int h = 0; h < 2; ++h) {
    const Quat mount = h == 0 ? m1 : m2;
    const Quat q_sensor = q_body * mount;  // inertial <- body <- sensor
    for (const auto& o : MakeObs(q_sensor, 15, 5e-5, 0.14, &rng)) {
      StarMatch m;
      m.b_sensor = o.b_sensor, m.r_inertial = o.r_inertial, m.sigma_rad = o.sigma_rad;
      heads[h].matches.push_back(m);
    }
    heads[h].status = "solved";
  }
  const AttitudeSolution one = SolveAttitude(heads[0]);
  const AttitudeSolution both = SolveMultiHead(heads, {m1, m2});
  ASSERT_EQ(both.status, "solved");
  EXPECT_THAT(both.q_inertial_from_sensor, QuaternionNear(q_body, 20.0));
  EXPECT_GT(one.sigma_roll_rad, 5 * one.sigma_cross_rad);
  EXPECT_LT(both.sigma_roll_rad, 2 * both.sigma_cross_rad);
  EXPECT_LT(both.sigma_roll_rad, one.sigma_roll_rad / 4);
}

TEST(SolveAttitude, SyntheticFrameErrorsAgreeWithReportedCovariance) {
  CatalogBuildOptions co;
  co.fov_deg = 16.6;
  const StarIdentifier id(BuildSolverCatalog(LoadSourceCatalog(DefaultBscPath()), co));
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  IdentifyOptions io;
  io.systematic_px = 0;
  double nees = 0;
  int n = 0;
  for (int i = 0; i < 100; ++i) {
    Rng rng(300 + i);
    const Quat q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
    testing::SyntheticOptions so;
    so.sigma_px = 0.1;
    const auto f = testing::MakeSyntheticFrame(id.catalog(), cam, q, so, &rng);
    const AttitudeSolution s = SolveAttitude(id.Identify(f.centroids, cam, io));
    if (s.status != "solved") continue;
    const Vec3 e = SensorError(s.q_inertial_from_sensor, q);
    nees += e.dot(s.covariance_rad2.inverse() * e);
    ++n;
  }
  ASSERT_GE(n, 99);
  // Mean NEES of n frames: chi-square with 3n dof / n; two-sided 99% bounds for n = 100:
  // 3 +/- 2.576 sqrt(6 / 100) = [2.37, 3.63] (over 400 such frames we measured mean 3.10,
  // median 2.36, 95th percentile 8.4 against chi-square(3)'s 3, 2.37, 7.8).
  EXPECT_GT(nees / n, 2.37);
  EXPECT_LT(nees / n, 3.63);
}

}  // namespace
}  // namespace ssiu
