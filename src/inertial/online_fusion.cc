#include "inertial/online_fusion.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace ssiu {
namespace {

// Shape from the parity fit since onset: a noise burst leaves the residual about the step + ramp fit
// well above the warm-up noise; a ramp has a trend over the span comparable with its step.
const char* FaultShape(const GyroVec& step, const GyroVec& ramp_per_s, double span_s, double variance_ratio) {
  if (variance_ratio > 2) return "noise";
  return ramp_per_s.norm() * span_s > 0.5 * step.norm() + 1.0 ? "ramp" : "step";
}

}  // namespace

const char* GyroSampleStatusName(GyroSampleStatus s) {
  switch (s) {
    case GyroSampleStatus::kAccepted:
      return "accepted";
    case GyroSampleStatus::kAcceptedPartial:
      return "accepted_partial";
    case GyroSampleStatus::kAcceptedAfterGap:
      return "accepted_after_gap";
    case GyroSampleStatus::kRejectedNonFinite:
      return "rejected_non_finite";
    case GyroSampleStatus::kRejectedOutOfRange:
      return "rejected_out_of_range";
    case GyroSampleStatus::kRejectedOutOfOrder:
      return "rejected_out_of_order";
    case GyroSampleStatus::kRejectedRepeated:
      return "rejected_repeated";
    case GyroSampleStatus::kRejectedBadTime:
      return "rejected_bad_time";
    case GyroSampleStatus::kRejectedWrongSize:
      return "rejected_wrong_size";
    case GyroSampleStatus::kRejectedTimeJump:
      return "rejected_time_jump";
    case GyroSampleStatus::kAcceptedTimeReset:
      return "accepted_time_reset";
  }
  return "rejected_bad_time";
}

const char* RestartReasonName(RestartReason r) {
  switch (r) {
    case RestartReason::kNone:
      return "none";
    case RestartReason::kNonFinite:
      return "non_finite";
    case RestartReason::kGyroGap:
      return "gyro_gap";
    case RestartReason::kTimeReset:
      return "time_reset";
  }
  return "none";
}

OnlineFusion::OnlineFusion(const GyroUnit& unit, const FuseOptions& options, std::pmr::memory_resource* mr)
    : unit_(unit), opt_(options), monitor_(mr), isolator_(mr), tracker_(mr), bias_history_(mr) {
  opt_.Check();
  unit_.Check("unit");
  const int n = unit_.size();
  axes_ = unit_.ProcessorAxes();
  arw_ = unit_.NoiseArw();
  use_.assign(n, true);
  correction_ = GyroVec::Zero(n);
  g_last_ = GyroVec::Zero(n);
  dyn_ = GyroVec::Zero(n);
  SetSolver();
  dt_nominal_ = 1.0 / unit_.rate_hz;
  sample_sigma_dph_ = arw_ * (60.0 / std::sqrt(dt_nominal_));  // deg/sqrt(h) -> deg/h per sample
  fdi_on_ = opt_.fdi && n >= 4;
  if (fdi_on_) monitor_ = ParityMonitor(axes_, use_, sample_sigma_dph_, dt_nominal_, opt_.fdi_options, mr);
  // Everything the per-sample calls may need, allocated now (online_fusion.h "Flight rules").
  use_scratch_ = use_;
  isolator_ = StarRateIsolator(axes_, use_, correction_, opt_.policy.max_star_samples_kept, mr);
  tracker_ = isolator_;
  const size_t n_events = static_cast<size_t>(opt_.policy.max_fault_events);
  faults_.reserve(n_events);
  // One residual buffer per event kept, one for the event being made, one spare.
  spare_residuals_.resize(n_events + 2);
  for (auto& r : spare_residuals_) r.reserve(kMaxGyros);
  bias_history_.resize(static_cast<size_t>(opt_.policy.bias_history_max));
  cal_on_ = opt_.calibrate_unit && n >= 4;
  cal_e_ = GyroAxes::Zero(n, 3);
  if (cal_on_) {
    cal_ = InflightCalibrator(unit_, opt_.calibration);
    cal_state_ = cal_.Estimate();
  }
}

void OnlineFusion::FeedCalibration(double t, const GyroVec& g, GyroSampleStatus status) {
  if (!cal_on_) return;
  // Every sample with all outputs usable, whatever the fault monitors say: before it is calibrated a
  // unit's own scale factors and tilts raise them in a slew (5 arcmin at 1 deg/s is 5 deg/h of parity),
  // and a calibration that stopped at their alarm would never converge where it is needed. A real
  // fault inside a bias block is taken for calibration error (chi2_per_dof shows it).
  if (status == GyroSampleStatus::kAccepted) {
    cal_.AddGyro(t, g);
  } else {
    cal_.BreakWindow();
  }
}

