#include "inertial/fdi.h"

#include "core/error.h"
#include "core/rng.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// Four-FOG outputs with biases and white noise; a step on `fault_gyro` from t_fault.
TEST(Fdi, ParityDetectsStepOnEachGyroAndStaysQuietWithout) {
  const GyroUnit u = DefaultFourFogUnit();
  const double dt = 0.01, sigma = 0.01 * 60 / std::sqrt(dt);  // ARW 0.01 deg/sqrt(h)
  const GyroVec biases = (GyroVec(4) << 2.0, -3.0, 1.5, 2.5).finished();
  for (int fault_gyro = 0; fault_gyro <= 4; ++fault_gyro) {  // 0: no fault
    ParityMonitor m(u.Axes(), std::vector<bool>(4, true), GyroVec::Constant(4, sigma), dt, FdiOptions{});
    Rng rng(100 + fault_gyro);
    double t_alarm = -1;
    for (int k = 1; k <= 180000 && t_alarm < 0; ++k) {  // 30 min
      const double t = k * dt;
      GyroVec g = u.Axes() * Vec3(100 * std::sin(t / 50), 360, -20) + biases;
      for (int i = 0; i < 4; ++i) g[i] += sigma * rng.Normal();
      if (fault_gyro > 0 && t > 900) g[fault_gyro - 1] += 20.0;
      if (m.Feed(t, g)) t_alarm = t;
    }
    if (fault_gyro == 0) {
      EXPECT_LT(t_alarm, 0) << "false alarm";
    } else {
      EXPECT_GT(t_alarm, 900) << "gyro " << fault_gyro;
      EXPECT_LT(t_alarm, 960) << "gyro " << fault_gyro;
      // At the alarm the window is partly filled: the jump has the sign of 20 * V(gyro) and at
      // most its size.
      const double full = 20.0 * m.V()(0, fault_gyro - 1);
      EXPECT_GT(m.jump()[0] * full, 0.0);
      EXPECT_LT(std::abs(m.jump()[0]), std::abs(full) + 0.5);
    }
  }
}

TEST(Fdi, IsolationRules) {
  FdiOptions o;
  const std::vector<bool> all(4, true);
  EXPECT_EQ(IsolateFromResiduals((GyroVec(4) << 0.3, 19.5, -0.8, 0.5).finished(), all, o), 1);
  EXPECT_EQ(IsolateFromResiduals((GyroVec(4) << 0.3, 9.5, -8.0, 0.5).finished(), all, o), -1);  // ambiguous
  EXPECT_EQ(IsolateFromResiduals((GyroVec(4) << 0.3, 0.5, -0.2, 0.1).finished(), all, o), -1);  // too small
  // With five gyros the parity direction alone points at the failed one.
  GyroUnit u = DefaultFourFogUnit();
  u.axes_body.push_back(Vec3(1, -1, 0).normalized());
  u.gyros.push_back(GyroErrorModel{});
  const std::vector<bool> five(5, true);
  const GyroParity v = ParityMatrix(u.Axes(), five);
  // A gyro whose parity column is parallel to no other one is isolated; otherwise the answer is
  // "cannot tell" (-1), never a wrong gyro.
  int isolated = 0;
  for (int i = 0; i < 5; ++i) {
    bool unique = true;
    for (int j = 0; j < 5; ++j) {
      if (j != i && std::abs(v.col(i).normalized().dot(v.col(j).normalized())) >= o.parity_isolation_cos) unique = false;
    }
    const int got = IsolateFromParity(v, v.col(i) * 20.0, five, o);
    EXPECT_EQ(got, unique ? i : -1) << "gyro " << i;
    isolated += got == i;
  }
  EXPECT_GE(isolated, 3);
  // With one parity relation it cannot.
  const GyroParity v4 = ParityMatrix(DefaultFourFogUnit().Axes(), all);
  EXPECT_EQ(IsolateFromParity(v4, v4.col(0) * 20.0, all, o), -1);
}

TEST(Fdi, OptionsCheck) {
  FdiOptions o;
  o.window_s = 0;
  EXPECT_THROW(o.Check(), InputError);
  o = FdiOptions{};
  o.isolation_ratio = 0.5;
  EXPECT_THROW(o.Check(), InputError);
}

}  // namespace
}  // namespace ssiu
