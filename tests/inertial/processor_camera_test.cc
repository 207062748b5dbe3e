// The unit's processor uses a head's camera.json fields beyond the geometry as `ssiu solve` does: the
// known hot pixels repaired before detection, the vignetting taken out of the fluxes before
// identification.
#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/error.h"
#include "inertial/unit_processor.h"
#include "sim/frame_sim.h"
#include "testing/sim_frames.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(UnitProcessor, HeadHotPixelsAndVignettingAreUsedAsBySolve) {
  OpticalHead head;
  head.camera = MakeCamera(512, 512, 16.6);
  const auto id = std::make_shared<const StarIdentifier>(MakeIdentifierForCamera("", head.camera, 0.0));
  int solved = 0;
  for (int i = 0; i < 3; ++i) {
    const Quat q = RandomAttitude(40 + i);
    FrameSimOptions fo;
    fo.vignetting = 0.6;
    SimulatedFrame sf = SimulateFrame(head.camera, testing::Bsc(), q, fo, 40 + i);
    const auto [hx, hy] = testing::HotPixelOnTheBrightestStarsWing(&sf);
    OpticalHead h = head;
    h.extras.vignetting = fo.vignetting;
    h.extras.psf_sigma_px = 1.25;  // the detector's expected PSF (the frame's own estimate otherwise)
    h.extras.hot_pixels = {{hx, hy}};
    DefectMap hot;
    MarkHotPixel(hx, hy, 512, 512, &hot);
    UnitProcessorOptions po;
    po.solve.detect.gain_e_per_adu = fo.gain_e_per_adu;
    UnitProcessor p({h}, {id}, DefaultFourFogUnit(), po), plain({head}, {id}, DefaultFourFogUnit(), po);
    const FrameReport r = p.OnFrames(0.0, {sf.image.view()}), r_plain = plain.OnFrames(0.0, {sf.image.view()});
    SolveOptions so = po.solve;
    UseCameraExtras(h.extras, &so);
    const SolveResult s = SolveFrame(*id, sf.image.view(), head.camera, so, &hot);
    ASSERT_EQ(r.heads[0].status, s.status) << "frame " << i;
    ASSERT_EQ(r_plain.heads[0].status, SolveStatus::kSolved) << "frame " << i;
    if (s.status != SolveStatus::kSolved) continue;
    ++solved;
    // The same answer as `ssiu solve`'s with the list and the law ...
    EXPECT_EQ(r.heads[0].detections, static_cast<int>(s.detections.stars.size()));
    EXPECT_EQ(r.heads[0].matches, static_cast<int>(s.identification.matches.size()));
    EXPECT_DOUBLE_EQ(r.heads[0].photometric_factor, s.identification.photometric_factor);
    EXPECT_LT(AttitudeErrorRad(r.heads[0].q_inertial_from_sensor, s.attitude.q_inertial_from_sensor) * kRadToArcsec,
              1e-6);
    EXPECT_THAT(r.heads[0].q_inertial_from_sensor, QuaternionNear(q, 20.0));
    // ... and not the one without them: the hot pixel pulls a centroid (0.0018 arcsec or more on the
    // attitude here, against 1e-6 above), the vignetting weakens the evidence.
    EXPECT_GT(
        AttitudeErrorRad(r_plain.heads[0].q_inertial_from_sensor, r.heads[0].q_inertial_from_sensor) * kRadToArcsec,
        1e-4);
    EXPECT_GT(r_plain.heads[0].photometric_factor, r.heads[0].photometric_factor);
  }
  EXPECT_EQ(solved, 3);
  // A hot pixel outside the head's image is refused at construction, naming the head.
  OpticalHead bad = head;
  bad.extras.hot_pixels = {{512, 3}};
  EXPECT_THROW(UnitProcessor({bad}, {id}, DefaultFourFogUnit(), UnitProcessorOptions{}), InputError);
}

}  // namespace
}  // namespace ssiu
