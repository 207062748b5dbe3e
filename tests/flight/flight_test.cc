// The C interface of the unit's processor (flight/ssiu_flight.h): the same answers as the C++
// processor on a simulated two-head mission, against the simulator's truth; its configuration text;
// and a loop that bad inputs cannot break (issue 26 item 6): NaN and out-of-order gyro samples,
// frames of the wrong size, a corrupt catalog blob at init.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "core/attitude.h"
#include "core/output.h"
#include "flight/flight_config.h"
#include "flight/flight_print.h"
#include "flight/ssiu_flight.h"
#include "identify/star_catalog.h"
#include "sim/frame_sim.h"
#include "sim/mission.h"
#include "testing/sim_frames.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

MissionConfig SmallMission() {
  MissionConfig c = DefaultMissionConfig();
  c.duration_s = 16;
  c.frame_rate_hz = 1;
  c.seed = 7;
  return WithUnitKnowledge(c);
}

// The mission's gyro samples, truth and catalog, made once per program.
struct Data {
  MissionConfig config = SmallMission();
  MissionData data;
  std::string blob;  // catalog.bin of head 1's catalog
  uint32_t crc = 0;
};
const Data& TheData() {
  static const Data d = [] {
    Data x;
    x.data = SimulateMission(x.config);
    x.blob = SolverCatalogBytes(MakeIdentifierForCamera("", x.config.heads[0].camera, 0.0).catalog());
    x.crc = Crc32(x.blob.data(), x.blob.size());
    return x;
  }();
  return d;
}

// Frame set i (an image a head), simulated on first use: rendering is most of the data's cost (nine
// tenths under qemu), and most tests need a few sets or none.
const std::vector<Image16>& FrameSet(size_t i) {
  const Data& d = TheData();
  static std::vector<std::vector<Image16>> sets(d.data.frame_t_s.size());
  if (sets.at(i).empty()) {
    for (size_t h = 0; h < d.config.heads.size(); ++h)
      sets[i].push_back(
          SimulateMissionFrame(d.config, d.data, testing::Bsc(), static_cast<int>(i), static_cast<int>(h)).image);
  }
  return sets[i];
}

ssiu_flight_config ConfigFor(const Data& d) {
  ssiu_flight_config c = FlightConfigFor(d.config.heads, d.config.unit, d.config.processor, d.config.start_utc,
                                         d.config.velocity_kms);
  c.catalog_crc32 = d.crc;
  return c;
}

// A handle in memory of its own, shut down at the end.
// The handle's memory: 16-byte aligned as ssiu_flight_init asks (std::max_align_t is only 8 on 32-bit
// ARM, where the handle's Eigen members want 16).
struct alignas(16) Block {
  unsigned char bytes[16];
};

struct Handle {
  std::vector<Block> memory;
  ssiu_flight* f = nullptr;
  ssiu_result rc = SSIU_ERR_INTERNAL;
  Handle(const ssiu_flight_config& c, const std::string& blob) {
    memory.resize(std::max<size_t>(ssiu_flight_memory_bytes(&c), 4096) / sizeof(Block) + 1);
    rc = ssiu_flight_init(&c, blob.data(), blob.size(), memory.data(), memory.size() * sizeof(Block), &f);
  }
  ~Handle() { ssiu_flight_shutdown(f); }
  const char* why() const { return reinterpret_cast<const char*>(memory.data()); }
};

ssiu_frame FrameOf(const Image16& im) {
  ssiu_frame f;
  std::memset(&f, 0, sizeof f);
  f.pixels = im.pixels.data();
  f.width_px = im.width;
  f.height_px = im.height;
  return f;
}

Quat QuatOf(const double q[4]) { return Quat(q[0], q[1], q[2], q[3]); }

// The same attitude, measured by AttitudeErrorRad: exactly 0 on x86-64, but where the compiler fuses
// multiplications and additions (aarch64: fused multiply-add is the default) the quaternion product of
// two equal attitudes keeps one product's rounding error, a residual of a few 1e-18 rad.
constexpr double kSameAttitudeRad = 1e-15;