void OnlineFusion::RefreshCalibration() {
  const UnitCalState s = cal_.Estimate();
  if (s.status != UnitCalStatus::kEstimated) {
    if (!cal_applied_) cal_state_ = s;
    return;
  }
  cal_state_ = s;
  // Applied from the first estimate on (the posterior mean: where the windows say little it stays near
  // the unit as it is), each later one replacing it. The outputs are
  // corrected to first order: g = (H + E) w + ... gives H w = g - E P g, P the rate solver of the gyros
  // in use (an isolated gyro's fault does not leak into the others' corrections).
  for (int i = 0; i < s.n_gyros; ++i) cal_e_.row(i) = cal_.OutputError(s, i).transpose();
  cal_applied_ = true;
  cal_state_.status = UnitCalStatus::kApplied;
}

void OnlineFusion::SetSolver() {
  // The gyros in use always span 3-D here (the constructor's unit check, Isolate's check before it
  // drops one): Make cannot fail, and the old solver stays if it ever did.
  RateSolver::Make(axes_, arw_, use_, &solver_);
  noise_ = FuseNoiseModel(unit_, solver_, opt_.bias_drift_floor_dph_per_sqrt_h);
}

int OnlineFusion::n_gyros_in_use() const { return static_cast<int>(std::count(use_.begin(), use_.end(), true)); }

std::vector<int> OnlineFusion::GyrosInUse() const {
  std::vector<int> out;
  for (size_t i = 0; i < use_.size(); ++i) {
    if (use_[i]) out.push_back(static_cast<int>(i) + 1);
  }
  return out;
}

void OnlineFusion::PropagateTo(double t_s, const Vec3& w, const GyroVec& g, bool coning) {
  const double d = t_s - t_cur_;
  filter_.Propagate(w, d, noise_, coning);
  if (isolating_) isolator_.AddGyro(g - dyn_, d);
  if (tracked_ >= 0) tracker_.AddGyro(g, d);
  t_cur_ = t_s;
}

FusionStatus OnlineFusion::Status() const {
  if (!initialised_ || restart_pending_) return FusionStatus::kFailed;
  bool unresolved = isolating_ || compensated_ || t_cur_ < t_settled_ || last_partial_ ||
                    (have_gyro_ && t_cur_ - t_last_gyro_ > opt_.policy.max_gyro_gap_s);
  for (const auto& f : faults_) unresolved |= f.status != FaultStatus::kIsolated;
  if (opt_.policy.degraded_without_spare) {  // called per gyro sample: count, do not build GyrosInUse()
    const int in_use = n_gyros_in_use();
    unresolved |= in_use < static_cast<int>(use_.size()) && in_use <= 3;
  }
  if (!unresolved) return FusionStatus::kOk;
  return t_cur_ - t_last_accepted_ > opt_.policy.failed_after_s ? FusionStatus::kFailed : FusionStatus::kDegraded;
}

Vec3 OnlineFusion::attitude_sigma_rad() const {
  Vec3 s;
  for (int a = 0; a < 3; ++a) s[a] = std::sqrt(P()(MekfIndex::kAttitude + a, MekfIndex::kAttitude + a));
  return s;
}

Vec3 OnlineFusion::bias_sigma_dph() const {
  Vec3 s;
  for (int a = 0; a < 3; ++a) s[a] = std::sqrt(P()(MekfIndex::kBias + a, MekfIndex::kBias + a)) * kRadSToDph;
  return s;
}

Vec3 OnlineFusion::BiasAt(double t_s) const {
  Vec3 b = n_bias_ == 0 ? filter_.bias() : bias_entry(0).second;
  for (size_t k = 0; k < n_bias_; ++k) {
    if (bias_entry(k).first <= t_s) b = bias_entry(k).second;
  }
  return b;
}

// Fault events live in faults_ (reserved to policy.max_fault_events); each takes a residual buffer
// reserved at construction, so that filling it allocates nothing, and gives it back when dropped.
void OnlineFusion::StartEvent(FaultEvent* ev) {
  if (!spare_residuals_.empty()) {
    ev->residual_dph = std::move(spare_residuals_.back());
    spare_residuals_.pop_back();
  }
  ev->residual_dph.clear();
}

void OnlineFusion::PushEvent(FaultEvent&& ev) {
  if (faults_.size() >= static_cast<size_t>(opt_.policy.max_fault_events)) {
    // Full: the oldest resolved event that is not the tracked one goes (the latest are what an
    // operator needs; the count says how many went).
    size_t k = 0;
    while (k + 1 < faults_.size() &&
           (faults_[k].status == FaultStatus::kDetected || (tracked_ >= 0 && k == tracked_event_))) {
      ++k;
    }
    if (tracked_ >= 0 && k == tracked_event_) track_reporting_ = false;
    spare_residuals_.push_back(std::move(faults_[k].residual_dph));
    faults_.erase(faults_.begin() + static_cast<std::ptrdiff_t>(k));
    if (tracked_ >= 0 && tracked_event_ > k) --tracked_event_;
    ++n_faults_dropped_;
  }
  faults_.push_back(std::move(ev));
}

