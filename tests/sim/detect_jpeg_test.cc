// JPEG frames (docs/detection.md, "JPEG frames"): lossy compression adds an error correlated within
// each 8x8 block (the quantised DCT coefficients), which the detector must neither take for stars nor
// let bias the centroids. Simulated 8-bit frames at a wide-field camera's levels (gain 8 e/ADU, noise
// about 1.8 ADU, as the GranaSAT frames) written losslessly (PNG) and as JPEG at several qualities by
// an independent encoder (OpenCV's libjpeg-turbo), detected the same way and scored against the truth,
// with the block-aware noise estimate on and off.
#include <algorithm>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>

#include "core/attitude.h"
#include "attitude/star_solver.h"
#include "core/image.h"
#include "detect/detect.h"
#include "sim/detection_score.h"
#include "sim/frame_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

constexpr int kQualities[] = {100, 95, 90, 85, 75, 50};
constexpr int kQ = 6;

struct JpegScores {
  DetectionScore png, jpeg[kQ][2];  // [quality][block-aware noise off, on]
  int png_flagged = 0, jpeg_flagged[kQ] = {};
};

JpegScores ScoreJpeg(int hot_pixels, int frames) {
  const Camera cam = MakeCamera(1024, 768, 20.0);
  FrameSimOptions so;
  so.bit_depth = 8;
  so.gain_e_per_adu = 8, so.bias_adu = 10, so.read_noise_e = 10;
  so.cosmic_rays = 0;
  so.hot_pixels = hot_pixels;
  const std::string dir = testing::TempDir("detect_jpeg");
  JpegScores out;
  for (int f = 0; f < frames; ++f) {
    const SimulatedFrame sf = SimulateFrame(cam, testing::Bsc(), RandomAttitude(900 + f), so, 900 + f);
    cv::Mat m(sf.image.height, sf.image.width, CV_8UC1);
    for (int y = 0; y < m.rows; ++y)
      for (int x = 0; x < m.cols; ++x) m.at<uchar>(y, x) = static_cast<uchar>(std::min<int>(255, sf.image.at(x, y)));
    DetectOptions o = DetectOptionsForSimulation(cam, so, false);
    o.saturation_adu = 255;
    EXPECT_TRUE(cv::imwrite(dir + "/f.png", m));
    const Detections dp = Detect(ReadFrame(dir + "/f.png").image.view(), o);
    out.png.Add(ScoreDetections(sf, dp));
    out.png_flagged += dp.block_artefacts;
    for (int k = 0; k < kQ; ++k) {
      EXPECT_TRUE(cv::imwrite(dir + "/f.jpg", m, {cv::IMWRITE_JPEG_QUALITY, kQualities[k]}));
      const Frame fj = ReadFrame(dir + "/f.jpg");
      for (int on = 0; on < 2; ++on) {
        o.block_aware_noise = on;
        const Detections dj = Detect(fj.image.view(), o);
        out.jpeg[k][on].Add(ScoreDetections(sf, dj));
        if (on) out.jpeg_flagged[k] += dj.block_artefacts;
      }
    }
  }
  std::printf("%d hot pixels, %d frames: PNG recall (SNR >= 10) %.3f of %d, false %d, centroid RMS %.3f px\n",
              hot_pixels, frames, out.png.recall_snr10(), out.png.true_stars_snr10, out.png.false_detections,
              out.png.centroid_rms_px);
  for (int k = 0; k < kQ; ++k) {
    const DetectionScore &a = out.jpeg[k][0], &b = out.jpeg[k][1];
    std::printf("  JPEG q %3d (blocks seen %d/%d): recall %.3f / %.3f, false %d / %d, centroid RMS %.3f / %.3f px "
                "(block-aware noise off / on)\n",
                kQualities[k], out.jpeg_flagged[k], frames, a.recall_snr10(), b.recall_snr10(), a.false_detections,
                b.false_detections, a.centroid_rms_px, b.centroid_rms_px);
  }
  return out;
}