// Feeds the mission through the handle in time order (frames before the first gyro sample after
// them), with `bad_gyro(k, &t, g)` to spoil sample k. Returns the frame reports.
template <typename Spoil>
std::vector<ssiu_frame_report> Replay(const Data& d, ssiu_flight* f, Spoil spoil,
                                      std::vector<ssiu_gyro_status>* gyro_status = nullptr) {
  std::vector<ssiu_frame_report> reports;
  const GyroSimulation& g = d.data.gyro;
  size_t fi = 0;
  auto frames_until = [&](double t, bool inclusive) {
    while (fi < d.data.frame_t_s.size() &&
           (inclusive ? d.data.frame_t_s[fi] <= t + 1e-9 : d.data.frame_t_s[fi] < t - 1e-9)) {
      std::vector<ssiu_frame> fr;
      for (const Image16& im : FrameSet(fi)) fr.push_back(FrameOf(im));
      ssiu_frame_report r;
      EXPECT_EQ(ssiu_flight_frames(f, d.data.frame_t_s[fi], fr.data(), static_cast<int32_t>(fr.size()), &r), SSIU_OK);
      reports.push_back(r);
      ++fi;
    }
  };
  for (size_t k = 0; k < g.t_s.size(); ++k) {
    frames_until(g.t_s[k], false);
    double t = g.t_s[k];
    std::vector<double> s(g.gyro_dph[k].data(), g.gyro_dph[k].data() + g.gyro_dph[k].size());
    spoil(k, &t, &s);
    ssiu_gyro_status st;
    EXPECT_EQ(ssiu_flight_gyro(f, t, s.data(), static_cast<int32_t>(s.size()), &st), SSIU_OK);
    if (gyro_status) gyro_status->push_back(st);
    frames_until(g.t_s[k], true);
  }
  return reports;
}

double FinalErrorArcsec(const Data& d, const ssiu_state& s) {
  size_t best = 0;
  for (size_t k = 0; k < d.data.gyro.t_s.size(); ++k)
    if (std::abs(d.data.gyro.t_s[k] - s.t_s) < std::abs(d.data.gyro.t_s[best] - s.t_s)) best = k;
  return AttitudeErrorRad(QuatOf(s.q_inertial_from_body), d.data.gyro.q_true[best]) * kRadToArcsec;
}

// Every result has its own name (events and logs), which gtest prints on a failure.
TEST(FlightInterface, ResultsHaveNames) {
  std::set<std::string> names;
  for (int r = SSIU_OK; r <= SSIU_ERR_INTERNAL; ++r) {
    const std::string name = ssiu_flight_result_name(static_cast<ssiu_result>(r));
    EXPECT_NE(name, "unknown") << r;
    names.insert(name);
  }
  EXPECT_EQ(names.size(), static_cast<size_t>(SSIU_ERR_INTERNAL + 1));
  EXPECT_EQ(::testing::PrintToString(SSIU_ERR_MEMORY), "err_memory");
  // The statuses print as their enumerators (the last of each, and one in the middle).
  EXPECT_EQ(::testing::PrintToString(SSIU_GYRO_ACCEPTED_TIME_RESET), "SSIU_GYRO_ACCEPTED_TIME_RESET");
  EXPECT_EQ(::testing::PrintToString(SSIU_GYRO_PARTIAL), "SSIU_GYRO_PARTIAL");
  EXPECT_EQ(::testing::PrintToString(SSIU_SOLVE_BAD_FRAME), "SSIU_SOLVE_BAD_FRAME");
  EXPECT_EQ(::testing::PrintToString(SSIU_UPDATE_NONE), "SSIU_UPDATE_NONE");
  EXPECT_EQ(::testing::PrintToString(SSIU_STATUS_FAILED), "SSIU_STATUS_FAILED");
  EXPECT_EQ(::testing::PrintToString(SSIU_UNIT_CAL_APPLIED), "SSIU_UNIT_CAL_APPLIED");
}