void OnlineFusion::FloorBias(double sigma) {
  const Mat6& p = filter_.P();
  double add = 0;
  for (int a = 0; a < 3; ++a) add = std::max(add, sigma * sigma - p(MekfIndex::kBias + a, MekfIndex::kBias + a));
  if (add > 0) filter_.InflateBias(std::sqrt(add));
}

// The isolated gyro leaves the rate solution, the parity baseline becomes a per-gyro correction, and
// the bias estimate goes back to its value before the onset: the remaining gyros did not change, and
// the correction keeps their body bias what it was (the covariance stays open until stars settle it).
// With no spare gyro (three in use) the gyro stays, its estimated fault subtracted.
void OnlineFusion::Isolate(int gi, double t, const char* method, const GyroVec& resid, double fault_dph) {
  const int n = unit_.size();
  FaultEvent& ev = faults_.back();
  ev.gyro = gi + 1;
  ev.t_isolate_s = t;
  ev.status = FaultStatus::kIsolated;
  ev.method = method;
  ev.fault_dph = fault_dph;
  ev.residual_dph.assign(resid.data(), resid.data() + resid.size());
  ev.step_dph = fault_dph;
  ev.ramp_dph_per_s = 0;
  if (fit_v_.rows() > 0) {  // the parity fit since onset, on this gyro's parity column
    const GyroVec d = fit_v_.col(gi);
    const double dd = d.squaredNorm();
    if (dd > 1e-12) {
      ev.step_dph = d.dot(fit_step_) / dd;
      ev.ramp_dph_per_s = d.dot(fit_ramp_) / dd;
      // The parity measures the fault far better than the star rates: its size now, from the
      // step + ramp fit over everything since the onset.
      if (monitor_.active() && monitor_.ready()) {
        GyroVec a, b;
        double variance_ratio = 1;
        monitor_.FitSinceOnset(&a, &b, &variance_ratio);
        ev.shape = FaultShape(a, b, t - ev.t_onset_s, variance_ratio);
        ev.step_dph = d.dot(a) / dd;
        ev.ramp_dph_per_s = d.dot(b) / dd;
        ev.fault_dph = d.dot(a + b * (t - ev.t_onset_s)) / dd;
      }
    }
  }
  isolating_ = false;
  t_settled_ = t + opt_.policy.settle_after_isolation_s;
  const Vec3 b_before = BiasAt(ev.t_onset_s);
  // The gyro can leave the rate solution when a spare is left and the others still span 3-D.
  use_scratch_ = use_;
  use_scratch_[gi] = false;
  RateSolver rest;
  if (n_gyros_in_use() <= 3 || !RateSolver::Make(axes_, arw_, use_scratch_, &rest)) {
    Compensate(gi, t, b_before);
    innov_s_ = 0;
    innov_zero_t_ = t;
    return;
  }
  correction_ = GyroVec::Zero(n);
  if (monitor_.active() && monitor_.ready()) correction_ = monitor_.V().transpose() * monitor_.baseline();
  const Vec3 leak_rad_s = solver_.Pinv().col(gi) * ev.fault_dph * kDphToRadS;
  filter_.ShiftBias(b_before - filter_.bias());
  use_[gi] = false;
  SetSolver();
  monitor_.Reset(axes_, use_, sample_sigma_dph_, dt_nominal_, opt_.fdi_options);
  if (monitor_.active()) monitor_.InheritBaseline(correction_);
  filter_.InflateBias(leak_rad_s.norm());
  innov_s_ = 0;
  innov_zero_t_ = t;
}

// No spare gyro: the isolated one stays in use with its fault subtracted. The first such fault is
// tracked: its star-rate residual (the isolator's, from detection on) is fitted as a step + ramp at
// every star sample and the fit is subtracted sample by sample, so that a slow ramp stays one fault
// instead of a new detection each time the filter's bias has absorbed another slice of it. A later
// detection that names the tracked gyro again is the same fault changing shape: the fit restarts at
// its onset and no second event is reported. Another gyro failing as well gets the constant
// compensation of its size at isolation.
void OnlineFusion::Compensate(int gi, double t, const Vec3& b_before) {
  compensated_ = true;
  FaultEvent& ev = faults_.back();
  if (tracked_ == gi) {
    track_from_s_ = std::max(track_from_s_, ev.t_onset_s);
    track_reporting_ = false;  // the event keeps the shape it had since its own onset
    spare_residuals_.push_back(std::move(faults_.back().residual_dph));
    faults_.pop_back();
    RefitTrackedFault(t);
    return;
  }
  if (tracked_ < 0) {
    tracked_ = gi;
    tracked_event_ = faults_.size() - 1;
    tracker_ = isolator_;
    track_from_s_ = track_onset0_s_ = ev.t_onset_s;
    track_reporting_ = true;
    track_fit_ = FaultFit();
    track_fit_.value_dph = ev.fault_dph;
    track_fit_t_ = t;
    RefitTrackedFault(t);
    if (track_fit_.n > 0) ev.fault_dph = track_fit_.value_dph;
    // The compensation covers the whole fault since onset: the bias goes back to its value then.
    filter_.ShiftBias(b_before - filter_.bias());
    dyn_[gi] = track_fit_.value_dph;
    return;
  }
  correction_[gi] += ev.fault_dph;
  filter_.ShiftBias(-solver_.Pinv().col(gi) * ev.fault_dph * kDphToRadS);
}

