// `ssiu run`'s mission clock and spacecraft velocity (issue 15): frames are rendered with the stars'
// aberration at start_utc + t and the processor removes it, so the per-frame star solutions stay at
// their noise level instead of being off by the ~20 arcsec of aberration.
#include <cmath>
#include <cstdio>

#include "core/astrometry.h"
#include "core/attitude.h"
#include "core/error.h"
#include "sim/mission.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

TEST(MissionSky, ClockAndVelocityKeysRoundTripAndBadOnesAreRefused) {
  MissionConfig c = DefaultMissionConfig();
  c.start_utc = "2031-03-01T10:00:00Z";
  c.velocity_kms = Vec3(1.0, -7.0, 2.5);
  const MissionConfig back = MissionConfigFromJson(MissionConfigToJson(c), "cfg.json");
  EXPECT_EQ(back.start_utc, c.start_utc);
  EXPECT_EQ(back.velocity_kms, c.velocity_kms);
  auto error = [](Json j) {
    try {
      MissionConfigFromJson(j, "cfg.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  Json j = MissionConfigToJson(c);
  j["start_utc"] = "2031-02-30T00:00:00Z";
  EXPECT_THAT(error(j), HasSubstr("start_utc"));
  j = MissionConfigToJson(c);
  j["velocity_kms"] = {1, 2};
  EXPECT_THAT(error(j), HasSubstr("cfg.json: field 'velocity_kms'"));
  j["velocity_kms"] = {1000, 0, 0};
  EXPECT_THAT(error(j), HasSubstr("cfg.json: field 'velocity_kms'"));
}

TEST(MissionSky, ProcessorRemovesTheAberrationTheFramesCarry) {
  MissionConfig c = DefaultMissionConfig();
  c.duration_s = 20;
  c.frame_rate_hz = 0.5;
  c.seed = 5;
  c.heads.resize(1);
  c.score_after_s = 0;
  c.velocity_kms = Vec3(-3.0, 6.0, 3.0);  // LEO, 7.3 km/s
  // The frames carry the aberration at the mission clock's time.
  const MissionData data = SimulateMission(c);
  const SimulatedFrame f = SimulateMissionFrame(c, data, testing::Bsc(), 4, 0);
  const Quat q_sensor = TrueAttitudeAt(data, data.frame_t_s[4]) * c.heads[0].q_body_from_sensor;
  const Vec3 bore = q_sensor * Vec3::UnitZ();
  const UtcTime t = AddSeconds(MissionSky(c).time, data.frame_t_s[4]);
  const double aberration_arcsec =
      std::acos(
          std::min(1.0, AberrateDirection(bore, EarthBarycentricVelocityMS(t) + c.velocity_kms * 1e3).dot(bore))) *
      kRadToArcsec;
  EXPECT_GT(aberration_arcsec, 15.0);
  // ... which the processor removes: the star-only solutions' cross-boresight error is a fraction of it.
  const MissionResult r = RunMission(c, testing::Bsc());
  std::printf("aberration at the boresight %.1f arcsec; star-only cross rms %.2f arcsec (max %.2f), %d/%d solved\n",
              aberration_arcsec, r.star_only.cross_rms_arcsec, r.star_only.cross_max_arcsec, r.frames_solved, r.frames);
  EXPECT_EQ(r.frames_solved, r.frames);
  EXPECT_LT(r.star_only.cross_max_arcsec, aberration_arcsec / 3);
}

}  // namespace
}  // namespace ssiu