// The C interface gives what the C++ processor gives on the same inputs, and both are near the truth.
TEST(FlightInterface, SameAnswersAsTheProcessorAndNearTheTruth) {
  const Data& d = TheData();
  Handle h(ConfigFor(d), d.blob);
  ASSERT_EQ(h.rc, SSIU_OK) << h.why();
  const auto reports = Replay(d, h.f, [](size_t, double*, std::vector<double>*) {});
  ASSERT_EQ(reports.size(), d.data.frame_t_s.size());

  UnitProcessor p(d.config.heads,
                  {std::make_shared<const StarIdentifier>(ParseSolverCatalog(d.blob.data(), d.blob.size(), "blob")),
                   std::make_shared<const StarIdentifier>(ParseSolverCatalog(d.blob.data(), d.blob.size(), "blob"))},
                  d.config.unit, d.config.processor);
  size_t fi = 0;
  const GyroSimulation& g = d.data.gyro;
  auto frames_until = [&](double t, bool inclusive) {
    while (fi < d.data.frame_t_s.size() &&
           (inclusive ? d.data.frame_t_s[fi] <= t + 1e-9 : d.data.frame_t_s[fi] < t - 1e-9)) {
      const FrameReport r = p.OnFrames(d.data.frame_t_s[fi], {FrameSet(fi)[0].view(), FrameSet(fi)[1].view()});
      const ssiu_frame_report& c = reports[fi];
      EXPECT_EQ(c.status, static_cast<int>(r.status)) << fi;
      EXPECT_EQ(c.heads_solved, r.heads_solved) << fi;
      for (int hd = 0; hd < 2; ++hd) {
        EXPECT_EQ(c.heads[hd].matches, r.heads[hd].matches) << fi;
        EXPECT_EQ(c.heads[hd].false_match_probability, r.heads[hd].false_match_probability) << fi;
        EXPECT_EQ(c.heads[hd].photometric_factor, r.heads[hd].photometric_factor) << fi;
        if (r.heads[hd].status == SolveStatus::kSolved) {  // as sure as the configuration asks
          EXPECT_LT(c.heads[hd].false_match_probability, d.config.processor.solve.identify.max_false_match_prob) << fi;
        }
      }
      if (r.status == SolveStatus::kSolved) {
        EXPECT_LE(AttitudeErrorRad(QuatOf(c.q_inertial_from_body), r.q_inertial_from_body), kSameAttitudeRad) << fi;
      }
      ++fi;
    }
  };
  for (size_t k = 0; k < g.t_s.size(); ++k) {
    frames_until(g.t_s[k], false);
    p.OnGyroSample(g.t_s[k], g.gyro_dph[k]);
    frames_until(g.t_s[k], true);
  }
  ssiu_state s;
  ASSERT_EQ(ssiu_flight_state(h.f, &s), SSIU_OK);
  const UnitAttitude a = p.Attitude();
  ASSERT_TRUE(s.valid);
  EXPECT_EQ(s.t_s, a.t_s);
  EXPECT_LE(AttitudeErrorRad(QuatOf(s.q_inertial_from_body), a.q_inertial_from_body), kSameAttitudeRad);
  EXPECT_EQ(s.status, SSIU_STATUS_OK);
  EXPECT_EQ(s.frame_sets, static_cast<int64_t>(d.data.frame_t_s.size()));
  EXPECT_EQ(s.frame_sets_solved, static_cast<int64_t>(d.data.frame_t_s.size()));
  EXPECT_EQ(s.gyros_in_use, 0xfu);
  // Every frame set solved on both heads (lost in space first, then tracking), and the final
  // attitude within a few arcsec of the truth (two 16.6-deg heads: ~1-2 arcsec).
  EXPECT_EQ(reports[0].heads[0].lost_in_space, 1);
  EXPECT_EQ(reports.back().heads[0].lost_in_space, 0);
  for (const auto& r : reports) EXPECT_EQ(r.heads_solved, 2);
  EXPECT_LT(FinalErrorArcsec(d, s), 5.0);
  EXPECT_EQ(s.unit_cal_status, SSIU_UNIT_CAL_OFF);  // off by default
}