void OnlineFusion::RefitTrackedFault(double t) {
  const double from = std::max(track_from_s_, t - opt_.fdi_options.compensation_window_s);
  tracker_.ForgetBefore(from);
  const FaultFit fit = tracker_.FitFault(tracked_, from, t);
  if (fit.n == 0) return;
  track_fit_ = fit;
  track_fit_t_ = t;
  // The compensation's own uncertainty reaches the body bias through this gyro's column of the rate
  // solution: the filter must not be surer of the bias than that.
  FloorBias(solver_.Pinv().col(tracked_).norm() * fit.sigma_dph * kDphToRadS);
  // The event reports the fit over everything since detection; once the window has moved on, the
  // fit follows the fault's latest shape for the compensation only (a ramp that stopped would
  // otherwise be reported as a step of whatever is left).
  if (!track_reporting_ || from > track_from_s_ + 1e-9) return;
  FaultEvent& ev = faults_[tracked_event_];
  // The onset of a ramp is where the fitted line crosses zero (the innovation CUSUM's last zero comes
  // later, when the ramp has grown out of the noise), taken only within a minute before that.
  const double ramp = fit.ramp_dph_per_s;
  const double step0 = fit.value_dph - ramp * (t - track_onset0_s_);
  ev.shape = FaultShape(GyroVec::Constant(1, step0), GyroVec::Constant(1, ramp), t - track_onset0_s_, 1.0);
  ev.t_onset_s = track_onset0_s_;
  if (ev.shape == "ramp" && step0 * ramp > 0) ev.t_onset_s = std::max(track_onset0_s_ - 60, t - fit.value_dph / ramp);
  ev.ramp_dph_per_s = ramp;
  ev.step_dph = fit.value_dph - ramp * (t - ev.t_onset_s);
}

void OnlineFusion::OnDetection(double t, const char* test, double onset_s, double parity_jump_dph) {
  FaultEvent ev;
  StartEvent(&ev);
  ev.t_detect_s = t;
  ev.t_onset_s = std::min(onset_s, t);
  ev.parity_jump_dph = parity_jump_dph;
  ev.status = FaultStatus::kDetected;
  ev.test = test;
  fit_v_ = GyroParity();
  if (monitor_.active() && monitor_.ready()) {
    double variance_ratio = 1;
    monitor_.FitSinceOnset(&fit_step_, &fit_ramp_, &variance_ratio);
    fit_v_ = monitor_.V();
    const double span = t - ev.t_onset_s;
    ev.shape = FaultShape(fit_step_, fit_ramp_, span, variance_ratio);
    ev.step_dph = fit_step_.norm();
    ev.ramp_dph_per_s = fit_ramp_.norm();
  } else {
    ev.shape = "step";
  }
  PushEvent(std::move(ev));
  const Vec3 b_before = BiasAt(faults_.back().t_onset_s);
  const GyroVec c = axes_ * (b_before * kRadSToDph) + (monitor_.active() && monitor_.ready()
                                                           ? GyroVec(monitor_.V().transpose() * monitor_.baseline())
                                                           : GyroVec(correction_));
  isolator_.Reset(axes_, use_, c);
  isolating_ = true;
}

// While a fault is detected but not isolated every estimate must cover it: the body bias (the fault's
// image in the rate solution) is given at least the variance of the largest body rate error the
// current parity residual can imply (its 1 s mean plus 3 sigma), so that the filter neither refuses
// the star fixes nor claims an accuracy it has not.
void OnlineFusion::OpenCovarianceWhileUnresolved() {
  if (!monitor_.active() || !monitor_.ready()) return;
  const double e_dph = monitor_.short_mean().norm() + 3 * monitor_.short_mean_sigma();
  FloorBias(LargestImpliedRateDph(monitor_.V(), solver_, use_, e_dph) * kDphToRadS);
}

