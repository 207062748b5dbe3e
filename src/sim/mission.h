// A short SSIU mission, simulated and processed as the unit would (`ssiu run`): a slew seen by one to
// three optical heads (star frames rendered by SimulateFrame at each head's true attitude) and by the
// four-FOG unit (SimulateGyro), fed in time order to the UnitProcessor (inertial/unit_processor.h),
// and its attitude and bias scored against the truth. The config format (SSIU.json) is in
// docs/inertial.md; examples/ssiu_mission.json is the built-in default written out.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/catalog.h"
#include "core/json.h"
#include "inertial/fuse.h"
#include "inertial/unit_processor.h"
#include "sim/frame_sim.h"
#include "sim/gyro_sim.h"

namespace ssiu {

struct MissionConfig {
  double duration_s = 120.0;
  double frame_rate_hz = 1.0;  // frames of every head at t = i / frame_rate_hz, i = 0, 1, ...
  uint64_t seed = 1;
  std::vector<OpticalHead> heads;  // 1..3
  GyroUnit unit;                   // gyro axes, error models, sample rate
  MotionProfile motion;            // slew (or sine/static/temperature) and injected gyro faults
  FrameSimOptions frame_sim;       // star-frame noise and artefacts (defect_seed + head index per head)
  UnitProcessorOptions processor;
  double score_after_s = 10.0;  // attitude errors are scored from this time on (filter settling)
  // The mission clock: t = 0 is start_utc (ISO 8601). Frames are rendered with the stars' proper
  // motion and aberration at start + t (frame_sim's time_utc and velocity are replaced) and the
  // processor removes them (SolveOptions::sky). velocity_kms: the spacecraft's velocity relative to
  // the Earth (ICRS), constant over the mission; zero = none.
  std::string start_utc = "2025-06-21T00:00:00Z";
  Vec3 velocity_kms = Vec3::Zero();

  void Check(const std::string& file) const;  // InputError naming the file and field
};

// The built-in default: 120 s slew at 0.1 deg/s, two 512x512 heads (16.6 deg FOV) 90 deg apart,
// frames at 1 Hz, four FOGs at 100 Hz with turn-on biases of a few deg/h.
MissionConfig DefaultMissionConfig();
// SSIU.json: required duration_s, frame_rate_hz, seed, heads; optional gyro_unit (unit.json),
// motion (a `ssiu simulate gyro` profile), frame_sim, processor, score_after_s, start_utc,
// velocity_kms [x,y,z]. Unknown keys are an
// error. InputError naming `file` and the field.
MissionConfig MissionConfigFromJson(const Json& j, const std::string& file);
MissionConfig LoadMissionConfig(const std::string& path);
// The config as the unit's processor knows itself (RunMission runs it so): the cameras' gain and
// exposure (the detector then expects the smear of the rate the gyros measure) from the simulator's,
// and the mission clock and velocity as its sky corrections.
MissionConfig WithUnitKnowledge(const MissionConfig& config);
// The mission clock's start and the spacecraft velocity as the processor's sky corrections.
SkyCorrections MissionSky(const MissionConfig& config);
Json MissionConfigToJson(const MissionConfig& c);

// The simulated truth and gyro data; frames are rendered on demand (a mission's frames would not fit
// in memory).
struct MissionData {
  GyroSimulation gyro;  // gyro log, true attitude and body bias at each gyro sample
  std::vector<double> frame_t_s;
};
MissionData SimulateMission(const MissionConfig& config);
// True body attitude at t (slerp between the truth samples around t; q0 at t <= 0).
Quat TrueAttitudeAt(const MissionData& data, double t_s);
// Head `head`'s frame number `frame`, rendered at the true head attitude (deterministic per seed).
SimulatedFrame SimulateMissionFrame(const MissionConfig& config, const MissionData& data, const StarCatalog& catalog,
                                    int frame, int head);

// Attitude error split about head 1's boresight: cross (angle between boresights) and roll (about it).
struct ErrorStats {
  double cross_rms_arcsec = 0, cross_max_arcsec = 0, roll_rms_arcsec = 0, roll_max_arcsec = 0;
  long n = 0;
};

struct HeadSummary {
  int frames = 0, solved = 0, lost_in_space = 0, tracking = 0;
  double mean_matches = 0, mean_sigma_cross_arcsec = 0, mean_sigma_roll_arcsec = 0;
  double detect_ms_mean = 0, identify_ms_mean = 0, total_ms_mean = 0, total_ms_max = 0;
};

struct MissionResult {
  int frames = 0, frames_solved = 0;  // frame times, and those with a body solution
  std::vector<HeadSummary> heads;
  ErrorStats star_only;               // the per-frame star solutions against the truth
  ErrorStats fused;                   // the fused attitude at every gyro sample after score_after_s
  double within_3sigma_fraction = 0;  // of fused per-axis errors at gyro samples after score_after_s
  // Of per-axis errors at gyro samples after score_after_s: within 3 sigma, or the status not ok
  // (issue 16's measure: wrong only while the unit says so).
  double trustworthy_fraction = 0;
  FusionStatus status = FusionStatus::kOk;  // worst processor status after the first fix
  std::map<std::string, double> status_s;   // time (s) in each status after the first fix
  double nees_mean = 0;                     // fused attitude NEES (3 dof) at frame times after score_after_s
  Vec3 bias_truth_dph = Vec3::Zero(), bias_dph = Vec3::Zero(), bias_sigma_dph = Vec3::Zero();
  double bias_error_start_dph = 0;  // |estimate - truth| just after the first fix (estimate 0 then)
  double bias_error_end_dph = 0;    // at the end
  UnitAttitude final_state;
  Quat q_truth_final = Quat::Identity();  // true body attitude at the gyro sample nearest final_state.t_s
  long updates = 0, rejected = 0;
  double frame_ms_mean = 0, frame_ms_max = 0;  // processor time per frame set (all heads + update)
  double gyro_us_mean = 0;                     // processor time per gyro sample
  double simulate_s = 0, process_s = 0;        // wall time spent rendering frames / processing
  // With RunMission's keep_history: the fused attitude after every gyro sample once it is valid
  // (t_s from start_utc), for `ssiu run --aem/--acm`.
  std::vector<FusedSample> history;

  std::string Text() const;  // human summary
  Json ToJson() const;
};

// Simulates the mission and processes it. Star identifiers are built (or loaded from the cache) for
// each head's camera by MakeIdentifierForCamera. With out_dir non-empty writes DIR/attitude.csv (the
// fused attitude and its error at every gyro sample), DIR/frames.csv (per frame and head),
// DIR/gyro.csv and DIR/truth.csv (conventions.md logs) and DIR/head<h>_first.png (each head's first
// frame); with write_frames also every frame of every head, DIR/frames/head<h>_<frame>.pgm (16-bit
// binary PGM, frame numbered from 0 with five digits, in the order of frames.csv).
MissionResult RunMission(const MissionConfig& config, const StarCatalog& catalog, const std::string& out_dir = "",
                         bool write_frames = false, bool keep_history = false);
// The name of head h's (0-based) frame number `frame` under DIR/frames.
std::string MissionFramePath(const std::string& out_dir, int head, int frame);

}  // namespace ssiu