// A head's hot pixels and vignetting in the C configuration act as in the C++ processor given the same
// camera extras (UnitProcessor.HeadHotPixelsAndVignettingAreUsedAsBySolve checks that against `ssiu
// solve`): a persistent hot pixel on the wing of the frame's brightest star, which only the list keeps
// out of its centroid, and a vignetted frame.
TEST(FlightInterface, HeadHotPixelsAndVignettingAsTheProcessor) {
  const Data& d = TheData();
  OpticalHead head;
  head.camera = d.config.heads[0].camera;
  UnitProcessorOptions po = d.config.processor;
  const auto id = std::make_shared<const StarIdentifier>(ParseSolverCatalog(d.blob.data(), d.blob.size(), "blob"));
  for (int i = 0; i < 2; ++i) {
    FrameSimOptions fo;
    fo.vignetting = 0.6;
    SimulatedFrame sf = SimulateFrame(head.camera, testing::Bsc(), RandomAttitude(60 + i), fo, 60 + i);
    const auto [hx, hy] = testing::HotPixelOnTheBrightestStarsWing(&sf);
    OpticalHead with = head;
    with.extras.vignetting = fo.vignetting;
    with.extras.psf_sigma_px = 1.25;
    with.extras.hot_pixels = {{hx, hy}, {3, 500}};
    ssiu_flight_config c = FlightConfigFor({with}, d.config.unit, po, "", Vec3::Zero()), plain_c = c;
    c.catalog_crc32 = plain_c.catalog_crc32 = d.crc;
    plain_c.heads[0].vignetting = plain_c.heads[0].psf_sigma_px = 0;
    plain_c.heads[0].n_hot_pixels = 0;
    Handle h(c, d.blob), plain(plain_c, d.blob);
    ASSERT_EQ(h.rc, SSIU_OK) << h.why();
    ASSERT_EQ(plain.rc, SSIU_OK) << plain.why();
    const ssiu_frame frame = FrameOf(sf.image);
    ssiu_frame_report r, r_plain;
    ASSERT_EQ(ssiu_flight_frames(h.f, 0.0, &frame, 1, &r), SSIU_OK);
    ASSERT_EQ(ssiu_flight_frames(plain.f, 0.0, &frame, 1, &r_plain), SSIU_OK);
    const FlightSetup setup = FlightSetupFrom(c);  // the options as the C configuration carries them
    UnitProcessor p({with}, {id}, setup.unit, setup.options);
    const FrameReport want = p.OnFrames(0.0, {sf.image.view()});
    ASSERT_EQ(want.heads[0].status, SolveStatus::kSolved) << i;
    ASSERT_EQ(r.heads[0].status, SSIU_SOLVE_SOLVED) << i;
    ASSERT_EQ(r_plain.heads[0].status, SSIU_SOLVE_SOLVED) << i;
    EXPECT_EQ(r.heads[0].detections, want.heads[0].detections);
    EXPECT_EQ(r.heads[0].matches, want.heads[0].matches);
    EXPECT_LE(AttitudeErrorRad(QuatOf(r.heads[0].q_inertial_from_sensor), want.heads[0].q_inertial_from_sensor),
              kSameAttitudeRad);
    // Without them the hot pixel pulls the star's centroid (1e-4 arcsec or more, against 1e-15 rad).
    EXPECT_GT(AttitudeErrorRad(QuatOf(r_plain.heads[0].q_inertial_from_sensor), want.heads[0].q_inertial_from_sensor) *
                  kRadToArcsec,
              1e-4);
  }
}

