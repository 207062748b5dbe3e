// The unit's processor: what the SSIU's on-board loop calls. Star frames of one to three optical heads
// are detected, identified (lost in space first, then tracking around the attitude the gyros
// propagate), solved together for the body attitude (QUEST over every head's matches), and fused
// with the four-FOG unit in the MEKF that also estimates the gyro biases and watches the gyros for a
// fault. `ssiu run` drives it with a simulated mission (sim/mission.h); docs/inertial.md.
//
//   UnitProcessor p(heads, identifiers, DefaultFourFogUnit(), UnitProcessorOptions{});
//   p.OnGyroSample(t_s, g_dph);              // every gyro sample (mean output over the interval)
//   FrameReport f = p.OnFrames(t_s, views);  // one ImageView per head (empty view: no frame)
//   UnitAttitude a = p.Attitude();           // body attitude, covariance, bias, faults
//
// No input breaks the loop (docs/inertial.md "Bad inputs"): a bad gyro sample is refused or repaired
// as its GyroSampleStatus says, a bad frame is a head status "bad_frame", a frame before the filter's
// time is refused by the filter (FrameReport::update.status), and nothing throws after construction.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "core/camera.h"
#include "core/heads.h"
#include "core/image.h"
#include "core/json.h"
#include "core/types.h"
#include "detect/detect.h"
#include "identify/identify.h"
#include "inertial/fuse.h"
#include "inertial/gyro_unit.h"
#include "inertial/online_fusion.h"

namespace ssiu {

struct UnitProcessorOptions {
  // Detection threshold, identification, tracking search radius; with solve.detect.smear.exposure_s > 0
  // the detector is told the smear the gyro rate predicts (motion during the exposure, docs/inertial.md).
  // The unit's frames come from its own detectors, never block-coded: no look for JPEG blocks (half a
  // pass over each frame, 0.1 ms a 512^2 head). The camera is calibrated (each head's camera.json,
  // discover frames in orbit): its focal length is kept, not refitted frame by frame.
  SolveOptions solve = [] {
    SolveOptions s;
    s.detect.block_aware_noise = false;
    s.identify.refine_focal_p = 0;
    return s;
  }();
  FuseOptions fuse;  // MEKF prior, NIS gate, FDI (the star noise comes from each solution's covariance)
  // The QUEST covariance is multiplied by this squared before it enters the filter (1 = trusted as is).
  double solution_sigma_scale = 1.0;
  // Added in quadrature to each axis' 1-sigma of a solution (arcsec): the QUEST covariance knows only
  // the centroid noise, not the unmodelled errors (distortion, catalog positions, motion in the exposure).
  double solution_sigma_floor_arcsec = 0.5;
  // Fraction of a solution's covariance that consecutive frames share: while a head tracks the same
  // stars, its error (catalog positions, distortion, the pattern's geometry) is fixed to the star
  // field, not white, so the filter cannot average it down (measured on simulated missions: one head's
  // roll error stays at the single-frame level over 120 s). The reported attitude covariance is never
  // below this fraction of the last accepted solution's covariance; the filter itself is unchanged.
  // 0.6: mean NEES 3.7 for one head, 2.0 / 1.7 for two / three (whose QUEST covariance is already
  // conservative) on the default 120 s mission; 1 gives 2.2 / 1.2 / 1.0, 0 gives 19 / 4.0 / 3.1.
  double correlated_fraction = 0.6;
  // Times measured (HeadResult's *_ms and timing_ms map, FrameReport::total_ms) and the detector's
  // and identifier's text: false on the flight path, which then reads no clock and allocates nothing.
  bool diagnostics = true;
  // Catalog stars about a field that identification predicts from (the brightest when more, flagged
  // in the head's result): sizes the identification workspace with solve.detect.max_stars centroids.
  // 16.6 deg heads with the default catalog see about 90 on average and under 300 anywhere.
  int max_stars_in_field = 600;
  void Check() const;  // InputError naming the field
};

// What one head's frame gave.
struct HeadResult {
  bool has_frame = false;
  SolveStatus status = SolveStatus::kNoFrame;
  SolveMode mode = SolveMode::kLostInSpace;  // when solved
  int detections = 0, matches = 0;
  double false_match_probability = 1, photometric_factor = 1;  // the identification's (identify.h)
  double sigma_cross_arcsec = 0, sigma_roll_arcsec = 0;  // this head's own solution
  Quat q_inertial_from_sensor = Quat::Identity();        // when solved
  std::map<std::string, double> timing_ms;               // detect, identify, attitude, total (options.diagnostics)
  double detect_ms = 0, identify_ms = 0, attitude_ms = 0, total_ms = 0;  // the same (0 without diagnostics)
};

// What one set of simultaneous frames gave.
struct FrameReport {
  double t_s = 0;
  std::vector<HeadResult> heads;
  SolveStatus status = SolveStatus::kNoMatch;  // solved (at least one head) or the reason nothing was solved
  int heads_solved = 0;
  Quat q_inertial_from_body = Quat::Identity();  // the star-only body attitude (all solved heads)
  Mat3 covariance_rad2 = Mat3::Zero();           // its error covariance, body axes
  bool initialised_filter = false;               // this solution started the filter
  MekfUpdate update;                             // the filter update it made
  double total_ms = 0;                           // detect + solve + update, all heads
};

// The unit's current estimate.
struct UnitAttitude {
  bool valid = false;  // false until the first solved frame, and while the filter awaits a restart
  double t_s = 0;
  Quat q_inertial_from_body = Quat::Identity();
  Mat3 covariance_rad2 = Mat3::Zero();  // attitude error, body axes
  Vec3 bias_dph = Vec3::Zero(), bias_sigma_dph = Vec3::Zero();
  std::vector<FaultEvent> faults;
  std::vector<int> gyros_in_use;                // 1-based
  FusionStatus status = FusionStatus::kFailed;  // OnlineFusion::Status()
  bool restart_pending = false;                 // the filter restarts from the next solved frame
  RestartReason last_restart = RestartReason::kNone;
  long restarts = 0;
  long gyro_samples_refused = 0;  // gyro samples not used (every rejected_* status)
  long gyro_samples_partial = 0;  // used with an output dropped
  long frames_refused = 0;        // frame sets with a bad_frame head or refused as a whole
  // The in-flight calibration of the unit's scale factors and tilts (options.fuse.calibrate_unit;
  // status "off" without it).
  UnitCalState unit_calibration;
};

class UnitProcessor {
 public:
  // One identifier per head (heads with the same camera may share one). InputError for 0 or more than
  // 3 heads, a missing identifier, a bad camera, unit or options.
  // The workspaces (detection, identification, the fusion's fault monitors and histories: nearly all
  // the memory) come from `mr`: the heap by default, the caller's block in the flight core (an Arena,
  // core/arena.h; WorkspaceBytes says how large).
  UnitProcessor(std::vector<OpticalHead> heads, std::vector<std::shared_ptr<const StarIdentifier>> identifiers,
                const GyroUnit& unit, const UnitProcessorOptions& options,
                std::pmr::memory_resource* mr = std::pmr::get_default_resource());
  // Bytes of an Arena that holds the workspaces of a processor made with these arguments (measured by
  // making them once on the heap: for start-up, not the rate group). InputError as the constructor.
  static size_t WorkspaceBytes(const std::vector<OpticalHead>& heads, const GyroUnit& unit,
                               const UnitProcessorOptions& options);