// Unusable outputs (NaN/inf, or beyond policy.max_gyro_output_dph: no FOG reads that) of one sample.
// With enough good gyros in use left to span 3-D the sample is kept, the rate solved from them: that
// is what the redundancy is for, and a flight engineer expects one corrupt word from one gyro to cost
// nothing but that gyro's share of the noise (the 3-gyro rate of the four-FOG unit has about 1.3
// times the 4-gyro noise), where holding the last rate instead would turn the body's angular
// acceleration over the interval into attitude error. Each unusable output is replaced by what the
// others predict for it, so that the rate from all gyros in use equals the rate from the good ones
// (the weighted least squares fits a consistent output exactly) and the star-rate isolator sees no
// jump; the parity monitor is not fed such a sample (its parity would be made up). Otherwise (no
// spare left) the sample is refused and AddGyro holds the last rate over its interval.
GyroSampleStatus OnlineFusion::CheckOutputs(GyroVec* g, bool* partial) {
  *partial = false;
  bool any_bad = false, bad_in_use = false, non_finite = false;
  bool bad[kMaxGyros] = {};
  for (int i = 0; i < g->size(); ++i) {
    const double v = (*g)[i];
    const bool nf = !std::isfinite(v), range = !nf && std::abs(v) > opt_.policy.max_gyro_output_dph;
    if (!nf && !range) continue;
    n_out_nonfinite_ += nf;
    n_out_range_ += range;
    non_finite |= nf;
    if (!any_bad) use_scratch_ = use_;  // same size: no allocation
    any_bad = true;
    bad_in_use |= use_[i];
    bad[i] = true;
    use_scratch_[i] = false;
    (*g)[i] = 0;
  }
  if (!any_bad) return GyroSampleStatus::kAccepted;
  const RateSolver* solver = &solver_;
  RateSolver rest;
  if (bad_in_use) {
    if (!RateSolver::Make(axes_, arw_, use_scratch_, &rest)) {
      return non_finite ? GyroSampleStatus::kRejectedNonFinite : GyroSampleStatus::kRejectedOutOfRange;
    }
    solver = &rest;
  }
  // The unused columns of a solver are zero: the zeroed outputs do not enter the rate.
  const Vec3 w_dph = solver->Solve(*g - correction_ - dyn_);
  for (int i = 0; i < g->size(); ++i) {
    if (bad[i]) (*g)[i] = axes_.row(i).dot(w_dph) + correction_[i] + dyn_[i];
  }
  *partial = bad_in_use;
  return bad_in_use ? GyroSampleStatus::kAcceptedPartial : GyroSampleStatus::kAccepted;
}

void OnlineFusion::SaveFilter() {
  q_saved_ = filter_.q();
  bias_saved_ = filter_.bias();
  p_saved_ = filter_.P();
}

// Checked inputs should keep the state finite; this is the net under them. A non-finite state is
// replaced by the last finite one (what q() reports meanwhile) and the filter restarts from the next
// star solution.
bool OnlineFusion::GuardFilter() {
  if (filter_.q().coeffs().allFinite() && filter_.bias().allFinite() && filter_.P().allFinite()) return false;
  filter_.Init(q_saved_, bias_saved_, p_saved_);
  RequestRestart(RestartReason::kNonFinite);
  return true;
}

void OnlineFusion::RequestRestart(RestartReason why) {
  restart_pending_ = true;
  last_restart_ = why;
  isolator_.BreakChain();
  tracker_.BreakChain();
}

// The attitude from the measurement, the bias estimate (and its covariance) kept: the gyros did not
// change, only the attitude was lost.
void OnlineFusion::Restart(double t, const Quat& q, const Mat3& r_body) {
  Mat6 p0 = Mat6::Zero();
  p0.block<3, 3>(MekfIndex::kAttitude, MekfIndex::kAttitude) = r_body;
  Vec3 b = filter_.bias();
  Mat3 pb = filter_.P().block<3, 3>(MekfIndex::kBias, MekfIndex::kBias);
  if (!b.allFinite() || !pb.allFinite()) {
    const double b0 = opt_.init_bias_sigma_dph * kDphToRadS;
    b = Vec3::Zero();
    pb = Mat3::Identity() * b0 * b0;
  }
  p0.block<3, 3>(MekfIndex::kBias, MekfIndex::kBias) = pb;
  filter_.Init(q, b, p0);
  restart_pending_ = false;
  ++n_restarts_;
  t_cur_ = t_last_st_ = t_last_accepted_ = t;
  innov_zero_t_ = t;
  consecutive_rejects_ = 0;
  ++n_used_;
  isolator_.BreakChain();
  tracker_.BreakChain();
}

