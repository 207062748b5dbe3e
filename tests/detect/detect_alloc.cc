// Detect with a workspace allocates nothing after the workspace is built (the flight core's rule,
// issue 26): simulated star frames with hot pixels, cosmic rays, streaks, saturated stars, a smear, a
// defect map, black and white frames, and more stars than the workspace keeps. A program of its own
// (detect_alloc_test): the counting operator new of testing/alloc_count.h counts every allocation of
// the process.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/catalog.h"
#include "detect/detect.h"
#include "sim/detection_score.h"
#include "sim/frame_sim.h"
#include "testing/alloc_count.h"

namespace ssiu {
namespace {

const StarCatalog& Bsc() {
  static const StarCatalog cat = LoadXplanetBsc(DefaultBscPath());
  return cat;
}

SimulatedFrame Simulate(const FrameSimOptions& so, uint64_t seed) {
  return SimulateFrame(Camera{}, Bsc(), RandomAttitude(seed), so, seed);
}

DetectLimits FlightLimits() {
  DetectLimits l;  // 1024 x 1024, 1000 detections
  l.diagnostics = false;
  return l;
}

// Runs the workspace form three times on `view` under an allocation counter and checks that no call
// allocated, that the calls agree, and (unless clamped) that they equal the one-call Detect.
Detections DetectCounted(DetectWorkspace* ws, const ImageView& view, const DetectOptions& o,
                         const DefectMap* map = nullptr) {
  Detections out, again;
  ws->Reserve(&out);
  ws->Reserve(&again);
  testing::AllocationCounter n;
  EXPECT_EQ(Detect(view, o, map, ws, &out), DetectStatus::kOk);
  for (int k = 0; k < 2; ++k) EXPECT_EQ(Detect(view, o, map, ws, &again), DetectStatus::kOk);
  const long allocations = n.Count();
  EXPECT_EQ(allocations, 0) << n.Bytes() << " bytes";
  EXPECT_TRUE(out.timing_ms.empty());
  EXPECT_EQ(out.stars.size(), again.stars.size());
  EXPECT_EQ(out.rejected.size(), again.rejected.size());
  if (out.clamped == 0) {
    const Detections ref = Detect(view, o, map);
    EXPECT_EQ(out.stars.size(), ref.stars.size());
    for (size_t i = 0; i < std::min(out.stars.size(), ref.stars.size()); ++i) {
      EXPECT_EQ(out.stars[i].x_px, ref.stars[i].x_px);
      EXPECT_EQ(out.stars[i].y_px, ref.stars[i].y_px);
      EXPECT_EQ(out.stars[i].flux_adu, ref.stars[i].flux_adu);
    }
    EXPECT_EQ(out.rejected.size(), ref.rejected.size());
    for (size_t i = 0; i < std::min(out.rejected.size(), ref.rejected.size()); ++i) {
      EXPECT_EQ(out.rejected[i].reason, ref.rejected[i].reason);
      EXPECT_EQ(RejectDetailName(out.rejected[i].detail_code), ref.rejected[i].detail);
      EXPECT_TRUE(out.rejected[i].detail.empty());  // no text without diagnostics
    }
  }
  return out;
}

// Detected stars within 1 px of a drawn star with SNR > 20, as a fraction of those stars.
double RecallOfBrightStars(const Detections& d, const SimulatedFrame& f) {
  int bright = 0, found = 0;
  for (const SimStar& s : f.stars) {
    if (s.snr < 20 || s.x_px < 3 || s.y_px < 3 || s.x_px > 1020 || s.y_px > 1020) continue;
    ++bright;
    for (const StarDetection& m : d.stars) {
      if (std::hypot(m.x_px - s.x_px, m.y_px - s.y_px) < 1.0) {
        ++found;
        break;
      }
    }
  }
  return bright > 0 ? double(found) / bright : 1.0;
}

TEST(DetectAlloc, StarFramesWithInterferersAllocateNothing) {
  DetectWorkspace ws(FlightLimits());
  FrameSimOptions so;  // defaults: 40 hot pixels, 5 dead pixels, 3 cosmic rays
  so.streaks = 2;
  so.cosmic_rays = 6;
  for (uint64_t seed : {1, 2}) {
    const SimulatedFrame f = Simulate(so, seed);
    const Detections d = DetectCounted(&ws, f.image.view(), DetectOptionsForSimulation(Camera{}, so, false));
    EXPECT_EQ(d.clamped, 0u);
    EXPECT_GT(RecallOfBrightStars(d, f), 0.9);
    int hot = 0, tracks = 0;
    for (const Rejection& r : d.rejected) {
      hot += r.reason == RejectReason::kHotPixel;
      tracks += r.reason == RejectReason::kCosmicRay || r.reason == RejectReason::kStreak;
    }
    EXPECT_GE(hot, 20);
    EXPECT_GE(tracks, 3);
  }
}

TEST(DetectAlloc, SaturatedStarsSmearAndDefectMapAllocateNothing) {
  DetectWorkspace ws(FlightLimits());
  FrameSimOptions bright;
  bright.mag0_flux_e_per_s = 5e8;  // the brighter stars saturate
  const SimulatedFrame fb = Simulate(bright, 11);
  const Detections db = DetectCounted(&ws, fb.image.view(), DetectOptionsForSimulation(Camera{}, bright, false));
  int saturated = 0;
  for (const StarDetection& s : db.stars) saturated += s.saturated;
  EXPECT_GE(saturated, 10);

  FrameSimOptions slew;
  slew.rate_x_dps = 2.0;  // smears of about 12 px, fitted as smeared PSFs
  const SimulatedFrame fs = Simulate(slew, 12);
  const Detections ds = DetectCounted(&ws, fs.image.view(), DetectOptionsForSimulation(Camera{}, slew, true));
  EXPECT_GT(RecallOfBrightStars(ds, fs), 0.8);

  const SimulatedFrame fd = Simulate(FrameSimOptions{}, 3);
  const DefectMap map = BuildDefectMap({fd.image.view()});
  const Detections dd =
      DetectCounted(&ws, fd.image.view(), DetectOptionsForSimulation(Camera{}, FrameSimOptions{}, false), &map);
  EXPECT_GT(RecallOfBrightStars(dd, fd), 0.9);
}

TEST(DetectAlloc, BlackWhiteAndOverfullFramesAllocateNothing) {
  DetectWorkspace ws(FlightLimits());
  const Image16 black(1024, 1024, 0), white(1024, 1024, 65535);
  const Detections d0 = DetectCounted(&ws, black.view(), DetectOptions{});
  EXPECT_TRUE(d0.stars.empty());
  const Detections d1 = DetectCounted(&ws, white.view(), DetectOptions{});
  EXPECT_TRUE(d1.stars.empty());
  // A frame smaller than the workspace's largest.
  const Image16 small(640, 480, 300);
  EXPECT_TRUE(DetectCounted(&ws, small.view(), DetectOptions{}).stars.empty());

  // More stars than the workspace keeps: the brightest 20, flagged.
  DetectLimits few = FlightLimits();
  few.max_detections = 20;
  DetectWorkspace ws20(few);
  const FrameSimOptions so;
  const SimulatedFrame f = Simulate(so, 1);
  const DetectOptions o = DetectOptionsForSimulation(Camera{}, so, false);
  const Detections all = Detect(f.image.view(), o);
  ASSERT_GT(all.stars.size(), 40u);
  const Detections d = DetectCounted(&ws20, f.image.view(), o);
  ASSERT_EQ(d.stars.size(), 20u);
  EXPECT_TRUE(d.clamped & kClampStars);
  EXPECT_FALSE(all.clamped & kClampStars);
  for (size_t i = 0; i < d.stars.size(); ++i) {  // the 20 brightest of the full list
    EXPECT_EQ(d.stars[i].x_px, all.stars[i].x_px);
    EXPECT_EQ(d.stars[i].flux_adu, all.stars[i].flux_adu);
  }
}

TEST(DetectAlloc, BytesIsWhatConstructionAllocated) {
  for (int side : {512, 1024}) {
    DetectLimits l = FlightLimits();
    l.max_width = l.max_height = side;
    testing::AllocationCounter n;
    const DetectWorkspace ws(l);
    Detections d;
    ws.Reserve(&d);
    EXPECT_EQ(static_cast<size_t>(n.Bytes()), ws.Bytes() + ws.OutputBytes()) << side;
    std::printf("DetectWorkspace %dx%d: %zu bytes, output %zu bytes\n", side, side, ws.Bytes(), ws.OutputBytes());
  }
}

TEST(DetectAlloc, CounterSeesTheOneCallForm) {
  // The one-call Detect builds its workspace per call: the counter must see that.
  const Image16 frame(256, 256, 100);
  testing::AllocationCounter n;
  const Detections d = Detect(frame.view(), DetectOptions{});
  EXPECT_GT(n.Count(), 0);
  EXPECT_FALSE(d.timing_ms.empty());
}

TEST(DetectAlloc, BadInputIsAStatusWithoutAllocation) {
  DetectWorkspace ws(FlightLimits());
  Detections out;
  ws.Reserve(&out);
  const Image16 big(1100, 1024, 100), tiny(8, 8, 100);
  const Image16 frame(1024, 1024, 100);
  DetectOptions bad;
  bad.threshold_sigma = std::nan("");
  DetectOptions fine_tile;
  fine_tile.tile_px = 8;  // below the workspace's min_tile_px (16)
  DefectMap wrong;
  wrong.width = wrong.height = 16;
  wrong.mask.assign(256, 0);
  testing::AllocationCounter n;
  EXPECT_EQ(Detect(big.view(), DetectOptions{}, nullptr, &ws, &out), DetectStatus::kImageTooLarge);
  EXPECT_EQ(Detect(tiny.view(), DetectOptions{}, nullptr, &ws, &out), DetectStatus::kImageTooSmall);
  EXPECT_EQ(Detect(frame.view(), bad, nullptr, &ws, &out), DetectStatus::kBadOptions);
  EXPECT_EQ(Detect(frame.view(), fine_tile, nullptr, &ws, &out), DetectStatus::kTileTooSmall);
  EXPECT_EQ(Detect(frame.view(), DetectOptions{}, &wrong, &ws, &out), DetectStatus::kDefectMapSize);
  EXPECT_EQ(n.Count(), 0);
  EXPECT_EQ(out.width, 0);
  EXPECT_TRUE(out.stars.empty());
}

}  // namespace
}  // namespace ssiu