// calibrate_unit 1: the state carries the in-flight unit calibration as the processor reports it
// (UnitAttitude::unit_calibration), and the attitude stays near the truth.
TEST(FlightInterface, UnitCalibrationIsInTheState) {
  const Data& d = TheData();
  ssiu_flight_config c = ConfigFor(d);
  c.calibrate_unit = 1;
  Handle h(c, d.blob);
  ASSERT_EQ(h.rc, SSIU_OK) << h.why();
  Replay(d, h.f, [](size_t, double*, std::vector<double>*) {});
  ssiu_state s;
  ASSERT_EQ(ssiu_flight_state(h.f, &s), SSIU_OK);
  ASSERT_TRUE(s.valid);
  EXPECT_NE(s.unit_cal_status, SSIU_UNIT_CAL_OFF);
  EXPECT_GT(s.unit_cal_windows, 0);
  if (s.unit_cal_status >= SSIU_UNIT_CAL_ESTIMATED) {
    for (int g = 0; g < 4; ++g) EXPECT_GT(s.scale_factor_sigma_ppm[g], 0) << g;
  }
  EXPECT_LT(FinalErrorArcsec(d, s), 5.0);
  c.calibrate_unit = 2;
  Handle bad(c, d.blob);
  EXPECT_EQ(bad.rc, SSIU_ERR_CONFIG);
}

// A NaN or infinite output on one gyro (the other three give the rate), NaN on all of them (the last
// rate held), a sample back in time, at the same time again, a NaN time: each says what became of
// it, and the filter goes on to end as near the truth as without them.
TEST(FlightInterface, BadGyroSamplesAreStatusesAndTheFilterGoesOn) {
  const Data& d = TheData();
  Handle h(ConfigFor(d), d.blob);
  ASSERT_EQ(h.rc, SSIU_OK) << h.why();
  std::vector<ssiu_gyro_status> st;
  const auto spoil = [&d](size_t k, double* t, std::vector<double>* g) {
    if (k == 350) (*g)[1] = std::nan("");
    if (k == 351) (*g)[3] = HUGE_VAL;
    if (k == 352) *t -= 0.5;
    if (k == 353) *t = d.data.gyro.t_s[351];
    if (k == 354) *t = std::nan("");
    if (k == 355) g->assign(g->size(), std::nan(""));
  };
  Replay(d, h.f, spoil, &st);
  EXPECT_EQ(st[349], SSIU_GYRO_ACCEPTED);
  EXPECT_EQ(st[350], SSIU_GYRO_PARTIAL);
  EXPECT_EQ(st[351], SSIU_GYRO_PARTIAL);
  EXPECT_EQ(st[352], SSIU_GYRO_REJECTED_OUT_OF_ORDER);
  EXPECT_EQ(st[353], SSIU_GYRO_REJECTED_REPEATED);
  EXPECT_EQ(st[354], SSIU_GYRO_REJECTED_BAD_TIME);
  EXPECT_EQ(st[355], SSIU_GYRO_REJECTED_NON_FINITE);
  EXPECT_EQ(st[356], SSIU_GYRO_ACCEPTED);
  ssiu_state s;
  ASSERT_EQ(ssiu_flight_state(h.f, &s), SSIU_OK);
  EXPECT_EQ(s.gyro_partial, 2);
  EXPECT_EQ(s.gyro_rejected, 4);
  EXPECT_EQ(s.restarts, 0);
  ASSERT_TRUE(s.valid);
  for (double q : s.q_inertial_from_body) EXPECT_TRUE(std::isfinite(q));
  EXPECT_LT(FinalErrorArcsec(d, s), 5.0);
}