TEST(DetectJpeg, BlockArtefactsAreSeenAndNotTakenForStars) {
  for (int hot : {0, 40}) {
    const JpegScores s = ScoreJpeg(hot, 3);
    EXPECT_EQ(s.png_flagged, 0);  // a frame never block-coded is not called blocky
    for (int k = 0; k < kQ; ++k) {
      const DetectionScore& on = s.jpeg[k][1];
      if (kQualities[k] <= 95) {
        EXPECT_EQ(s.jpeg_flagged[k], 3) << kQualities[k];
      }
      // Down to quality 90 (95 with the simulator's 40 hot pixels, which JPEG's ringing turns from
      // single saturated pixels into star-like blobs: docs/detection.md), what the lossless frame gives
      // (false detections, recall, centroids).
      if (kQualities[k] >= (hot ? 95 : 90)) {
        EXPECT_LE(on.false_detections, s.png.false_detections + 2) << kQualities[k];
        EXPECT_GE(on.recall_snr10(), s.png.recall_snr10() - 0.02) << kQualities[k];
        EXPECT_LE(on.centroid_rms_px, 1.15 * s.png.centroid_rms_px) << kQualities[k];
      }
      // Below: the block-aware noise takes far fewer block patterns for stars (at most half) and keeps
      // the recall of the SNR >= 10 stars within 5 %.
      if (kQualities[k] <= 75) {
        EXPECT_LE(2 * on.false_detections, s.jpeg[k][0].false_detections) << kQualities[k];
        EXPECT_GE(on.recall_snr10(), s.jpeg[k][0].recall_snr10() - 0.05) << kQualities[k];
      }
    }
  }
}

// The solver on heavily compressed frames (qualities 75 and 50, where the detector still passes
// tens to hundreds of block patterns as faint stars): the pipeline's default solve (detect ->
// identify lost in space -> QUEST) of each frame, scored against the simulator's attitude. A wrong
// attitude would be a false match; too many false detections would be a no_match.
TEST(DetectJpeg, LowQualityFramesStillSolveRightOrSayNoMatch) {
  const Camera cam = MakeCamera(1024, 768, 20.0);
  const StarIdentifier id = MakeIdentifierForCamera("", cam, 0.0);
  FrameSimOptions so;
  so.bit_depth = 8;
  so.gain_e_per_adu = 8, so.bias_adu = 10, so.read_noise_e = 10;
  so.cosmic_rays = 0;
  const std::string dir = testing::TempDir("solve_jpeg");
  for (const int hot : {0, 40}) {
    so.hot_pixels = hot;
    for (const int quality : {75, 50}) {
      int solved = 0, wrong = 0;
      double worst_arcsec = 0;
      for (int f = 0; f < 4; ++f) {
        const Quat q = RandomAttitude(950 + f);
        const SimulatedFrame sf = SimulateFrame(cam, testing::Bsc(), q, so, 950 + f);
        cv::Mat m(sf.image.height, sf.image.width, CV_8UC1);
        for (int y = 0; y < m.rows; ++y)
          for (int x = 0; x < m.cols; ++x) m.at<uchar>(y, x) = static_cast<uchar>(std::min<int>(255, sf.image.at(x, y)));
        ASSERT_TRUE(cv::imwrite(dir + "/f.jpg", m, {cv::IMWRITE_JPEG_QUALITY, quality}));
        const SolveResult r = SolveFrame(id, ReadFrame(dir + "/f.jpg").image.view(), cam, SolveOptions{});
        if (r.status != SolveStatus::kSolved) continue;
        ++solved;
        const double err = SplitAttitudeError(r.attitude.q_inertial_from_sensor, q).cross_rad * kRadToArcsec;
        worst_arcsec = std::max(worst_arcsec, err);
        wrong += err > 60;
      }
      std::printf("JPEG q %d, %d hot pixels: solved %d of 4, wrong %d, worst cross-boresight %.1f arcsec\n", quality,
                  hot, solved, wrong, worst_arcsec);
      EXPECT_EQ(wrong, 0) << quality << " " << hot;
      EXPECT_GE(solved, 3) << quality << " " << hot;
      EXPECT_LT(worst_arcsec, 10.0) << quality << " " << hot;  // 59 arcsec/px, hundreds of stars
    }
  }
}

}  // namespace
}  // namespace ssiu