GyroSampleStatus OnlineFusion::AddGyro(double t_k, const GyroVec& g_in) {
  auto done = [this](GyroSampleStatus s) {
    ++n_status_[static_cast<size_t>(s)];
    return s;
  };
  const int n = unit_.size();
  // The time tag first: a refused sample changes nothing.
  if (g_in.size() != n) return done(GyroSampleStatus::kRejectedWrongSize);
  if (!std::isfinite(t_k)) return done(GyroSampleStatus::kRejectedBadTime);
  bool after_gap = false, time_reset = false;
  double t_back_prev = 0;
  if (have_gyro_) {
    const double dt = t_k - t_last_gyro_;
    if (std::abs(dt) <= 1e-9) return done(GyroSampleStatus::kRejectedRepeated);
    if (dt < 0) {
      // Refused; but a long run of them that follow one another is the clock gone back (or the last
      // accepted tag corrupt): without this, one such event would lock out every later sample.
      const bool follows = n_back_ > 0 && t_k > t_back_ + 1e-9 && t_k - t_back_ <= opt_.policy.max_gyro_gap_s;
      n_back_ = follows ? n_back_ + 1 : 1;
      t_back_prev = t_back_;
      t_back_ = t_k;
      if (n_back_ < opt_.policy.resync_after_samples) return done(GyroSampleStatus::kRejectedOutOfOrder);
      time_reset = true;
    }
    if (dt > opt_.policy.max_gyro_gap_s) {
      // One corrupt time tag far ahead must not lock out every later sample: the jump is believed
      // when the next sample follows it.
      if (!(have_jump_ && t_k > t_jump_ + 1e-9 && t_k - t_jump_ <= opt_.policy.max_gyro_gap_s)) {
        have_jump_ = true;
        t_jump_ = t_k;
        return done(GyroSampleStatus::kRejectedTimeJump);
      }
      after_gap = true;
    }
  }
  const double t_prev = time_reset ? t_back_prev : after_gap ? t_jump_ : have_gyro_ ? t_last_gyro_ : t_k - dt_nominal_;
  have_jump_ = false;
  n_back_ = 0;
  GyroVec g = g_in;
  unit_.RemoveCalibratedErrors(&g);  // a bench-calibrated unit's known bias and scale factor
  bool partial = false;
  const GyroSampleStatus outputs = CheckOutputs(&g, &partial);
  const bool held = outputs == GyroSampleStatus::kRejectedNonFinite || outputs == GyroSampleStatus::kRejectedOutOfRange;
  if (held && !have_gyro_) {
    last_partial_ = true;
    return done(outputs);  // no rate yet to hold
  }
  have_gyro_ = true;
  t_last_gyro_ = t_k;
  // The gyros did not cover the gap, or the clock went back: the attitude is taken afresh from the
  // next star solution.
  if (after_gap && initialised_ && t_k - t_cur_ > opt_.policy.max_gyro_gap_s) RequestRestart(RestartReason::kGyroGap);
  if (time_reset && initialised_) RequestRestart(RestartReason::kTimeReset);
  if (held) {
    // No rate from this sample: the last one is held over its interval (the filter's process noise
    // grows as usual); the star-rate chains break (the gyro angle over it is unknown).
    last_partial_ = true;
    if (cal_on_) cal_.BreakWindow();
    if (initialised_ && !restart_pending_ && t_k > t_cur_) {
      isolator_.BreakChain();
      tracker_.BreakChain();
      SaveFilter();
      filter_.Propagate(w_last_, t_k - t_cur_, noise_, false);
      t_cur_ = t_k;
      GuardFilter();
    }
    return done(outputs);
  }
  const GyroSampleStatus status = time_reset  ? GyroSampleStatus::kAcceptedTimeReset
                                  : after_gap ? GyroSampleStatus::kAcceptedAfterGap
                                              : outputs;
  FeedCalibration(t_k, g, status);
  // The applied unit calibration, before the rate, the fault monitors and the filter see the outputs.
  if (cal_applied_) g -= cal_e_ * (solver_.Pinv() * g);
  g_last_ = g;
  last_partial_ = partial;
  // A tracked fault's compensation at the middle of this sample's interval.
  if (tracked_ >= 0) {
    const double t_mid = t_k - 0.5 * (t_k - t_prev);
    dyn_[tracked_] = track_fit_.value_dph + track_fit_.ramp_dph_per_s * (t_mid - track_fit_t_);
  }
  // The rate for this step comes from the gyros in use before any isolation at this sample (as Fuse()).
  const Vec3 w = RateDph(g) * kDphToRadS;
  w_last_ = w;
  if (!initialised_ || restart_pending_ || t_k <= t_cur_) return done(status);
  const double full = t_k - t_prev;
  ++n_gyro_;
  SaveFilter();

  if (fdi_on_ && partial) {
    // A made-up output has no parity: the monitor skips the sample.
  } else if (fdi_on_ && isolating_) {
    monitor_.Track(t_k, g);
    OpenCovarianceWhileUnresolved();
  } else if (fdi_on_ && monitor_.Feed(t_k, g)) {
    OnDetection(t_k, monitor_.alarm_test().c_str(), monitor_.onset_s(), monitor_.jump().norm());
    // The size of the fault now, not the window mean that crossed the threshold.
    const GyroVec step = monitor_.StepEstimate(nullptr);
    const double now_dph = std::max(step.norm(), monitor_.short_mean().norm() + 3 * monitor_.short_mean_sigma());
    const double worst_dph = LargestImpliedRateDph(monitor_.V(), solver_, use_, now_dph);
    // The fault began at the onset (at most one parity window ago for the window test) and has
    // turned the attitude since, unknown to the filter: open the attitude covariance by that angle,
    // or the NIS gate refuses the very star fixes that would correct it.
    const double since_s = std::max(opt_.fdi_options.window_s, t_k - faults_.back().t_onset_s);
    filter_.InflateAttitude(worst_dph * kDphToRadS * since_s);
    // Several parity relations (5+ gyros): the direction of the fault's parity since onset.
    const GyroVec dir = fit_step_ + fit_ramp_ * (t_k - faults_.back().t_onset_s);
    const int gi = IsolateFromParity(monitor_.V(), dir, use_, opt_.fdi_options);
    if (gi >= 0) {
      const double f = step.dot(monitor_.V().col(gi)) / monitor_.V().col(gi).squaredNorm();
      Isolate(gi, t_k, "parity", GyroVec::Zero(n), f);
      w_last_ = RateDph(g) * kDphToRadS;
    } else {
      // Until isolation the fault feeds the bias: open its covariance (kept open sample by sample).
      filter_.InflateBias(worst_dph * kDphToRadS);
    }
  }
  const double d = t_k - t_cur_;
  PropagateTo(t_k, w, g, std::abs(d - full) < 1e-9 * full);
  GuardFilter();
  return done(status);
}

