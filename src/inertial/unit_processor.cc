#include "inertial/unit_processor.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "attitude/quest.h"
#include "core/error.h"
#include "detect/detect.h"

namespace ssiu {
namespace {

// The smallest covariance >= p (in the PSD order along the floor's principal axes) that is at least
// `floor` along each of them: p + sum_i max(0, l_i - v_i' p v_i) v_i v_i' over floor's eigenpairs.
Mat3 FloorCovariance(const Mat3& p, const Mat3& floor) {
  const Eigen::SelfAdjointEigenSolver<Mat3> es(floor);
  Mat3 out = p;
  for (int i = 0; i < 3; ++i) {
    const Vec3 v = es.eigenvectors().col(i);
    const double short_by = es.eigenvalues()[i] - v.dot(p * v);
    if (short_by > 0) out += short_by * v * v.transpose();
  }
  return out;
}

// One detector workspace for every head (they are solved in turn): room for the largest frame and
// the most stars detection keeps (DetectOptions::max_stars). Lists clamp at their limits rather than
// grow (Detections::clamped), so a frame set never allocates.
DetectLimits ProcessorDetectLimits(const std::vector<OpticalHead>& heads, const UnitProcessorOptions& o) {
  DetectLimits l;
  l.max_width = l.max_height = 16;
  for (const auto& h : heads) {
    l.max_width = std::max(l.max_width, h.camera.width);
    l.max_height = std::max(l.max_height, h.camera.height);
  }
  l.max_detections = std::max(1, o.solve.detect.max_stars);
  l.min_tile_px = std::clamp(std::min(l.min_tile_px, o.solve.detect.tile_px), 8, 1024);
  l.diagnostics = o.diagnostics;
  l.grow = false;
  return l;
}

// Times for the report, read only with options.diagnostics: the flight path reads no clock (nothing
// it computes depends on time, and the rate group's own timer is the integrator's).
class Stopwatch {
 public:
  using Clock = std::chrono::steady_clock;
  explicit Stopwatch(bool on) : on_(on), t0_(on ? Clock::now() : Clock::time_point()) {}
  double Ms() const { return on_ ? std::chrono::duration<double, std::milli>(Clock::now() - t0_).count() : 0.0; }