  // A gyro sample: the outputs g1..gN (deg/h), mean over (t_prev, t_s], in time order. What became of
  // it is the status (OnlineFusion::AddGyro); allocates nothing.
  GyroSampleStatus OnGyroSample(double t_s, const GyroVec& g_dph);
  // Frames taken at t_s (mid-exposure), one view per head in head order; a view with data == nullptr
  // means that head has no frame this time. Expected failures (no stars, no match) and bad input are
  // in the report: a view of the wrong size or stride is that head's "bad_frame", a wrong number of
  // views or a non-finite t_s makes every head's (and the report's) status "bad_frame".
  FrameReport OnFrames(double t_s, const std::vector<ImageView>& images);
  // The same into a caller-owned report (its vectors keep their capacity).
  void OnFrames(double t_s, const std::vector<ImageView>& images, FrameReport* out);

  UnitAttitude Attitude() const;
  // Into a caller-owned one (its vectors keep their capacity). Without `with_faults` out->faults is
  // left empty: copying an event copies its residual list, which allocates; fusion().faults() is the
  // same list, read in place.
  void Attitude(UnitAttitude* out, bool with_faults = true) const;
  const std::vector<OpticalHead>& heads() const { return heads_; }
  const OnlineFusion& fusion() const { return fusion_; }
  // Heap bytes of the per-frame buffers, all taken at construction (docs/flight.md, "Memory"): the
  // detector's workspace with its detection and centroid lists; the identification workspace with
  // each head's reserved result.
  size_t DetectBytes() const;
  size_t IdentifyBytes() const;

 private:
  void SolveHead(int h, double t_s, const ImageView& image, Identification* id, HeadResult* r);

  std::vector<OpticalHead> heads_;
  std::vector<std::shared_ptr<const StarIdentifier>> ids_;
  // A gyro sample was used: the body rate handed to the detector (expected smear,
  // SolveOptions::detect.smear: active when its exposure_s > 0) is the fusion's last rate.
  bool have_gyro_ = false;
  std::vector<Identification> ids_scratch_;  // per head, reused frame to frame
  std::vector<DefectMap> hot_;               // per head: its camera's known hot pixels (empty when none)
  // The heads are solved one after the other: one detector workspace (for the largest head), one
  // detection list and one centroid list serve them all, sized at construction.
  DetectWorkspace detect_ws_;
  Detections detections_;
  std::vector<Centroid> centroids_;
  IdentifyWorkspace identify_ws_;
  std::vector<Quat> mounts_;
  long frames_refused_ = 0;
  UnitProcessorOptions options_;
  OnlineFusion fusion_;
  Mat3 last_fix_covariance_ = Mat3::Zero();  // of the last accepted solution (body axes, rad^2)
};

}  // namespace ssiu