MekfUpdate OnlineFusion::AddAttitude(double t_j, const Quat& q_in, const Mat3& r_body) {
  const MekfUpdate u = AddAttitudeChecked(t_j, q_in, r_body);
  // The calibration takes the fixes the filter took (a gated one may be an outlier).
  if (cal_on_ && u.accepted && cal_.AddFix(t_j, q_in, r_body)) RefreshCalibration();
  return u;
}

MekfUpdate OnlineFusion::AddAttitudeChecked(double t_j, const Quat& q_in, const Mat3& r_body) {
  MekfUpdate u;
  // A measurement the filter cannot use changes nothing.
  const double qn = q_in.coeffs().allFinite() ? q_in.norm() : 0;
  if (!std::isfinite(t_j) || !(qn > 0.5 && qn < 2) || !r_body.allFinite() || !(r_body.diagonal().minCoeff() > 0)) {
    ++n_bad_meas_;
    u.status = UpdateStatus::kRejectedBadInput;
    return u;
  }
  const Quat q_meas = std::abs(qn - 1) > 1e-9 ? q_in.normalized() : q_in;
  if (initialised_ && t_j < t_cur_ - 1e-9 && !restart_pending_) {  // (a restart takes a fix of any time)
    ++n_late_;
    u.status = UpdateStatus::kRejectedLate;
    return u;
  }
  if (initialised_ && std::abs(t_j - t_last_st_) <= 1e-9) {  // the same frame again would count twice
    ++n_repeat_meas_;
    u.status = UpdateStatus::kRejectedRepeated;
    return u;
  }
  const double max_gap = opt_.policy.max_gyro_gap_s;
  // The latest time the estimator knows: the filter's, or the gyros' (ahead of it when a restart
  // waits for this fix, or before the first fix).
  const double t_known = !have_gyro_ ? t_cur_ : initialised_ ? std::max(t_cur_, t_last_gyro_) : t_last_gyro_;
  bool jumped = false;
  if ((initialised_ || have_gyro_) && t_j - t_known > max_gap) {
    // Far beyond: a corrupt time tag, or the gyros silent. Believed when the next measurement
    // follows it.
    if (!(have_meas_jump_ && t_j > t_meas_jump_ + 1e-9 && t_j - t_meas_jump_ <= max_gap)) {
      have_meas_jump_ = true;
      t_meas_jump_ = t_j;
      u.status = UpdateStatus::kRejectedTimeJump;
      return u;
    }
    jumped = true;
  }
  have_meas_jump_ = false;
  if (!initialised_) {
    Mat6 p0 = Mat6::Zero();
    p0.block<3, 3>(0, 0) = r_body;
    const double b0 = opt_.init_bias_sigma_dph * kDphToRadS;
    p0.block<3, 3>(3, 3) = Mat3::Identity() * b0 * b0;
    filter_.Init(q_meas, Vec3::Zero(), p0);
    initialised_ = true;
    t_cur_ = t_last_st_ = t_last_accepted_ = t_j;
    innov_zero_t_ = t_j;
    n_used_ = 1;
    u.accepted = true;
    u.status = UpdateStatus::kInitialised;
    return u;
  }
  // Beyond the gap, or the gyros silent for longer than it: nothing carries the attitude to this fix,
  // it restarts from it (a star-only attitude while the gyros stay silent; Status() says degraded).
  if (jumped || (have_gyro_ && t_j - t_last_gyro_ > max_gap)) {
    if (!restart_pending_) last_restart_ = RestartReason::kGyroGap;
    restart_pending_ = true;
  }
  if (restart_pending_) {
    Restart(t_j, q_meas, r_body);
    u.accepted = true;
    u.status = UpdateStatus::kInitialised;
    return u;
  }
  SaveFilter();
  u = Update(t_j, q_meas, r_body);
  if (GuardFilter()) u.accepted = false;
  return u;
}