// A frame of the wrong size is that head's `bad_frame`, the other head still solves; a wrong number
// of frames is an argument error; nothing throws.
TEST(FlightInterface, WrongFramesAreStatusesNotCrashes) {
  const Data& d = TheData();
  Handle h(ConfigFor(d), d.blob);
  ASSERT_EQ(h.rc, SSIU_OK) << h.why();
  ssiu_frame fr[2] = {FrameOf(FrameSet(0)[0]), FrameOf(FrameSet(0)[1])};
  fr[0].width_px -= 1;
  ssiu_frame_report r;
  ASSERT_EQ(ssiu_flight_frames(h.f, 0.0, fr, 2, &r), SSIU_OK);
  EXPECT_EQ(r.heads[0].status, SSIU_SOLVE_BAD_FRAME);
  EXPECT_EQ(r.heads[1].status, SSIU_SOLVE_SOLVED);
  EXPECT_EQ(r.status, SSIU_SOLVE_SOLVED);
  EXPECT_EQ(r.update_status, SSIU_UPDATE_INITIALISED);
  EXPECT_EQ(ssiu_flight_frames(h.f, 1.0, fr, 1, &r), SSIU_ERR_ARGUMENT);
  EXPECT_THAT(ssiu_flight_last_error(h.f), HasSubstr("n_heads"));
  fr[0] = FrameOf(FrameSet(1)[0]);
  fr[1].pixels = nullptr;  // head 2 silent
  ASSERT_EQ(ssiu_flight_frames(h.f, 1.0, fr, 2, &r), SSIU_OK);
  EXPECT_EQ(r.heads[1].status, SSIU_SOLVE_NO_FRAME);
  EXPECT_EQ(r.heads[0].status, SSIU_SOLVE_SOLVED);
  // A frame set before the filter's time: solved, and refused by the filter as late.
  ASSERT_EQ(ssiu_flight_frames(h.f, 0.5, fr, 2, &r), SSIU_OK);
  EXPECT_EQ(r.status, SSIU_SOLVE_SOLVED);
  EXPECT_EQ(r.update_status, SSIU_UPDATE_REJECTED_LATE);
  const double nan_t = std::nan("");
  ASSERT_EQ(ssiu_flight_frames(h.f, nan_t, fr, 2, &r), SSIU_OK);
  EXPECT_EQ(r.status, SSIU_SOLVE_BAD_FRAME);
  EXPECT_EQ(r.heads[0].status, SSIU_SOLVE_BAD_FRAME);
}

// A blob that is not the catalog the configuration names is refused before it is read: a flipped
// byte, a truncated blob, random bytes (with a matching CRC, so that the parser itself sees them).
TEST(FlightInterface, CorruptCatalogBlobIsRefusedAtInit) {
  const Data& d = TheData();
  ssiu_flight_config c = ConfigFor(d);
  std::string blob = d.blob;
  blob[blob.size() / 2] ^= 0x10;
  {
    Handle h(c, blob);
    EXPECT_EQ(h.rc, SSIU_ERR_CATALOG);
    EXPECT_EQ(h.f, nullptr);
    EXPECT_THAT(h.why(), HasSubstr("CRC"));
  }
  for (const std::string& bad : {d.blob.substr(0, d.blob.size() / 3), d.blob.substr(0, 40), std::string(5000, '\x5a')}) {
    c.catalog_crc32 = Crc32(bad.data(), bad.size());
    Handle h(c, bad);
    EXPECT_EQ(h.rc, SSIU_ERR_CATALOG);
    EXPECT_EQ(h.f, nullptr);
    EXPECT_THAT(h.why(), HasSubstr("catalog"));
  }
  c.catalog_crc32 = 0;
  Handle h(c, d.blob);
  EXPECT_EQ(h.rc, SSIU_ERR_CATALOG);
  EXPECT_THAT(h.why(), HasSubstr("catalog_crc32"));
}