 private:
  bool on_;
  Clock::time_point t0_;
};

// The per-frame outputs in `mr` with the room a call may fill: the detection lists and each head's
// matches (the processor's, made after its workspaces).
void ReserveOutputs(const DetectWorkspace& detect, const IdentifyWorkspace& identify, std::pmr::memory_resource* mr,
                    Detections* detections, std::vector<Identification>* ids) {
  UseResource(&detections->stars, mr);
  UseResource(&detections->rejected, mr);
  detect.Reserve(detections);
  for (auto& id : *ids) {
    UseResource(&id.matches, mr);
    identify.Reserve(&id);
  }
}

// A head's known hot pixels (camera.json `hot_pixels`) as its defect map, in `mr`: empty, taking no
// memory, when it lists none.
DefectMap HotPixelMap(const OpticalHead& head, std::pmr::memory_resource* mr, const std::string& what) {
  DefectMap m;
  UseResource(&m.mask, mr);
  MarkHotPixels(head.extras.hot_pixels, head.camera.width, head.camera.height, &m, what);
  return m;
}

IdentifyWorkspace MakeIdentifyWorkspace(const UnitProcessorOptions& o, std::pmr::memory_resource* mr) {
  return IdentifyWorkspace(std::max(1, o.solve.detect.max_stars), std::max(1, o.max_stars_in_field),
                           std::clamp(o.solve.identify.pattern_centroids, 3, 1000),
                           std::clamp(o.solve.identify.verify_centroids, 3, 100000), mr);
}

}  // namespace

size_t UnitProcessor::WorkspaceBytes(const std::vector<OpticalHead>& heads, const GyroUnit& unit,
                                     const UnitProcessorOptions& options) {
  options.Check();
  // The constructor's order (the members' declaration order), so that the alignment gaps are the same.
  Arena meter = Arena::Meter();
  {
    const DetectWorkspace detect(ProcessorDetectLimits(heads, options), &meter);
    const IdentifyWorkspace identify = MakeIdentifyWorkspace(options, &meter);
    const OnlineFusion fusion(unit, options.fuse, &meter);
    std::vector<DefectMap> hot;
    for (const OpticalHead& h : heads) hot.push_back(HotPixelMap(h, &meter, "head camera"));
    Detections detections;
    std::vector<Identification> ids(heads.size());
    ReserveOutputs(detect, identify, &meter, &detections, &ids);
  }
  return meter.used();
}

void UnitProcessorOptions::Check() const {
  solve.Check();
  fuse.Check();
  if (!(solution_sigma_scale > 0 && solution_sigma_scale < 100)) {
    throw InputError("processor options", "solution_sigma_scale must be in (0, 100)");
  }
  if (!(solution_sigma_floor_arcsec >= 0 && solution_sigma_floor_arcsec < 3600)) {
    throw InputError("processor options", "solution_sigma_floor_arcsec must be in [0, 3600)");
  }
  if (!(correlated_fraction >= 0 && correlated_fraction <= 1)) {
    throw InputError("processor options", "correlated_fraction must be in [0, 1]");
  }
  if (!(max_stars_in_field >= 1 && max_stars_in_field <= 100000)) {
    throw InputError("processor options", "max_stars_in_field must be in [1, 100000]");
  }
}

UnitProcessor::UnitProcessor(std::vector<OpticalHead> heads,
                             std::vector<std::shared_ptr<const StarIdentifier>> identifiers, const GyroUnit& unit,
                             const UnitProcessorOptions& options, std::pmr::memory_resource* mr)
    : heads_(std::move(heads)),
      ids_(std::move(identifiers)),
      detect_ws_(ProcessorDetectLimits(heads_, options), mr),
      identify_ws_(MakeIdentifyWorkspace(options, mr)),
      options_(options),
      fusion_(unit, options.fuse, mr) {
  options_.Check();
  if (heads_.empty() || heads_.size() > static_cast<size_t>(kMaxHeads)) {
    throw InputError("heads", "the unit has 1 to 3 optical heads, not " + std::to_string(heads_.size()));
  }
  if (ids_.size() != heads_.size()) throw InputError("heads", "one star identifier per head is needed");
  hot_.reserve(heads_.size());
  for (size_t h = 0; h < heads_.size(); ++h) {
    if (!ids_[h]) throw InputError("heads", "head " + std::to_string(h + 1) + " has no star identifier");
    const std::string what = "head " + std::to_string(h + 1) + " camera";
    heads_[h].camera.Check(what);
    const CameraExtras& e = heads_[h].extras;
    if (!(e.vignetting >= 0 && e.vignetting < 1)) throw InputError(what, "vignetting must be in [0, 1)");
    hot_.push_back(HotPixelMap(heads_[h], mr, what));  // repaired before detection
    heads_[h].q_body_from_sensor.normalize();
    mounts_.push_back(heads_[h].q_body_from_sensor);
  }
  ids_scratch_.resize(heads_.size());
  ReserveOutputs(detect_ws_, identify_ws_, mr, &detections_, &ids_scratch_);
  identify_ws_.diagnostics = options_.diagnostics;
  centroids_.reserve(static_cast<size_t>(detect_ws_.limits().max_detections));
}

size_t UnitProcessor::DetectBytes() const {
  return detect_ws_.Bytes() + detect_ws_.OutputBytes() + centroids_.capacity() * sizeof(Centroid);
}

size_t UnitProcessor::IdentifyBytes() const {
  size_t b = identify_ws_.Bytes();
  for (const auto& id : ids_scratch_) b += id.matches.capacity() * sizeof(StarMatch);
  return b;
}

GyroSampleStatus UnitProcessor::OnGyroSample(double t_s, const GyroVec& g_dph) {
  const GyroSampleStatus s = fusion_.AddGyro(t_s, g_dph);
  have_gyro_ |= GyroSampleUsed(s);
  return s;
}

void UnitProcessor::SolveHead(int h, double t_s, const ImageView& image, Identification* id, HeadResult* out) {
  const Stopwatch t0(options_.diagnostics);
  HeadResult& r = *out;
  r = HeadResult();
  r.has_frame = true;
  const OpticalHead& head = heads_[h];
  const StarIdentifier& sid = *ids_[h];
  const SolveOptions& so = options_.solve;
  if (image.width != head.camera.width || image.height != head.camera.height || image.stride < image.width) {
    r.status = SolveStatus::kBadFrame;  // nothing to solve from (a wrong stride would read out of bounds)
    return;
  }
  DetectOptions dopt = so.detect;
  UseCameraExtras(head.extras, &dopt);  // camera.json's psf_sigma_px, as `ssiu solve`
  if (dopt.gain_e_per_adu == 0) dopt.gain_e_per_adu = head.camera.gain_e_per_adu;
  if (dopt.smear.exposure_s > 0 && have_gyro_) {
    // Motion during the exposure: the body rate of the last gyro sample (gyros in use, faults
    // compensated, less the estimated bias) in this head's sensor axes. Its error (deg/h) is far
    // below what smears.
    const Vec3 w_body = fusion_.last_rate_rad_s() - (fusion_.initialised() ? fusion_.bias_rad_s() : Vec3::Zero());
    dopt.smear.rate_rad_s = head.q_body_from_sensor.conjugate() * w_body;
    dopt.smear.camera = head.camera;
  }
  if (Detect(image, dopt, &hot_[h], &detect_ws_, &detections_) != DetectStatus::kOk) {
    // Options were checked at construction and the size above: what is left is a frame the detector
    // cannot take (e.g. smaller than its smallest tile).
    r.status = SolveStatus::kBadFrame;
    return;
  }
  r.detect_ms = t0.Ms();
  r.detections = static_cast<int>(detections_.stars.size());
  CentroidsFromDetections(detections_, so.detector_sigma_scale, &centroids_);
  TakeOutVignetting(head.camera, head.extras.vignetting, &centroids_);  // in place (SolveCentroids' fluxes)
  const std::vector<Centroid>& c = centroids_;

  // Tracking around the attitude the gyros carried forward; lost in space before the first fix or
  // when tracking fails (the same fallback as attitude/star_solver.h's Tracker). While the fused
  // attitude is suspect (a gyro fault not yet resolved, a restart pending) its prediction may be far
  // off and would pull tracking onto wrong stars: lost in space first, then tracking with a search
  // radius four times wider.
  const Stopwatch t1(options_.diagnostics);
  const bool suspect = fusion_.initialised() && (fusion_.Status() != FusionStatus::kOk || fusion_.restart_pending());
  if (fusion_.initialised() && !suspect) {
    const Quat q_pred = fusion_.q() * head.q_body_from_sensor;
    sid.MatchWithAttitude(c, head.camera, q_pred, so.track_search_radius_px, so.identify, &identify_ws_, id);
    r.mode = SolveMode::kTracking;
  }
  if (!fusion_.initialised() || suspect || id->status != SolveStatus::kSolved) {
    sid.Identify(c, head.camera, so.identify, &identify_ws_, id);
    r.mode = SolveMode::kLostInSpace;
  }
  if (suspect && id->status != SolveStatus::kSolved) {
    const Quat q_pred = fusion_.q() * head.q_body_from_sensor;
    sid.MatchWithAttitude(c, head.camera, q_pred, 4 * so.track_search_radius_px, so.identify, &identify_ws_, id);
    r.mode = SolveMode::kTracking;
  }
  r.identify_ms = t1.Ms();
  r.status = id->status;
  r.false_match_probability = id->false_match_probability;
  r.photometric_factor = id->photometric_factor;
  if (id->status == SolveStatus::kSolved) {
    SkyCorrections sky = so.sky;  // the frame's time: the unit's clock t_s from sky.time
    if (sky.active()) sky.time = AddSeconds(sky.time, t_s);
    ApplySkyCorrections(sid, sky, id);
    const Stopwatch t2(options_.diagnostics);
    const AttitudeSolution a = SolveAttitude(*id);
    r.attitude_ms = t2.Ms();
    r.matches = static_cast<int>(id->matches.size());
    r.q_inertial_from_sensor = a.q_inertial_from_sensor;
    r.sigma_cross_arcsec = a.sigma_cross_rad * kRadToArcsec;
    r.sigma_roll_arcsec = a.sigma_roll_rad * kRadToArcsec;
  }
  r.total_ms = t0.Ms();
  if (options_.diagnostics) {
    r.timing_ms["detect"] = r.detect_ms;
    r.timing_ms["identify"] = r.identify_ms;
    if (id->status == SolveStatus::kSolved) r.timing_ms["attitude"] = r.attitude_ms;
    r.timing_ms["total"] = r.total_ms;
  }
}

FrameReport UnitProcessor::OnFrames(double t_s, const std::vector<ImageView>& images) {
  FrameReport f;
  OnFrames(t_s, images, &f);
  return f;
}

void UnitProcessor::OnFrames(double t_s, const std::vector<ImageView>& images, FrameReport* out) {
  const Stopwatch t0(options_.diagnostics);
  FrameReport& f = *out;
  f.heads.resize(heads_.size());
  f.t_s = t_s;
  f.status = SolveStatus::kNoMatch;
  f.heads_solved = 0;
  f.q_inertial_from_body = Quat::Identity();
  f.covariance_rad2 = Mat3::Zero();
  f.initialised_filter = false;
  f.update = MekfUpdate();
  f.total_ms = 0;
  if (images.size() != heads_.size() || !std::isfinite(t_s)) {
    // Which view belongs to which head is unknown (or when it was taken): nothing is used.
    for (auto& h : f.heads) {
      h = HeadResult();
      h.status = SolveStatus::kBadFrame;
    }
    f.status = SolveStatus::kBadFrame;
    ++frames_refused_;
    f.total_ms = t0.Ms();
    return;
  }
  bool bad = false;
  for (size_t h = 0; h < heads_.size(); ++h) {
    ids_scratch_[h].matches.clear();
    ids_scratch_[h].status = SolveStatus::kNoFrame;
    if (images[h].data == nullptr) {
      f.heads[h] = HeadResult();
      continue;
    }
    SolveHead(static_cast<int>(h), t_s, images[h], &ids_scratch_[h], &f.heads[h]);
    bad |= f.heads[h].status == SolveStatus::kBadFrame;
    if (f.heads[h].status == SolveStatus::kSolved) ++f.heads_solved;
  }
  frames_refused_ += bad;
  if (f.heads_solved == 0) {
    f.status = SolveStatus::kNoFrame;
    for (const auto& h : f.heads) {
      if (h.has_frame) f.status = h.status;  // the last head's reason
    }
    f.total_ms = t0.Ms();
    return;
  }
  // One QUEST over the matches of every solved head, in body axes (attitude/quest.h SolveMultiHead).
  const AttitudeSolution body = SolveMultiHead(ids_scratch_, mounts_);
  if (body.status != SolveStatus::kSolved) {
    f.status = body.status;
    f.total_ms = t0.Ms();
    return;
  }
  f.status = SolveStatus::kSolved;
  f.q_inertial_from_body = body.q_inertial_from_sensor;
  const double s = options_.solution_sigma_scale;
  const double floor_rad = options_.solution_sigma_floor_arcsec * kArcsecToRad;
  f.covariance_rad2 = body.covariance_rad2 * (s * s) + Mat3::Identity() * (floor_rad * floor_rad);
  f.initialised_filter = !fusion_.initialised() || fusion_.restart_pending();
  f.update = fusion_.AddAttitude(t_s, f.q_inertial_from_body, f.covariance_rad2);
  f.initialised_filter = f.initialised_filter && f.update.status == UpdateStatus::kInitialised;
  if (f.update.accepted) last_fix_covariance_ = f.covariance_rad2;
  f.total_ms = t0.Ms();
}

UnitAttitude UnitProcessor::Attitude() const {
  UnitAttitude a;
  Attitude(&a);
  return a;
}

void UnitProcessor::Attitude(UnitAttitude* out, bool with_faults) const {
  UnitAttitude& a = *out;
  a.valid = fusion_.initialised() && !fusion_.restart_pending();
  a.t_s = fusion_.t_s();
  a.q_inertial_from_body = fusion_.q();
  a.covariance_rad2 = FloorCovariance(fusion_.P().block<3, 3>(MekfIndex::kAttitude, MekfIndex::kAttitude),
                                      options_.correlated_fraction * last_fix_covariance_);
  a.bias_dph = fusion_.bias_rad_s() * kRadSToDph;
  a.bias_sigma_dph = fusion_.bias_sigma_dph();
  if (with_faults) {
    a.faults = fusion_.faults();
  } else {
    a.faults.clear();
  }
  a.gyros_in_use.clear();
  const std::vector<bool>& use = fusion_.gyros_in_use_mask();
  for (size_t i = 0; i < use.size(); ++i) {
    if (use[i]) a.gyros_in_use.push_back(static_cast<int>(i) + 1);
  }
  a.status = fusion_.Status();
  a.restart_pending = fusion_.restart_pending();
  a.last_restart = fusion_.last_restart();
  a.restarts = fusion_.n_restarts();
  a.gyro_samples_refused = 0;
  for (int k = 0; k < kGyroSampleStatusCount; ++k) {
    const auto st = static_cast<GyroSampleStatus>(k);
    if (!GyroSampleUsed(st)) a.gyro_samples_refused += fusion_.n_gyro_status(st);
  }
  a.gyro_samples_partial = fusion_.n_gyro_status(GyroSampleStatus::kAcceptedPartial);
  a.frames_refused = frames_refused_;
  a.unit_calibration = fusion_.unit_calibration();
}

}  // namespace ssiu
