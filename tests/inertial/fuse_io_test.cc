// Bad gyro / star-tracker logs: a one-line InputError naming the file and the field.
#include <fstream>

#include "core/error.h"
#include "inertial/fuse.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

std::string Write(const std::string& dir, const std::string& name, const std::string& text) {
  const std::string p = dir + "/" + name;
  std::ofstream(p) << text;
  return p;
}

template <typename F>
std::string ErrorOf(F f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(FuseIo, BadGyroLogs) {
  const std::string d = testing::TempDir("fuseio");
  using ::testing::HasSubstr;
  const std::string missing = Write(d, "m.csv", "t_s,wx_dph,wy_dph\n0.01,1,2\n0.02,1,2\n");
  EXPECT_THAT(ErrorOf([&] { ReadGyroLog(missing); }), HasSubstr("wz_dph"));
  const std::string nan = Write(d, "n.csv", "t_s,g1_dph,g2_dph,g3_dph,g4_dph\n0.01,1,2,3,4\n0.02,1,nan,3,4\n");
  EXPECT_THAT(ErrorOf([&] { ReadGyroLog(nan, 4); }), HasSubstr("g2_dph"));
  const std::string unsorted = Write(d, "u.csv", "t_s,wx_dph,wy_dph,wz_dph\n0.02,1,2,3\n0.01,1,2,3\n");
  EXPECT_THAT(ErrorOf([&] { ReadGyroLog(unsorted); }), HasSubstr("t_s"));
  const std::string few = Write(d, "f.csv", "t_s,wx_dph,wy_dph,wz_dph\n0.01,1,2,3\n");
  EXPECT_THAT(ErrorOf([&] { ReadGyroLog(few); }), HasSubstr("too few"));
  const std::string none = Write(d, "x.csv", "t_s,a\n0.01,1\n0.02,1\n");
  EXPECT_THAT(ErrorOf([&] { ReadGyroLog(none); }), HasSubstr("g1_dph"));
  // Extra columns are kept and ignored; the g-columns are counted.
  const std::string ok =
      Write(d, "ok.csv", "t_s,g1_dph,g2_dph,g3_dph,g4_dph,temp_c\n0.01,1,2,3,4,20\n0.02,1,2,3,4,20\n");
  const GyroLog log = ReadGyroLog(ok);
  EXPECT_FALSE(log.body_rates);
  EXPECT_EQ(log.rates_dph[1].size(), 4);
  EXPECT_EQ(log.rates_dph[1][3], 4.0);
}

TEST(FuseIo, BadStarTrackerLogs) {
  const std::string d = testing::TempDir("fuseio_st");
  using ::testing::HasSubstr;
  EXPECT_THAT(ErrorOf([&] { ReadStarTrackerLog(Write(d, "a.csv", "t_s,qw,qx,qy\n0,1,0,0\n")); }), HasSubstr("qz"));
  EXPECT_THAT(ErrorOf([&] { ReadStarTrackerLog(Write(d, "b.csv", "t_s,qw,qx,qy,qz\n1,1,0,0,0\n0,1,0,0,0\n")); }),
              HasSubstr("t_s"));
  EXPECT_THAT(ErrorOf([&] { ReadStarTrackerLog(Write(d, "c.csv", "t_s,qw,qx,qy,qz\n0,0,0,0,0\n")); }),
              HasSubstr("quaternion"));
  EXPECT_THAT(
      ErrorOf([&] {
        ReadStarTrackerLog(Write(d, "e.csv", "t_s,qw,qx,qy,qz,sigma_cross_arcsec,sigma_roll_arcsec\n0,1,0,0,0,5,-1\n"));
      }),
      HasSubstr("sigma"));
}

TEST(FuseIo, GyroCountMismatchAndNoStarData) {
  GyroLog log;
  log.file = "g.csv";
  log.t_s = {0.01, 0.02};
  log.rates_dph = {GyroVec::Zero(5), GyroVec::Zero(5)};
  StarTrackerLog st;
  st.t_s = {0.0};
  st.q_inertial_from_body = {Quat::Identity()};
  EXPECT_THROW(Fuse(log, st, DefaultFourFogUnit(), FuseOptions{}), InputError);
  log.rates_dph = {GyroVec::Zero(4), GyroVec::Zero(4)};
  st.t_s = {5.0};
  EXPECT_EQ(Fuse(log, st, DefaultFourFogUnit(), FuseOptions{}).status, FuseStatus::kNoStarData);
}

}  // namespace
}  // namespace ssiu