TEST(FlightInterface, BadConfigAndMemoryAreRefusedWithTheField) {
  const Data& d = TheData();
  ssiu_flight_config c = ConfigFor(d);
  c.heads[1].focal_length_px = -3;
  EXPECT_EQ(ssiu_flight_check_config(&c), SSIU_ERR_CONFIG);
  EXPECT_EQ(ssiu_flight_memory_bytes(&c), 0u);
  {
    Handle h(c, d.blob);
    EXPECT_EQ(h.rc, SSIU_ERR_CONFIG);
    EXPECT_THAT(h.why(), HasSubstr("head2"));
  }
  c = ConfigFor(d);
  c.n_gyros = 2;
  EXPECT_EQ(ssiu_flight_check_config(&c), SSIU_ERR_CONFIG);
  // A size of 0 is refused at init with the field's name.
  for (const auto& [field, member] :
       {std::pair{"max_star_samples", &ssiu_flight_config::max_star_samples},
        std::pair{"max_patterns", &ssiu_flight_config::max_patterns},
        std::pair{"max_stars_in_field", &ssiu_flight_config::max_stars_in_field}}) {
    c = ConfigFor(d);
    c.*member = 0;
    Handle h(c, d.blob);
    EXPECT_EQ(h.rc, SSIU_ERR_CONFIG) << field;
    EXPECT_THAT(h.why(), HasSubstr(field));
  }
  c = ConfigFor(d);
  std::vector<Block> small(2);
  ssiu_flight* f = reinterpret_cast<ssiu_flight*>(1);
  EXPECT_EQ(ssiu_flight_init(&c, d.blob.data(), d.blob.size(), small.data(), sizeof(Block) * 2, &f),
            SSIU_ERR_MEMORY);
  EXPECT_EQ(f, nullptr);
  EXPECT_EQ(ssiu_flight_init(nullptr, d.blob.data(), d.blob.size(), small.data(), 32, &f), SSIU_ERR_NULL);
  // After shutdown the handle is gone: calls say so.
  Handle h(c, d.blob);
  ASSERT_EQ(h.rc, SSIU_OK);
  ssiu_flight_shutdown(h.f);
  const double g[4] = {0, 0, 0, 0};
  EXPECT_EQ(ssiu_flight_gyro(h.f, 0.0, g, 4, nullptr), SSIU_ERR_NOT_INITIALISED);
  ssiu_state s;
  EXPECT_EQ(ssiu_flight_state(h.f, &s), SSIU_ERR_NOT_INITIALISED);
  h.f = nullptr;
}

// flight.cfg: every field written and read back exactly; bad lines named.
TEST(FlightConfig, TextRoundTripsAndNamesBadLines) {
  const Data& d = TheData();
  const ssiu_flight_config c = ConfigFor(d);
  const std::string text = FlightConfigText(c);
  ssiu_flight_config back;
  char why[256] = {0};
  ASSERT_EQ(ssiu_flight_parse_config(text.data(), text.size(), &back, why, sizeof why), SSIU_OK) << why;
  EXPECT_EQ(FlightConfigText(back), text);
  EXPECT_EQ(back.n_heads, 2);
  EXPECT_EQ(back.heads[1].q_body_sensor[1], c.heads[1].q_body_sensor[1]);
  EXPECT_EQ(back.catalog_crc32, d.crc);
  EXPECT_STREQ(back.epoch_utc, d.config.start_utc.c_str());
  EXPECT_EQ(back.systematic_px, d.config.processor.solve.identify.systematic_px);
  const FlightSetup s = FlightSetupFrom(back);
  EXPECT_EQ(s.heads[1].camera.width, 512);
  EXPECT_NEAR(AttitudeErrorRad(s.heads[1].q_body_from_sensor, d.config.heads[1].q_body_from_sensor), 0, 1e-15);
  for (const std::string& bad : {std::string("n_heads 2\nhead1.size_px 512\n"), std::string("n_heads two\n"),
                                 std::string("n_heads 2\nfocal 3\n"), std::string("velocity_kms 1 2 3 4\n")}) {
    EXPECT_EQ(ssiu_flight_parse_config(bad.data(), bad.size(), &back, why, sizeof why), SSIU_ERR_CONFIG) << bad;
    EXPECT_THAT(why, HasSubstr("flight.cfg:")) << bad;
  }
  EXPECT_THAT(testing::ErrorOf([] { ParseFlightConfigText("n_heads 2\nhead1.size_px 512\n", "unit.cfg"); }),
              HasSubstr("unit.cfg:2: key 'head1.size_px' needs 2 values"));
}