MekfUpdate OnlineFusion::Update(double t_j, const Quat& q_meas, const Mat3& r_body) {
  MekfUpdate u;
  if (t_j > t_cur_) PropagateTo(t_j, w_last_, g_last_, false);

  const double gap = t_j - t_last_st_;
  t_last_st_ = t_j;
  // Star rates for isolation do not depend on the filter: every measurement counts.
  if (isolating_) {
    if (gap > opt_.policy.isolation_chain_gap_s) isolator_.BreakChain();
    isolator_.AddStar(t_j, q_meas, r_body);
    // Only a tracked fault's fit reads the stored samples, never older than its window: keep the
    // store bounded while an unresolved fault stays watched.
    isolator_.ForgetBefore(t_j - opt_.fdi_options.compensation_window_s);
  }
  if (tracked_ >= 0) {
    if (gap > opt_.policy.isolation_chain_gap_s) tracker_.BreakChain();
    tracker_.AddStar(t_j, q_meas, r_body);
    RefitTrackedFault(t_j);
  }
  // Without parity (three gyros left) a fault shows only in the star innovations: while one is
  // suspected, keep the bias open to the rate error the last innovation implies.
  const bool no_parity = fdi_on_ && !monitor_.active();
  if (no_parity && isolating_ && gap > 0) {
    const Vec3 resid = 2 * (filter_.q().conjugate() * q_meas).vec();
    FloorBias(resid.norm() / gap);
  }
  // A run of rejections means the filter, not the star tracker, is wrong: accept the next one.
  const double gate = consecutive_rejects_ >= opt_.policy.accept_after_rejections
                          ? std::numeric_limits<double>::infinity()
                          : opt_.nis_gate;
  u = filter_.UpdateAttitude(q_meas, r_body, gate);
  if (!u.accepted) {
    ++n_rejected_;
    ++consecutive_rejects_;
  } else {
    consecutive_rejects_ = 0;
    ++n_used_;
    t_last_accepted_ = t_j;
    // The ring full, the oldest entry goes (an isolation then restores from less far back).
    const size_t cap = bias_history_.size();
    if (n_bias_ == cap) {
      bias_first_ = (bias_first_ + 1) % cap;
      --n_bias_;
    }
    bias_history_[(bias_first_ + n_bias_) % cap] = {t_j, filter_.bias()};
    ++n_bias_;
    while (n_bias_ > 2 && bias_entry(0).first < t_j - opt_.policy.bias_history_s) {
      bias_first_ = (bias_first_ + 1) % cap;
      --n_bias_;
    }
  }
  if (no_parity && !isolating_) {
    // CUSUM on the innovations: their covariance grown noise_ratio times (chi^2, 3 dof; the same
    // log-likelihood ratio as the parity noise test), threshold from the false-alarm rate at the
    // star rate.
    const double rho = opt_.fdi_options.noise_ratio;
    if (innov_h_ == 0) innov_h_ = CusumThreshold(1, 1.0, opt_.fdi_options.false_alarm_per_h);
    innov_s_ = std::max(0.0, innov_s_ + 0.5 * (1 - 1 / rho) * u.nis - 1.5 * std::log(rho));
    if (innov_s_ == 0) innov_zero_t_ = t_j;
    if (innov_s_ > innov_h_) {
      OnDetection(t_j, "star_innovation", innov_zero_t_, 0.0);
      isolator_.AddStar(t_j, q_meas, r_body);
      innov_s_ = 0;
      filter_.InflateBias(std::sqrt(u.nis / 3) * std::sqrt(std::max(0.0, r_body.trace() / 3)) / std::max(gap, 1e-3));
    }
    return u;
  }
  if (!isolating_) return u;
  FaultEvent& ev = faults_.back();
  const GyroVec r = isolator_.ResidualDph();
  const int gi = IsolateSequential(r, isolator_.ResidualSigmaDph(), isolator_.covered_s(), use_, opt_.fdi_options);
  if (gi >= 0) {
    Isolate(gi, t_j, "star_rates", r, r[gi]);
    w_last_ = RateDph(g_last_) * kDphToRadS;
  } else if (t_j - ev.t_detect_s > opt_.fdi_options.isolation_timeout_s) {
    ev.status = FaultStatus::kUnresolved;  // still watched: a later isolation resolves it
    ev.residual_dph.assign(r.data(), r.data() + r.size());
  }
  return u;
}

}  // namespace ssiu
