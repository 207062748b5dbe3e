#include "sim/mission.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/csv.h"
#include "core/error.h"
#include "inertial/propagate.h"

namespace ssiu {
namespace {

using Clock = std::chrono::steady_clock;
double SecondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Deterministic, well-mixed per-frame seeds (splitmix64 finaliser).
uint64_t Mix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Error of q_est against q_true as a rotation vector in body axes (q_est = q_true * exp(e)).
Vec3 BodyError(const Quat& q_est, const Quat& q_true) { return RotationVectorFromQuat(q_true.conjugate() * q_est); }

struct ErrorAccumulator {
  double sc = 0, sr = 0, mc = 0, mr = 0;
  long n = 0;
  void Add(const Vec3& e_sensor) {
    const double c = std::hypot(e_sensor.x(), e_sensor.y()) * kRadToArcsec;
    const double r = std::abs(e_sensor.z()) * kRadToArcsec;
    sc += c * c;
    sr += r * r;
    mc = std::max(mc, c);
    mr = std::max(mr, r);
    ++n;
  }
  ErrorStats Stats() const {
    ErrorStats s;
    s.n = n;
    if (n == 0) return s;
    s.cross_rms_arcsec = std::sqrt(sc / n);
    s.roll_rms_arcsec = std::sqrt(sr / n);
    s.cross_max_arcsec = mc;
    s.roll_max_arcsec = mr;
    return s;
  }
};

Json StatsJson(const ErrorStats& s) {
  return {{"cross_rms_arcsec", s.cross_rms_arcsec},
          {"cross_max_arcsec", s.cross_max_arcsec},
          {"roll_rms_arcsec", s.roll_rms_arcsec},
          {"roll_max_arcsec", s.roll_max_arcsec},
          {"samples", s.n}};
}
Json V3(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

void MissionConfig::Check(const std::string& file) const {
  if (!(duration_s > 0 && duration_s <= 86400)) throw InputError(file, "field 'duration_s' must be in (0, 86400]");
  if (!(frame_rate_hz > 0 && frame_rate_hz <= 100)) throw InputError(file, "field 'frame_rate_hz' must be in (0, 100]");
  if (duration_s * frame_rate_hz > 100000)
    throw InputError(file, "more than 100000 frame times (duration_s * frame_rate_hz)");
  if (heads.empty() || heads.size() > static_cast<size_t>(kMaxHeads)) {
    throw InputError(file, "field 'heads': " + std::to_string(heads.size()) + " heads given, the unit has 1 to 3");
  }
  for (size_t h = 0; h < heads.size(); ++h) heads[h].camera.Check(file + ": heads[" + std::to_string(h) + "].camera");
  unit.Check(file + ": gyro_unit");
  motion.Check(file + ": motion", unit.size());
  try {
    frame_sim.Check();
  } catch (const InputError& e) {
    throw InputError(file + ": frame_sim: " + e.what());
  }
  // Each frame is smeared by the true rate, and the frame simulator takes up to 90 deg/s per axis:
  // refuse the motion here, naming it, rather than fail at the first fast frame.
  for (long i = 0; i / frame_rate_hz <= duration_s + 1e-9; ++i) {
    const double t_s = i / frame_rate_hz, w_dps = motion.RateBodyRadS(t_s).norm() * kRadToDeg;
    if (!(w_dps <= 90)) {
      std::ostringstream msg;
      msg << "field 'motion': the body rate reaches " << w_dps << " deg/s at t = " << t_s
          << " s; frames are simulated up to 90 deg/s";
      throw InputError(file, msg.str());
    }
  }
  try {
    processor.Check();
  } catch (const InputError& e) {
    throw InputError(file + ": processor: " + e.what());
  }
  if (!(score_after_s >= 0 && score_after_s < duration_s)) {
    throw InputError(file, "field 'score_after_s' must be in [0, duration_s)");
  }
  ParseUtcIso8601(start_utc, file + ": field 'start_utc'");
  if (!velocity_kms.allFinite() || velocity_kms.norm() > 100)
    throw InputError(file, "field 'velocity_kms' must be [x, y, z] km/s, at most 100 km/s");
}

SkyCorrections MissionSky(const MissionConfig& c) {
  SkyCorrections s;
  s.time = ParseUtcIso8601(c.start_utc, "mission: field 'start_utc'");
  s.have_velocity = c.velocity_kms.norm() > 0;
  s.velocity_m_s = c.velocity_kms * 1000.0;
  return s;
}

MissionConfig DefaultMissionConfig() {
  MissionConfig c;
  // Two heads of 512x512 px and 16.6 deg: head 1 along body +Z, head 2 along body -Y (90 deg about
  // body +X), so that each head's poorly observed roll is the other's cross-boresight.
  OpticalHead h1;
  h1.camera = MakeCamera(512, 512, 16.6);
  OpticalHead h2 = h1;
  h2.q_body_from_sensor = Quat(Eigen::AngleAxisd(90 * kDegToRad, Vec3::UnitX()));
  c.heads = {h1, h2};
  // Four FOGs (three orthogonal plus one skewed) with turn-on biases of a few deg/h.
  c.unit = DefaultFourFogUnit();
  const double biases_dph[4] = {2.0, -3.0, 1.5, 2.5};
  for (int i = 0; i < 4; ++i) c.unit.gyros[i].bias_dph = biases_dph[i];
  c.motion.type = "slew";
  c.motion.rate_dps = 0.1;
  c.motion.axis_body = Vec3(0.3, -0.5, 0.8).normalized();
  c.motion.q0 = QuatFromRaDecRoll(84.0 * kDegToRad, -1.0 * kDegToRad, 0.0);  // head 1 near Orion's belt
  // The simulated frames have no lens distortion and draw the solver's own catalog, so the centroid
  // error the solver does not model is small (the identify default of 0.5 px is for real optics).
  // It sets the solutions' covariance, and so how much the filter trusts each frame.
  c.processor.solve.identify.systematic_px = 0.1;
  return c;
}

MissionConfig MissionConfigFromJson(const Json& j, const std::string& file) {
  if (!j.is_object()) throw InputError(file, "the config must be a JSON object");
  CheckKeys(j,
            {"duration_s", "frame_rate_hz", "seed", "heads", "gyro_unit", "motion", "frame_sim", "processor",
             "score_after_s", "start_utc", "velocity_kms", "comment"},
            file);
  MissionConfig c = DefaultMissionConfig();
  c.duration_s = JsonNumber(j, "duration_s", file);
  c.frame_rate_hz = JsonNumber(j, "frame_rate_hz", file);
  c.seed = static_cast<uint64_t>(JsonInt(j, "seed", 0, 9000000000000000LL, file));
  c.score_after_s = JsonNumberOr(j, "score_after_s", std::min(c.score_after_s, 0.5 * c.duration_s), file);

  if (!j.contains("heads")) throw InputError(file, "missing field 'heads'");
  c.heads = HeadsFromJson(j.at("heads"), file, "heads");
  if (j.contains("gyro_unit")) c.unit = GyroUnitFromJson(j.at("gyro_unit"), file + ": gyro_unit");
  if (j.contains("motion")) c.motion = MotionProfileFromJson(j.at("motion"), file + ": motion");
  if (j.contains("frame_sim")) c.frame_sim = FrameSimOptionsFromJson(j.at("frame_sim"), file + ": frame_sim");
  if (j.contains("start_utc")) {
    if (!j.at("start_utc").is_string()) throw InputError(file, "field 'start_utc' must be an ISO 8601 UTC string");
    c.start_utc = j.at("start_utc").get<std::string>();
  }
  if (j.contains("velocity_kms")) {
    const Json& v = j.at("velocity_kms");
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
      throw InputError(file, "field 'velocity_kms' must be [x, y, z] km/s (ICRS)");
    c.velocity_kms = Vec3(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
  }
  if (j.contains("processor")) {
    const Json& p = j.at("processor");
    const std::string what = file + ": processor";
    if (!p.is_object()) throw InputError(what, "must be an object");
    CheckKeys(p,
              {"threshold_sigma", "systematic_px", "track_search_radius_px", "nis_gate", "init_bias_sigma_dph",
               "bias_drift_floor_dph_per_sqrt_h", "fdi", "solution_sigma_scale", "solution_sigma_floor_arcsec",
               "correlated_fraction", "calibrate_unit"},
              what);
    UnitProcessorOptions& o = c.processor;
    o.solve.identify.systematic_px = JsonNumberOr(p, "systematic_px", o.solve.identify.systematic_px, what);
    o.solve.detect.threshold_sigma = JsonNumberOr(p, "threshold_sigma", o.solve.detect.threshold_sigma, what);
    o.solve.track_search_radius_px = JsonNumberOr(p, "track_search_radius_px", o.solve.track_search_radius_px, what);
    o.fuse.nis_gate = JsonNumberOr(p, "nis_gate", o.fuse.nis_gate, what);
    o.fuse.init_bias_sigma_dph = JsonNumberOr(p, "init_bias_sigma_dph", o.fuse.init_bias_sigma_dph, what);
    o.fuse.bias_drift_floor_dph_per_sqrt_h =
        JsonNumberOr(p, "bias_drift_floor_dph_per_sqrt_h", o.fuse.bias_drift_floor_dph_per_sqrt_h, what);
    o.solution_sigma_scale = JsonNumberOr(p, "solution_sigma_scale", o.solution_sigma_scale, what);
    o.solution_sigma_floor_arcsec = JsonNumberOr(p, "solution_sigma_floor_arcsec", o.solution_sigma_floor_arcsec, what);
    o.correlated_fraction = JsonNumberOr(p, "correlated_fraction", o.correlated_fraction, what);
    o.fuse.fdi = JsonBoolOr(p, "fdi", o.fuse.fdi, what);
    o.fuse.calibrate_unit = JsonBoolOr(p, "calibrate_unit", o.fuse.calibrate_unit, what);
  }
  c.Check(file);
  return c;
}

MissionConfig LoadMissionConfig(const std::string& path) { return MissionConfigFromJson(ReadJsonFile(path), path); }

Json MissionConfigToJson(const MissionConfig& c) {
  Json heads = Json::array();
  for (const auto& h : c.heads) {
    const auto q = ToWxyz(h.q_body_from_sensor);
    heads.push_back({{"camera", CameraToJson(h.camera)}, {"q_body_sensor", {q[0], q[1], q[2], q[3]}}});
  }
  const auto q0 = ToWxyz(c.motion.q0);
  Json motion = {
      {"type", c.motion.type},         {"q0", {q0[0], q0[1], q0[2], q0[3]}},          {"axis", V3(c.motion.axis_body)},
      {"rate_dps", c.motion.rate_dps}, {"amplitude_dps", V3(c.motion.amplitude_dps)}, {"period_s", c.motion.period_s}};
  if (!c.motion.faults.empty()) {
    Json f = Json::array();
    for (const auto& g : c.motion.faults) f.push_back(g.ToJson());
    motion["faults"] = f;
  }
  if (!c.motion.st_outages_s.empty()) motion["star_tracker"] = {{"outages_s", c.motion.st_outages_s}};
  const UnitProcessorOptions& o = c.processor;
  return {{"duration_s", c.duration_s},
          {"frame_rate_hz", c.frame_rate_hz},
          {"seed", c.seed},
          {"score_after_s", c.score_after_s},
          {"start_utc", c.start_utc},
          {"velocity_kms", V3(c.velocity_kms)},
          {"heads", heads},
          {"gyro_unit", GyroUnitToJson(c.unit)},
          {"motion", motion},
          {"frame_sim", FrameSimOptionsToJson(c.frame_sim)},
          {"processor",
           {{"threshold_sigma", o.solve.detect.threshold_sigma},
            {"systematic_px", o.solve.identify.systematic_px},
            {"track_search_radius_px", o.solve.track_search_radius_px},
            {"nis_gate", o.fuse.nis_gate},
            {"init_bias_sigma_dph", o.fuse.init_bias_sigma_dph},
            {"bias_drift_floor_dph_per_sqrt_h", o.fuse.bias_drift_floor_dph_per_sqrt_h},
            {"fdi", o.fuse.fdi},
            {"solution_sigma_scale", o.solution_sigma_scale},
            {"solution_sigma_floor_arcsec", o.solution_sigma_floor_arcsec},
            {"correlated_fraction", o.correlated_fraction},
            {"calibrate_unit", o.fuse.calibrate_unit}}}};
}

MissionData SimulateMission(const MissionConfig& config) {
  config.Check("mission");
  MissionData d;
  GyroSimOptions go;
  go.duration_s = config.duration_s;
  go.seed = config.seed;
  d.gyro = SimulateGyro(config.unit, config.motion, go);
  for (long i = 0;; ++i) {
    const double t = i / config.frame_rate_hz;
    if (t > config.duration_s + 1e-9) break;
    // motion.star_tracker.outages_s: the heads take no frames then (sun or moon in the field, eclipse).
    if (!config.motion.InStarOutage(t)) d.frame_t_s.push_back(t);
  }
  return d;
}

Quat TrueAttitudeAt(const MissionData& data, double t_s) {
  const auto& t = data.gyro.t_s;
  const auto& q = data.gyro.q_true;
  if (t.empty() || t_s <= 0) return data.gyro.q0;
  const size_t k = std::upper_bound(t.begin(), t.end(), t_s) - t.begin();  // first sample after t_s
  if (k >= t.size()) return q.back();
  const double t0 = k == 0 ? 0.0 : t[k - 1];
  const Quat q0 = k == 0 ? data.gyro.q0 : q[k - 1];
  const double a = (t_s - t0) / (t[k] - t0);
  return q0.slerp(a, q[k]).normalized();
}

SimulatedFrame SimulateMissionFrame(const MissionConfig& config, const MissionData& data, const StarCatalog& catalog,
                                    int frame, int head) {
  const OpticalHead& h = config.heads.at(head);
  FrameSimOptions so = config.frame_sim;
  so.defect_seed = config.frame_sim.defect_seed + head;  // each head its own sensor defects
  const double t_s = data.frame_t_s.at(frame);
  const Quat q_sensor = TrueAttitudeAt(data, t_s) * h.q_body_from_sensor;
  // Motion during the exposure: the true body rate at mid-exposure in this head's sensor axes (it
  // replaces any rate given in frame_sim).
  const Vec3 w_sensor_dps = h.q_body_from_sensor.conjugate() * config.motion.RateBodyRadS(t_s) * kRadToDeg;
  so.rate_x_dps = w_sensor_dps.x();
  so.rate_y_dps = w_sensor_dps.y();
  so.rate_z_dps = w_sensor_dps.z();
  // The mission clock and the spacecraft's velocity.
  so.time_utc = FormatUtcIso8601(AddSeconds(MissionSky(config).time, t_s));
  so.velocity_x_kms = config.velocity_kms.x();
  so.velocity_y_kms = config.velocity_kms.y();
  so.velocity_z_kms = config.velocity_kms.z();
  const uint64_t seed = Mix(Mix(config.seed) ^ (static_cast<uint64_t>(frame) * kMaxHeads + head));
  return SimulateFrame(h.camera, catalog, q_sensor, so, seed);
}

MissionConfig WithUnitKnowledge(const MissionConfig& config_in) {
  MissionConfig config = config_in;
  // The processor knows its cameras' gain (a property of the unit); the simulator's is the truth.
  for (auto& h : config.heads) {
    if (h.camera.gain_e_per_adu == 0) h.camera.gain_e_per_adu = config.frame_sim.gain_e_per_adu;
  }
  // ... and its exposure, so that the detector expects the smear of the rate the gyros measure.
  if (config.processor.solve.detect.smear.exposure_s == 0) {
    config.processor.solve.detect.smear.exposure_s = config.frame_sim.exposure_s;
  }
  // ... and its clock and velocity, from which it removes proper motion and aberration.
  config.processor.solve.sky = MissionSky(config);
  return config;
}

namespace {

// One identifier per distinct field of view (MakeIdentifierForCamera's catalog key).
std::vector<std::shared_ptr<const StarIdentifier>> IdentifiersForHeads(const std::vector<OpticalHead>& heads) {
  std::map<long, std::shared_ptr<const StarIdentifier>> by_fov;
  std::vector<std::shared_ptr<const StarIdentifier>> ids;
  for (const auto& h : heads) {
    const long key = std::lround(h.camera.FovMaxRad() * kRadToDeg * 10);
    if (!by_fov.count(key)) {
      by_fov[key] = std::make_shared<const StarIdentifier>(MakeIdentifierForCamera("", h.camera, 0.0));
    }
    ids.push_back(by_fov[key]);
  }
  return ids;
}

// One mission run: the simulated gyro samples and frames fed to the unit processor in time order,
// its outputs scored against the truth and, with an output directory, recorded as CSV columns.
class MissionRun {
 public:
  MissionRun(const MissionConfig& config, const MissionData& data, const StarCatalog& catalog,
             const std::string& out_dir, bool write_frames, bool keep_history);
  MissionResult Run();

 private:
  void OnFrameTime(double t_f);
  std::vector<SimulatedFrame> SimulateFrameSet();
  void ScoreHeads(const FrameReport& fr);
  void RecordFrameRow(double t_f, const FrameReport& fr, const Vec3& e_star);
  void OnGyroSample(size_t k);
  void RecordAttitudeRow(size_t k, const UnitAttitude& a, const Vec3& e, int code);
  void Summarise();
  void WriteCsvs() const;

  const MissionConfig& config_;
  const MissionData& data_;
  const GyroSimulation& g_;
  const StarCatalog& catalog_;
  const std::string out_dir_;
  const int nh_;
  const bool write_, write_frames_, keep_history_;
  UnitProcessor proc_;
  MissionResult res_;
  const Quat q_sensor1_from_body_;
  ErrorAccumulator star_acc_, fused_acc_;
  long within_ = 0, axis_samples_ = 0, nees_n_ = 0, trusted_ = 0, trust_n_ = 0;
  FusionStatus worst_ = FusionStatus::kOk;
  double t_prev_status_ = -1;
  double nees_sum_ = 0, frame_ms_sum_ = 0, gyro_s_ = 0, sim_s_ = 0;
  std::vector<std::vector<double>> att_cols_, frame_cols_;
  bool first_valid_ = true;
  size_t fi_ = 0;  // the next frame time
};

MissionRun::MissionRun(const MissionConfig& config, const MissionData& data, const StarCatalog& catalog,
                       const std::string& out_dir, bool write_frames, bool keep_history)
    : config_(config),
      data_(data),
      g_(data.gyro),
      catalog_(catalog),
      out_dir_(out_dir),
      nh_(static_cast<int>(config.heads.size())),
      write_(!out_dir.empty()),
      write_frames_(write_frames && write_),
      keep_history_(keep_history),
      proc_(config.heads, IdentifiersForHeads(config.heads), config.unit, config.processor),
      q_sensor1_from_body_(config.heads[0].q_body_from_sensor.conjugate()) {
  res_.heads.resize(nh_);
  res_.frames = static_cast<int>(data.frame_t_s.size());
  if (write_) std::filesystem::create_directories(out_dir_);
  if (write_frames_) std::filesystem::create_directories(out_dir_ + "/frames");
  att_cols_.resize(write_ ? 19 : 0);
  frame_cols_.resize(write_ ? 6 + 5 * nh_ : 0);
}

// The gyro samples in time order, each frame time processed before the first sample after it.
MissionResult MissionRun::Run() {
  const auto t_run = Clock::now();
  for (size_t k = 0; k < g_.t_s.size(); ++k) {
    while (fi_ < data_.frame_t_s.size() && data_.frame_t_s[fi_] < g_.t_s[k] - 1e-9) OnFrameTime(data_.frame_t_s[fi_]);
    const auto t0 = Clock::now();
    proc_.OnGyroSample(g_.t_s[k], g_.gyro_dph[k]);
    gyro_s_ += SecondsSince(t0);
    while (fi_ < data_.frame_t_s.size() && data_.frame_t_s[fi_] <= g_.t_s[k] + 1e-9) OnFrameTime(data_.frame_t_s[fi_]);
    OnGyroSample(k);
  }
  while (fi_ < data_.frame_t_s.size()) OnFrameTime(data_.frame_t_s[fi_]);
  res_.process_s = SecondsSince(t_run) - sim_s_;
  res_.simulate_s = sim_s_;
  Summarise();
  if (write_) WriteCsvs();
  return res_;
}

// Frame fi_ of every head, rendered (its rendering time kept out of the processing time).
std::vector<SimulatedFrame> MissionRun::SimulateFrameSet() {
  const auto t0 = Clock::now();
  std::vector<SimulatedFrame> frames;
  for (int h = 0; h < nh_; ++h)
    frames.push_back(SimulateMissionFrame(config_, data_, catalog_, static_cast<int>(fi_), h));
  sim_s_ += SecondsSince(t0);
  if (write_ && fi_ == 0) {
    for (int h = 0; h < nh_; ++h)
      WritePng16(out_dir_ + "/head" + std::to_string(h + 1) + "_first.png", frames[h].image);
  }
  if (write_frames_) {
    for (int h = 0; h < nh_; ++h) WritePgm16(MissionFramePath(out_dir_, h, static_cast<int>(fi_)), frames[h].image);
  }
  return frames;
}

// The frames of one frame time through the processor; the star solution and the filter's NEES scored.
void MissionRun::OnFrameTime(double t_f) {
  const std::vector<SimulatedFrame> frames = SimulateFrameSet();
  std::vector<ImageView> views;
  for (const auto& f : frames) views.push_back(f.image.view());
  const FrameReport fr = proc_.OnFrames(t_f, views);
  frame_ms_sum_ += fr.total_ms;
  res_.frame_ms_max = std::max(res_.frame_ms_max, fr.total_ms);
  const Quat q_true = TrueAttitudeAt(data_, t_f);
  ScoreHeads(fr);
  Vec3 e_star = Vec3::Constant(std::nan(""));
  if (fr.status == SolveStatus::kSolved) {
    ++res_.frames_solved;
    e_star = BodyError(fr.q_inertial_from_body, q_true);
    if (t_f >= config_.score_after_s) star_acc_.Add(q_sensor1_from_body_ * e_star);
  }
  const UnitAttitude a = proc_.Attitude();
  if (a.valid && t_f >= config_.score_after_s) {
    const Vec3 e = BodyError(a.q_inertial_from_body, q_true);
    nees_sum_ += e.dot(a.covariance_rad2.ldlt().solve(e));
    ++nees_n_;
  }
  if (write_) RecordFrameRow(t_f, fr, e_star);
  ++fi_;
}

// Per head: frames solved, how (lost in space or tracking), matches, sigmas and timings (sums; means in Summarise).
void MissionRun::ScoreHeads(const FrameReport& fr) {
  for (int h = 0; h < nh_; ++h) {
    const HeadResult& hr = fr.heads[h];
    HeadSummary& s = res_.heads[h];
    ++s.frames;
    if (hr.status == SolveStatus::kSolved) {
      ++s.solved;
      s.mean_matches += hr.matches;
      s.mean_sigma_cross_arcsec += hr.sigma_cross_arcsec;
      s.mean_sigma_roll_arcsec += hr.sigma_roll_arcsec;
      (hr.mode == SolveMode::kTracking ? s.tracking : s.lost_in_space)++;
    }
    auto ms = [&](const char* k) { return hr.timing_ms.count(k) ? hr.timing_ms.at(k) : 0.0; };
    s.detect_ms_mean += ms("detect");
    s.identify_ms_mean += ms("identify");
    s.total_ms_mean += ms("total");
    s.total_ms_max = std::max(s.total_ms_max, ms("total"));
  }
}

// A row of frames.csv (columns in WriteCsvs).
void MissionRun::RecordFrameRow(double t_f, const FrameReport& fr, const Vec3& e_star) {
  frame_cols_[0].push_back(t_f);
  frame_cols_[1].push_back(fr.heads_solved);
  frame_cols_[2].push_back(fr.update.accepted ? 1 : 0);
  for (int i = 0; i < 3; ++i) frame_cols_[3 + i].push_back(e_star[i] * kRadToArcsec);
  for (int h = 0; h < nh_; ++h) {
    const HeadResult& hr = fr.heads[h];
    const bool ok = hr.status == SolveStatus::kSolved;
    frame_cols_[6 + 5 * h].push_back(ok ? 1 : 0);
    frame_cols_[7 + 5 * h].push_back(ok ? (hr.mode == SolveMode::kTracking ? 1 : 0) : std::nan(""));
    frame_cols_[8 + 5 * h].push_back(hr.matches);
    frame_cols_[9 + 5 * h].push_back(ok ? hr.sigma_cross_arcsec : std::nan(""));
    frame_cols_[10 + 5 * h].push_back(hr.timing_ms.count("total") ? hr.timing_ms.at("total") : 0.0);
  }
}

// The fused attitude after gyro sample k scored against the truth: its error, whether the covariance
// covers it, and the time spent in each status.
void MissionRun::OnGyroSample(size_t k) {
  const UnitAttitude a = proc_.Attitude();
  if (!a.valid) return;
  if (first_valid_) {
    res_.bias_error_start_dph = (a.bias_dph - g_.body_bias_dph[k]).norm();
    first_valid_ = false;
  }
  const Vec3 e = BodyError(a.q_inertial_from_body, g_.q_true[k]);
  worst_ = std::max(worst_, a.status);
  if (t_prev_status_ >= 0) res_.status_s[FusionStatusName(a.status)] += g_.t_s[k] - t_prev_status_;
  t_prev_status_ = g_.t_s[k];
  if (g_.t_s[k] >= config_.score_after_s) {
    fused_acc_.Add(q_sensor1_from_body_ * e);
    for (int i = 0; i < 3; ++i) {
      const bool w = std::abs(e[i]) <= 3 * std::sqrt(a.covariance_rad2(i, i));
      within_ += w ? 1 : 0;
      trusted_ += w || a.status != FusionStatus::kOk ? 1 : 0;
      ++axis_samples_;
      ++trust_n_;
    }
  }
  if (write_) RecordAttitudeRow(k, a, e, static_cast<int>(a.status));  // status_code
  if (keep_history_) {
    FusedSample f;
    f.t_s = g_.t_s[k];
    f.q_inertial_from_body = a.q_inertial_from_body;
    f.sigma_rad = a.covariance_rad2.diagonal().cwiseSqrt();
    f.bias_dph = a.bias_dph;
    f.bias_sigma_dph = a.bias_sigma_dph;
    f.w_body_rad_s = proc_.fusion().last_rate_rad_s() - a.bias_dph * kDphToRadS;
    f.status = a.status;
    res_.history.push_back(f);
  }
}

// A row of attitude.csv (columns in WriteCsvs).
void MissionRun::RecordAttitudeRow(size_t k, const UnitAttitude& a, const Vec3& e, int code) {
  const auto q = ToWxyz(a.q_inertial_from_body);
  const auto qt = ToWxyz(g_.q_true[k]);
  att_cols_[0].push_back(g_.t_s[k]);
  for (int i = 0; i < 4; ++i) att_cols_[1 + i].push_back(q[i]);
  for (int i = 0; i < 3; ++i) att_cols_[5 + i].push_back(std::sqrt(a.covariance_rad2(i, i)) * kRadToArcsec);
  for (int i = 0; i < 3; ++i) att_cols_[8 + i].push_back(e[i] * kRadToArcsec);
  for (int i = 0; i < 3; ++i) att_cols_[11 + i].push_back(a.bias_dph[i]);
  for (int i = 0; i < 4; ++i) att_cols_[14 + i].push_back(qt[i]);
  att_cols_[18].push_back(code);
}

// The sums into means and the run's figures: errors, coverage, status, final state and bias.
void MissionRun::Summarise() {
  for (auto& s : res_.heads) {
    if (s.solved > 0) {
      s.mean_matches /= s.solved;
      s.mean_sigma_cross_arcsec /= s.solved;
      s.mean_sigma_roll_arcsec /= s.solved;
    }
    if (s.frames > 0) {
      s.detect_ms_mean /= s.frames;
      s.identify_ms_mean /= s.frames;
      s.total_ms_mean /= s.frames;
    }
  }
  res_.star_only = star_acc_.Stats();
  res_.fused = fused_acc_.Stats();
  res_.within_3sigma_fraction = axis_samples_ > 0 ? static_cast<double>(within_) / axis_samples_ : 0.0;
  res_.trustworthy_fraction = trust_n_ > 0 ? static_cast<double>(trusted_) / trust_n_ : 0.0;
  res_.status = worst_;
  res_.nees_mean = nees_n_ > 0 ? nees_sum_ / nees_n_ : 0.0;
  res_.final_state = proc_.Attitude();
  if (!g_.t_s.empty()) {
    const auto it = std::lower_bound(g_.t_s.begin(), g_.t_s.end(), res_.final_state.t_s);
    const size_t k = std::min(static_cast<size_t>(it - g_.t_s.begin()), g_.t_s.size() - 1);
    res_.q_truth_final = g_.q_true[k];
  }
  res_.bias_dph = res_.final_state.bias_dph;
  res_.bias_sigma_dph = res_.final_state.bias_sigma_dph;
  res_.bias_truth_dph = g_.body_bias_dph.empty() ? Vec3::Zero() : g_.body_bias_dph.back();
  res_.bias_error_end_dph = (res_.bias_dph - res_.bias_truth_dph).norm();
  res_.updates = proc_.fusion().n_updates();
  res_.rejected = proc_.fusion().n_rejected();
  res_.frame_ms_mean = res_.frames > 0 ? frame_ms_sum_ / res_.frames : 0.0;
  res_.gyro_us_mean = g_.t_s.empty() ? 0.0 : gyro_s_ * 1e6 / g_.t_s.size();
}

// attitude.csv and frames.csv (the recorded rows), gyro.csv and truth.csv (the simulated data).
void MissionRun::WriteCsvs() const {
  WriteCsv(out_dir_ + "/attitude.csv",
           {"t_s", "qw", "qx", "qy", "qz", "sigma_x_arcsec", "sigma_y_arcsec", "sigma_z_arcsec", "err_x_arcsec",
            "err_y_arcsec", "err_z_arcsec", "bx_dph", "by_dph", "bz_dph", "true_qw", "true_qx", "true_qy", "true_qz",
            "status_code"},
           att_cols_, 12);
  std::vector<std::string> fh = {
      "t_s", "heads_solved", "update_accepted", "star_err_x_arcsec", "star_err_y_arcsec", "star_err_z_arcsec"};
  for (int h = 1; h <= nh_; ++h) {
    const std::string p = "head" + std::to_string(h) + "_";
    for (const char* n : {"solved", "tracking", "matches", "sigma_cross_arcsec", "ms"}) fh.push_back(p + n);
  }
  WriteCsv(out_dir_ + "/frames.csv", fh, frame_cols_, 9);
  std::vector<std::vector<double>> gc(1 + config_.unit.size() + 1), tc(5);
  for (size_t k = 0; k < g_.t_s.size(); ++k) {
    gc[0].push_back(g_.t_s[k]);
    for (int i = 0; i < config_.unit.size(); ++i) gc[1 + i].push_back(g_.gyro_dph[k][i]);
    gc.back().push_back(g_.temp_c[k]);
    const auto q = ToWxyz(g_.q_true[k]);
    tc[0].push_back(g_.t_s[k]);
    for (int i = 0; i < 4; ++i) tc[1 + i].push_back(q[i]);
  }
  std::vector<std::string> gh = {"t_s"};
  for (int i = 1; i <= config_.unit.size(); ++i) gh.push_back("g" + std::to_string(i) + "_dph");
  gh.push_back("temp_c");
  WriteCsv(out_dir_ + "/gyro.csv", gh, gc, 17);  // all digits: a replay feeds the same doubles
  WriteCsv(out_dir_ + "/truth.csv", {"t_s", "qw", "qx", "qy", "qz"}, tc, 15);
}

}  // namespace

std::string MissionFramePath(const std::string& out_dir, int head, int frame) {
  char name[48];
  std::snprintf(name, sizeof name, "/frames/head%d_%05d.pgm", head + 1, frame);
  return out_dir + name;
}

MissionResult RunMission(const MissionConfig& config_in, const StarCatalog& catalog, const std::string& out_dir,
                         bool write_frames, bool keep_history) {
  config_in.Check("mission");
  const MissionConfig config = WithUnitKnowledge(config_in);
  const MissionData data = SimulateMission(config);
  return MissionRun(config, data, catalog, out_dir, write_frames, keep_history).Run();
}

std::string MissionResult::Text() const {
  std::string s;
  char b[512];
  std::snprintf(b, sizeof b, "ssiu run: %d frame times, %d with a star solution; %zu head(s)\n", frames, frames_solved,
                heads.size());
  s += b;
  for (size_t h = 0; h < heads.size(); ++h) {
    const HeadSummary& x = heads[h];
    std::snprintf(b, sizeof b,
                  "  head %zu: %d/%d frames solved (%d lost in space, %d tracking), %.1f stars matched, "
                  "1-sigma %.1f cross / %.1f roll arcsec; %.1f ms per frame (detect %.1f, identify %.1f, max %.1f)\n",
                  h + 1, x.solved, x.frames, x.lost_in_space, x.tracking, x.mean_matches, x.mean_sigma_cross_arcsec,
                  x.mean_sigma_roll_arcsec, x.total_ms_mean, x.detect_ms_mean, x.identify_ms_mean, x.total_ms_max);
    s += b;
  }
  std::snprintf(b, sizeof b,
                "  star solutions vs truth (about head 1's boresight): cross RMS %.2f max %.2f, roll RMS %.2f max "
                "%.2f arcsec\n",
                star_only.cross_rms_arcsec, star_only.cross_max_arcsec, star_only.roll_rms_arcsec,
                star_only.roll_max_arcsec);
  s += b;
  std::snprintf(b, sizeof b,
                "  fused vs truth (every gyro sample): cross RMS %.2f max %.2f, roll RMS %.2f max %.2f arcsec; "
                "%.1f%% of axis errors within 3 sigma; NEES %.2f (3 expected)\n",
                fused.cross_rms_arcsec, fused.cross_max_arcsec, fused.roll_rms_arcsec, fused.roll_max_arcsec,
                100 * within_3sigma_fraction, nees_mean);
  s += b;
  if (final_state.valid) {
    const auto q = ToWxyz(final_state.q_inertial_from_body), qt = ToWxyz(q_truth_final);
    std::snprintf(b, sizeof b,
                  "  body attitude at t = %.2f s: q = [%.7f, %.7f, %.7f, %.7f], truth [%.7f, %.7f, %.7f, %.7f], "
                  "error %.2f arcsec\n",
                  final_state.t_s, q[0], q[1], q[2], q[3], qt[0], qt[1], qt[2], qt[3],
                  AttitudeErrorRad(final_state.q_inertial_from_body, q_truth_final) * kRadToArcsec);
    s += b;
  }
  std::snprintf(b, sizeof b,
                "  gyro bias (body x, y, z): estimate %.3f %.3f %.3f, truth %.3f %.3f %.3f deg/h; error %.3f deg/h "
                "(1-sigma %.3f %.3f %.3f), %.2f at the first fix\n",
                bias_dph.x(), bias_dph.y(), bias_dph.z(), bias_truth_dph.x(), bias_truth_dph.y(), bias_truth_dph.z(),
                bias_error_end_dph, bias_sigma_dph.x(), bias_sigma_dph.y(), bias_sigma_dph.z(), bias_error_start_dph);
  s += b;
  if (std::any_of(final_state.faults.begin(), final_state.faults.end(),
                  [](const FaultEvent& f) { return f.status == FaultStatus::kIsolated; })) {
    // The truth is the image of all gyros' slow errors (the failed one's step included); the
    // estimate is that of the gyros still in use, so their difference is not an error.
    s += "  (bias truth covers every gyro, the failed one included; after an isolation it is not the estimate's "
         "truth)\n";
  }
  std::string in_use;
  for (int g : final_state.gyros_in_use) in_use += (in_use.empty() ? "" : ",") + std::to_string(g);
  if (final_state.faults.empty()) {
    s += "  FDI: no fault; gyros in use " + in_use + "\n";
  } else {
    for (const auto& f : final_state.faults) {
      std::snprintf(b, sizeof b,
                    "  FDI: %s gyro %d, %s from %.2f s, detected at %.2f s (%s), isolated at %.2f s (%s), %.2f deg/h\n",
                    FaultStatusName(f.status), f.gyro, f.shape.c_str(), f.t_onset_s, f.t_detect_s, f.test.c_str(),
                    f.t_isolate_s, f.method.c_str(), f.fault_dph);
      s += b;
    }
    s += "  gyros in use " + in_use + "\n";
  }
  const UnitCalState& uc = final_state.unit_calibration;
  if (uc.status != UnitCalStatus::kOff) {
    std::snprintf(b, sizeof b, "  unit calibration: %s, %d star windows, worst combination sigma %.1f\n",
                  UnitCalStatusName(uc.status), uc.n_windows, uc.worst_combination_sigma);
    s += b;
  }
  s += std::string("  status: ") + FusionStatusName(status);
  for (const auto& [k, v] : status_s)
    s += ", " + k + " " + std::to_string(v).substr(0, std::to_string(v).find('.') + 2) + " s";
  s += "\n";
  std::snprintf(b, sizeof b,
                "  filter: %ld star updates, %ld rejected; processor %.1f ms per frame set (max %.1f), %.2f us per "
                "gyro sample; %.1f s processing, %.1f s rendering frames\n",
                updates, rejected, frame_ms_mean, frame_ms_max, gyro_us_mean, process_s, simulate_s);
  s += b;
  return s;
}

Json MissionResult::ToJson() const {
  Json hs = Json::array();
  for (size_t h = 0; h < heads.size(); ++h) {
    const HeadSummary& x = heads[h];
    hs.push_back({{"head", h + 1},
                  {"frames", x.frames},
                  {"solved", x.solved},
                  {"lost_in_space", x.lost_in_space},
                  {"tracking", x.tracking},
                  {"mean_matches", x.mean_matches},
                  {"mean_sigma_cross_arcsec", x.mean_sigma_cross_arcsec},
                  {"mean_sigma_roll_arcsec", x.mean_sigma_roll_arcsec},
                  {"timing_ms",
                   {{"detect_mean", x.detect_ms_mean},
                    {"identify_mean", x.identify_ms_mean},
                    {"total_mean", x.total_ms_mean},
                    {"total_max", x.total_ms_max}}}});
  }
  Json faults = Json::array();
  for (const auto& f : final_state.faults) faults.push_back(f.ToJson());
  Json fused_json = StatsJson(fused);
  fused_json["within_3sigma_fraction"] = within_3sigma_fraction;
  fused_json["nees_mean"] = nees_mean;
  fused_json["trustworthy_fraction"] = trustworthy_fraction;
  const auto q = ToWxyz(final_state.q_inertial_from_body);
  const auto qt = ToWxyz(q_truth_final);
  Vec3 sigma;
  for (int i = 0; i < 3; ++i) sigma[i] = std::sqrt(final_state.covariance_rad2(i, i)) * kRadToArcsec;
  Json out = {{"status", frames_solved > 0 ? FusionStatusName(status) : "no_star_solution"},
              {"status_s", status_s},
              {"frames", frames},
              {"frames_solved", frames_solved},
              {"heads", hs},
              {"star_solution_error", StatsJson(star_only)},
              {"fused_error", fused_json},
              {"final",
               {{"t_s", final_state.t_s},
                {"q", {q[0], q[1], q[2], q[3]}},
                {"sigma_body_arcsec", V3(sigma)},
                {"q_truth", {qt[0], qt[1], qt[2], qt[3]}},
                {"error_arcsec", AttitudeErrorRad(final_state.q_inertial_from_body, q_truth_final) * kRadToArcsec}}},
              {"bias",
               {{"estimate_dph", V3(bias_dph)},
                {"truth_dph", V3(bias_truth_dph)},
                {"sigma_dph", V3(bias_sigma_dph)},
                {"error_dph", bias_error_end_dph},
                {"error_at_first_fix_dph", bias_error_start_dph}}},
              {"faults", faults},
              {"gyros_in_use", final_state.gyros_in_use},
              {"filter", {{"updates", updates}, {"rejected", rejected}}},
              {"timing",
               {{"frame_ms_mean", frame_ms_mean},
                {"frame_ms_max", frame_ms_max},
                {"gyro_sample_us_mean", gyro_us_mean},
                {"process_s", process_s},
                {"simulate_s", simulate_s}}}};
  if (final_state.unit_calibration.status != UnitCalStatus::kOff) {
    out["unit_calibration"] = UnitCalStateToJson(final_state.unit_calibration);
  }
  return out;
}

}  // namespace ssiu