// A head's camera.json extras (psf_sigma_px, vignetting, hot_pixels) go into the C configuration, through its text
// and back; a list the interface cannot hold, or pixels outside the head's image, are refused by name.
TEST(FlightConfig, HeadVignettingAndHotPixelsRoundTrip) {
  const Data& d = TheData();
  std::vector<OpticalHead> heads = d.config.heads;
  heads[1].extras.vignetting = 0.35;
  heads[1].extras.psf_sigma_px = 2.5;
  heads[1].extras.hot_pixels = {{0, 0}, {511, 7}, {256, 511}};
  ssiu_flight_config c = FlightConfigFor(heads, d.config.unit, d.config.processor, "", Vec3::Zero());
  const std::string text = FlightConfigText(c);
  EXPECT_THAT(text, HasSubstr("head2.psf_sigma_px 2.5\nhead2.vignetting 0.34999999999999998\n"));
  EXPECT_THAT(text, HasSubstr("head2.hot_pixels 3 0 0 511 7 256 511\n"));
  EXPECT_THAT(text, HasSubstr("head1.hot_pixels 0\n"));
  const FlightSetup s = FlightSetupFrom(ParseFlightConfigText(text, "flight.cfg"));
  EXPECT_EQ(s.heads[1].extras.vignetting, 0.35);
  EXPECT_EQ(s.heads[1].extras.psf_sigma_px, 2.5);
  EXPECT_EQ(s.heads[1].extras.hot_pixels, heads[1].extras.hot_pixels);
  EXPECT_EQ(s.heads[0].extras.vignetting, 0);
  EXPECT_TRUE(s.heads[0].extras.hot_pixels.empty());
  // A configuration written before the fields existed reads as none.
  std::string old_text, line;
  for (std::istringstream in(text); std::getline(in, line);)
    if (line.find("vignetting") == std::string::npos && line.find("hot_pixels") == std::string::npos &&
        line.find("psf_sigma") == std::string::npos)
      old_text += line + "\n";
  EXPECT_TRUE(FlightSetupFrom(ParseFlightConfigText(old_text, "old.cfg")).heads[1].extras.hot_pixels.empty());

  for (const auto& [bad, why] : {std::pair{"head1.hot_pixels 2 1 2 3\n", "flight.cfg:1: key 'head1.hot_pixels' needs"},
                                 std::pair{"head1.hot_pixels 1 70000 2\n", "'70000' is not a whole number from 0"},
                                 std::pair{"head1.hot_pixels 257\n", "'257' is not a whole number from 0 to 256"},
                                 std::pair{"head1.hot_pixels 1 3 4 5\n", "more than its count"},
                                 std::pair{"head1.hot_pixels 1 2.5 4\n", "'2.5'"}}) {
    const std::string text_bad = bad;  // (a structured binding cannot be captured in C++17)
    EXPECT_THAT(testing::ErrorOf([&] { ParseFlightConfigText(text_bad, "flight.cfg"); }), HasSubstr(why)) << bad;
  }
  ssiu_flight_config b = c;
  b.heads[1].hot_pixels_xy[1][0] = 512;  // the image is 512 wide
  EXPECT_THAT(testing::ErrorOf([&] { FlightSetupFrom(b); }), HasSubstr("head2.hot_pixels_xy[1] lies outside"));
  EXPECT_EQ(ssiu_flight_check_config(&b), SSIU_ERR_CONFIG);
  b = c;
  b.heads[1].vignetting = 1;
  EXPECT_THAT(testing::ErrorOf([&] { FlightSetupFrom(b); }), HasSubstr("head2.vignetting must be in [0, 1)"));
  b = c;
  b.heads[1].psf_sigma_px = -1;
  EXPECT_THAT(testing::ErrorOf([&] { FlightSetupFrom(b); }), HasSubstr("head2.psf_sigma_px must be in [0, 50)"));
  b = c;
  b.heads[0].n_hot_pixels = SSIU_FLIGHT_MAX_HOT_PIXELS + 1;
  EXPECT_THAT(testing::ErrorOf([&] { FlightSetupFrom(b); }), HasSubstr("head1.n_hot_pixels must be 0 to 256"));
  heads[0].extras.hot_pixels.assign(SSIU_FLIGHT_MAX_HOT_PIXELS + 1, {1, 1});
  EXPECT_THAT(testing::ErrorOf([&] { FlightConfigFor(heads, d.config.unit, d.config.processor, "", Vec3::Zero()); }),
              HasSubstr("head1: more than 256 hot pixels"));
}

}  // namespace
}  // namespace ssiu
