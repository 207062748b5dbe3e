#include "discover/discover_frames.h"

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <limits>

#include "core/astrometry.h"
#include "core/error.h"
#include "core/stats.h"
#include "core/types.h"
#include "discover/discover_frames_internal.h"
#include "discover/discovery_json.h"

namespace ssiu {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

// Camera parameter blocks: 0 focal_length (df), 1-2 principal_point (dcx, dcy), 3 lens_distortion (dk1),
// 4 pixel_aspect (relative change of fy alone, da: fy -> fy (1 + da)), 5-7 aberration (b = v/c, ICRS:
// an observer velocity the catalog directions were not corrected for), 8 lens_distortion's second term
// (dk2, tried once k1 is in the model).
constexpr int kCam = 9;
using CamMask = std::array<bool, kCam>;
constexpr CamMask kNoCam = {};
CamMask MaskOf(std::initializer_list<int> blocks) {
  CamMask m = kNoCam;
  for (int k : blocks) m[k] = true;
  return m;
}
// The cause each camera parameter belongs to.
constexpr const char* kCamCause[kCam] = {"focal_length", "principal_point", "principal_point",
                                         "lens_distortion", "pixel_aspect", "aberration",
                                         "aberration", "aberration", "lens_distortion"};

// The camera of a frame whose boresight (inertial) is `bore`. Uncorrected aberration moves every star
// towards the apex by (v/c) sin(theta) (core/astrometry.h); across a field, to first order, that is a
// common shift (taken up by the frame's rotation) and a change of scale by 1 - b.bore: the stars
// close in on the boresight as it nears the apex. So it acts as a focal length that varies from frame
// to frame with the pointing, which frames in several directions tell apart from a focal-length error.
Camera Apply(const Camera& c0, const double* cam, const Vec3& bore = Vec3::Zero()) {
  Camera c = c0;
  const double aberration_scale = 1 - Vec3(cam[5], cam[6], cam[7]).dot(bore);
  if (aberration_scale != 1) c.ScaleFocal(aberration_scale);
  c.ScaleFocal((c0.focal_length_px + cam[0]) / c0.focal_length_px);  // fx and fy, aspect kept
  c.cx_px += cam[1];
  c.cy_px += cam[2];
  c.distortion.k1 += cam[3];
  c.distortion.k2 += cam[8];
  if (cam[4] != 0) c.focal_length_y_px = c.FocalYPx() * (1 + cam[4]);
  return c;
}

Quat Perturbed(const Quat& q, const double* d) {
  // q * exp(d/2): a small rotation in the sensor frame.
  Quat dq(1, d[0] / 2, d[1] / 2, d[2] / 2);
  dq.normalize();
  return (q * dq).normalized();
}

struct GeoFit {
  std::vector<double> rot;  // 3 per frame
  double cam[kCam] = {};
  double rss = 0;    // weighted
  MatrixXd cov_cam;  // unscaled covariance of the active camera parameters
  VectorXd res;      // 2 per star, measured - model over the centroid sigma
  MatrixXd jac;      // d res / d parameters at the last iteration (rotations, then camera)
};

// Predicted pixel of star s (nullopt-free: behind the camera gives a huge residual).
Vec2 Predict(const Camera& c, const Quat& q, const FrameStar& s) {
  const Vec3 v = q.conjugate() * s.r_inertial;
  const auto p = c.Project(v);
  return p ? *p : Vec2(1e6, 1e6);
}

// Gauss-Newton over the per-frame rotations of `frames` (others ignored) and the active camera
// parameters (mask), numerical Jacobian. fixed_cam: start (and, when mask is empty, held) values.
GeoFit FitGeometry(const SolvedFrameSet& set, const Camera& cam0, const std::vector<bool>& use_frame,
                   const std::array<bool, kCam>& mask, const double* fixed_cam, const FrameDiscoverOptions& o) {
  const int nf = static_cast<int>(set.q.size());
  GeoFit g;
  g.rot.assign(3 * nf, 0.0);
  for (int k = 0; k < kCam; ++k) g.cam[k] = fixed_cam ? fixed_cam[k] : 0.0;
  std::vector<int> rows;
  for (int i = 0; i < static_cast<int>(set.stars.size()); ++i) {
    if (use_frame[set.stars[i].frame]) rows.push_back(i);
  }
  std::vector<int> cam_idx;
  for (int k = 0; k < kCam; ++k) {
    if (mask[k]) cam_idx.push_back(k);
  }
  std::vector<int> frame_col(nf, -1);
  int np = 0;
  for (int f = 0; f < nf; ++f) {
    if (use_frame[f]) frame_col[f] = np, np += 3;
  }
  const int ncam0 = np;
  np += static_cast<int>(cam_idx.size());
  const int nr = 2 * static_cast<int>(rows.size());
  auto residuals = [&](const GeoFit& st, VectorXd* r) {
    std::vector<Camera> c;  // per frame: aberration makes the scale depend on the boresight
    for (int f = 0; f < nf; ++f) c.push_back(Apply(cam0, st.cam, set.q[f] * Vec3::UnitZ()));
    r->resize(nr);
    for (size_t k = 0; k < rows.size(); ++k) {
      const FrameStar& s = set.stars[rows[k]];
      const Vec2 p = Predict(c[s.frame], Perturbed(set.q[s.frame], &st.rot[3 * s.frame]), s);
      const double w = 1 / std::max(s.sigma_px, o.min_sigma_px);
      (*r)(2 * k) = (s.x_px - p.x()) * w;
      (*r)(2 * k + 1) = (s.y_px - p.y()) * w;
    }
  };
  VectorXd r;
  MatrixXd jtj;
  for (int it = 0; it < o.iterations; ++it) {
    residuals(g, &r);
    MatrixXd j = MatrixXd::Zero(nr, np);
    const double h_rot = 1e-7;
    const double h_cam[kCam] = {1e-3, 1e-3, 1e-3, 1e-7, 1e-7, 1e-7, 1e-7, 1e-7, 1e-6};
    for (int f = 0; f < nf; ++f) {
      if (frame_col[f] < 0) continue;
      for (int a = 0; a < 3; ++a) {
        GeoFit t = g;
        t.rot[3 * f + a] += h_rot;
        VectorXd r2;
        residuals(t, &r2);
        j.col(frame_col[f] + a) = (r2 - r) / h_rot;
      }
    }
    for (size_t k = 0; k < cam_idx.size(); ++k) {
      GeoFit t = g;
      t.cam[cam_idx[k]] += h_cam[cam_idx[k]];
      VectorXd r2;
      residuals(t, &r2);
      j.col(ncam0 + k) = (r2 - r) / h_cam[cam_idx[k]];
    }
    // r = measured - model: d r / d p = -d model / d p, so the step is -(J^T J)^-1 J^T r.
    jtj = j.transpose() * j;
    g.jac = j;
    const VectorXd step = -jtj.ldlt().solve(j.transpose() * r);
    if (!step.allFinite()) break;
    for (int f = 0; f < nf; ++f) {
      if (frame_col[f] < 0) continue;
      for (int a = 0; a < 3; ++a) g.rot[3 * f + a] += step(frame_col[f] + a);
    }
    for (size_t k = 0; k < cam_idx.size(); ++k) g.cam[cam_idx[k]] += step(ncam0 + k);
    if (step.cwiseAbs().maxCoeff() < 1e-12) break;
  }
  residuals(g, &r);
  g.rss = r.squaredNorm();
  g.res = r;
  if (!cam_idx.empty() && jtj.rows() == np) {
    const MatrixXd inv = jtj.ldlt().solve(MatrixXd::Identity(np, np));
    g.cov_cam = inv.bottomRightCorner(cam_idx.size(), cam_idx.size());
  }
  return g;
}

// P(chi^2_dof > w) for dof 1, 2 or 3 (closed forms).
double ChiSq1or2Survival(double w, int dof) {
  if (w <= 0) return 1.0;
  if (dof == 3) return std::erfc(std::sqrt(w / 2)) + std::sqrt(2 * w / kPi) * std::exp(-w / 2);
  return dof == 1 ? std::erfc(std::sqrt(w / 2)) : std::exp(-w / 2);
}

// Held-out residuals of the stars of `use_frame` under camera offsets `cam`, rotations refitted with the
// camera held: 2 per star (measured - model over the centroid sigma), as GeoFit::res.
VectorXd HeldOutResiduals(const SolvedFrameSet& set, const Camera& cam0, const std::vector<bool>& use_frame,
                          const double* cam, const FrameDiscoverOptions& o) {
  return FitGeometry(set, cam0, use_frame, kNoCam, cam, o).res;
}

// A held-out figure before and after a fix, its gain and the z of the improvement (0 when undefined).
struct HeldOut {
  double before = 0, after = 0, gain = 1, z = 0;
  bool z_defined = false;
};

// z of a held-out improvement (docs/discrepancy.md, as for the gyro): with e the held-out residual of
// the base and p the held-out prediction of the cause (fitted on other data), e.p / sqrt(p' S p) is
// N(0, 1) when the cause has no effect and e is noise of covariance S = s2 I, independent of p.
double HeldOutZ(double e_dot_p, double p_dot_p, double s2) {
  return p_dot_p > 0 && s2 > 0 ? e_dot_p / std::sqrt(s2 * p_dot_p) : 0.0;
}

void Fail(const std::string& what) { throw InputError("options", what); }

// The steps of DiscoverFrames (docs/discrepancy.md): stepwise extension of the model. At each step every
// cause not yet in the model is tested against the model (geometric causes: fitted jointly with the
// causes already in it), the significant ones are gated (bounds, held-out gain over the model) in BIC
// order and the first that passes enters; the loop ends when none passes. Then the residual of the
// final joint model is tested for structure (`unexplained`).
//
// False alarms across steps: step k tests the m_k causes left, each at alpha / m_k (Bonferroni within
// the step). On clean data only the first step can name anything, so P(a cause named) <= alpha. Once
// every present cause is in the model, the next step is again a test of clean data at alpha, and the
// search stops at its first step without a pass: P(a cause beyond the present ones) <= alpha as well,
// plus what a wrong cause absorbs of a present one, which the held-out gate and the joint refit bound.
class FrameCauseSearch {
 public:
  FrameCauseSearch(const SolvedFrameSet& set, const Camera& camera, const FrameDiscoverOptions& o)
      : set_(set), camera_(camera), o_(o), nf_(static_cast<int>(set.q.size())) {}

  FrameDiscovery Run() {
    d_.frames = static_cast<int>(set_.status.size());
    d_.frames_solved = nf_;
    d_.stars = static_cast<int>(set_.stars.size());
    d_.fitted_camera = camera_;
    hot_ = discover_internal::AnalyseHotPixels(set_, o_, &d_);
    psf_ = discover_internal::AnalysePsfShape(set_, camera_, o_, &d_);
    if (!hot_.tested) d_.not_tested.push_back("hot_pixels");
    if (!psf_.tested) d_.not_tested.push_back("psf_shape");
    aberration_testable_ = AberrationTestable();
    if (!aberration_testable_) d_.not_tested.push_back("aberration");
    d_.gain_z_min = boost::math::quantile(boost::math::complement(boost::math::normal(), o_.gain_alpha));
    if (nf_ == 0 || d_.stars < 10) {
      // Bonferroni over the candidates of the vocabulary (5 geometric/photometric + these).
      const double alpha_each = o_.alpha / (5 + aberration_testable_ + hot_.tested + psf_.tested);
      if (hot_.tested && hot_.candidate.p_value < alpha_each) {
        FrameCandidate c = hot_.candidate;
        c.significant = c.evaluated = true;
        c.gain = hot_.gain, c.verdict = "named";
        d_.candidates.push_back(c);
        HeldOut h;
        h.before = hot_.before, h.after = hot_.after, h.gain = hot_.gain;
        Enter(c, h);
        Conclude();
      }
      return d_;
    }
    GeometricModels();
    MeasuredFigures();
    for (int step = 1;; ++step) {
      std::vector<FrameCandidate> cands = StepCandidates();
      if (cands.empty()) break;
      for (auto& c : cands) c.significant = c.p_value < o_.alpha / cands.size();
      HeldOut ho;
      const int chosen = ChooseCause(&cands, &ho);
      d_.steps.push_back(cands);
      if (step == 1) d_.candidates = cands;
      if (chosen < 0) break;
      Enter(cands[chosen], ho);
    }
    Prune();
    Conclude();
    return d_;
  }

 private:
  struct Spec {
    std::string cause;
    CamMask mask;
    // A further term: "k2" added to lens_distortion in the model, "k1+k2" lens_distortion entering with
    // both (a k2-dominated lens looks like neither k1 nor a focal length alone); else empty.
    std::string term;
  };

  // aberration needs frames pointing in several directions (else it is a focal length): the
  // boresights' scatter matrix must have no small eigenvalue, and more frames than its 3 parameters
  // plus a focal length (with 3 frames it fits any per-frame scale).
  bool AberrationTestable() const {
    if (set_.q.size() < 6) return false;
    Mat3 scatter = Mat3::Zero();
    for (const auto& q : set_.q) scatter += (q * Vec3::UnitZ()) * (q * Vec3::UnitZ()).transpose() / set_.q.size();
    return Eigen::SelfAdjointEigenSolver<Mat3>(scatter).eigenvalues().minCoeff() > 0.02;
  }

  static CamMask Union(const CamMask& a, const CamMask& b) {
    CamMask m;
    for (int k = 0; k < kCam; ++k) m[k] = a[k] || b[k];
    return m;
  }
  static CamMask Minus(const CamMask& a, const CamMask& b) {
    CamMask m;
    for (int k = 0; k < kCam; ++k) m[k] = a[k] && !b[k];
    return m;
  }
  // The model's camera offsets on the blocks of `mask`, zero elsewhere: where a fit of `mask` starts.
  void StartOf(const CamMask& mask, double* start) const {
    for (int k = 0; k < kCam; ++k) start[k] = mask[k] ? model_.cam[k] : 0.0;
  }
  // RMS (px) of a fit's whitened residuals over the stars it was fitted to.
  double FittedRmsPx(const VectorXd& res) const {
    double ss = 0;
    for (int i = 0; i < d_.stars; ++i) {
      const double w = std::max(set_.stars[i].sigma_px, o_.min_sigma_px);
      ss += (std::pow(res(2 * i), 2) + std::pow(res(2 * i + 1), 2)) * w * w;
    }
    return std::sqrt(ss / (2 * d_.stars));
  }

  bool InModel(const std::string& cause) const {
    for (const auto& e : d_.causes) {
      if (e.cause == cause) return true;
    }
    return false;
  }

  // The camera causes, the base (camera as given, one rotation per frame) and the fullest model (every
  // camera cause), whose residual variance scales every chi-square: it holds whatever is present.
  void GeometricModels() {
    specs_ = {{"focal_length", MaskOf({0}), ""},
              {"principal_point", MaskOf({1, 2}), ""},
              {"lens_distortion", MaskOf({3}), ""},
              {"pixel_aspect", MaskOf({4}), ""},
              {"lens_distortion", MaskOf({8}), "k2"},
              {"lens_distortion", MaskOf({3, 8}), "k1+k2"}};
    const bool ab = aberration_testable_;
    if (ab) specs_.push_back({"aberration", MaskOf({5, 6, 7}), ""});
    const std::vector<bool> all(nf_, true);
    base_ = FitGeometry(set_, camera_, all, kNoCam, nullptr, o_);
    const GeoFit fullest =
        FitGeometry(set_, camera_, all, ab ? MaskOf({0, 1, 2, 3, 4, 5, 6, 7, 8}) : MaskOf({0, 1, 2, 3, 4, 8}),
                    nullptr, o_);
    s2_ = fullest.rss / std::max(1, 2 * d_.stars - (3 * nf_ + kCam));
    model_ = base_;
    model_mask_ = kNoCam;
    base_rms_px_ = model_rms_px_ = FittedRmsPx(base_.res);
  }

  // The candidates of one step: every cause not in the model, tested against it.
  std::vector<FrameCandidate> StepCandidates() {
    std::vector<FrameCandidate> out;
    const std::vector<bool> all(nf_, true);
    const double nobs = 2.0 * d_.stars;
    fits_.clear();
    for (const auto& sp : specs_) {
      // A cause enters once (alone or with its further term); a further term only after its cause, once.
      const bool added_term = sp.term == "k2";
      if (!added_term ? InModel(sp.cause) : !InModel(sp.cause) || Union(model_mask_, sp.mask) == model_mask_)
        continue;
      FrameCandidate c;
      c.cause = sp.cause;
      c.term = sp.term;
      c.dof = static_cast<int>(std::count(sp.mask.begin(), sp.mask.end(), true));
      const GeoFit g = FitGeometry(set_, camera_, all, Union(model_mask_, sp.mask), model_.cam, o_);
      c.statistic = std::max(0.0, (model_.rss - g.rss) / s2_);
      c.p_value = ChiSq1or2Survival(c.statistic, c.dof);
      c.delta_bic = c.statistic - c.dof * std::log(nobs);
      fits_[Key(c)] = g;
      out.push_back(c);
    }
    if (!InModel("vignetting")) out.push_back(VignettingCandidate());
    for (const auto* r : {&hot_, &psf_}) {
      if (r->tested && !InModel(r->candidate.cause)) out.push_back(r->candidate);
    }
    return out;
  }

  // The model's camera (the named geometric causes; aberration is not a camera property).
  Camera ModelCamera() const {
    double cam[kCam];
    for (int k = 0; k < kCam; ++k) cam[k] = k >= 5 && k <= 7 ? 0.0 : model_.cam[k];
    return Apply(camera_, cam);
  }

  // Vignetting: y = ln(flux) + 0.4 ln(10) V against u = (r / r_corner)^2, r about the model's
  // principal point.
  FrameCandidate VignettingCandidate() {
    const Camera cam = ModelCamera();
    vu_.clear(), vy_.clear(), vframe_.clear();
    std::vector<double> y_whole;  // before the model's vignetting is taken out: the whole law's fit
    for (const auto& s : set_.stars) {
      const double u = VignettingRadius2(cam, s.x_px, s.y_px);
      const double model = 1 - o_.vignetting * u;  // the model's own vignetting, taken out
      if (!(s.flux > 0) || !(model > 0.05)) continue;
      vu_.push_back(u);
      y_whole.push_back(std::log(s.flux) + 0.4 * std::log(10.0) * s.mag);
      vy_.push_back(y_whole.back() - std::log(model));
      vframe_.push_back(s.frame);
    }
    FrameCandidate c;
    c.cause = "vignetting";
    c.dof = 1;
    const int n = static_cast<int>(vu_.size());
    if (n >= 10) {
      double mu = 0, my = 0;
      for (int i = 0; i < n; ++i) mu += vu_[i] / n, my += vy_[i] / n;
      double suu = 0, suy = 0;
      for (int i = 0; i < n; ++i) suu += (vu_[i] - mu) * (vu_[i] - mu), suy += (vu_[i] - mu) * (vy_[i] - my);
      const double slope = suy / suu;
      double ss = 0;
      for (int i = 0; i < n; ++i) ss += std::pow(vy_[i] - my - slope * (vu_[i] - mu), 2);
      vig_s_ = std::sqrt(ss / (n - 2));
      const double se = vig_s_ / std::sqrt(suu);
      c.statistic = std::pow(slope / se, 2);
      c.p_value = ChiSq1or2Survival(c.statistic, 1);
      c.delta_bic = c.statistic - std::log(static_cast<double>(n));
    }
    // The parameter is the whole law's v (the model's and what is left beyond it), fitted as one law.
    vig_v_ = n >= 10 ? discover_internal::FitVignettingLaw(vu_, y_whole, &vig_sigma_) : 0.0;
    return c;
  }

  // Measured figures for the comparison with the simulator.
  void MeasuredFigures() {
    std::vector<double> y;
    for (const auto& s : set_.stars) {
      if (s.flux > 0) y.push_back(std::log(s.flux) + 0.4 * std::log(10.0) * s.mag);
    }
    if (!y.empty()) {
      double m = 0, ss = 0;
      for (double v : y) m += v / y.size();
      for (double v : y) ss += (v - m) * (v - m);
      d_.zero_point_adu = std::exp(m);
      d_.photometric_scatter_mag = std::sqrt(ss / y.size()) * 2.5 / std::log(10.0);
    }
    std::vector<double> ps;
    for (const auto& s : set_.stars) {
      if (s.psf_sigma_px > 0) ps.push_back(s.psf_sigma_px);
    }
    d_.psf_sigma_median_px = Median(ps);
    d_.background_median_adu = Median(set_.background_adu);
    d_.noise_median_adu = Median(set_.noise_adu);
  }

  const Spec* SpecOf(const std::string& cause, const std::string& term = "") const {
    for (const auto& sp : specs_) {
      if (sp.cause == cause && sp.term == term) return &sp;
    }
    return nullptr;
  }
  static std::string Key(const FrameCandidate& c) { return c.term.empty() ? c.cause : c.cause + ":" + c.term; }

  // The model's held-out residuals of a step (HeldOutFolds of model_mask_), computed once for every
  // candidate of the step that reaches the held-out gate.
  struct ModelFolds {
    bool done = false;
    VectorXd e, w2;
  };

  // Geometric: the model with and without the cause fitted on the even frames, scored on the odd ones
  // and vice versa (rotations refitted there with the camera held); RMS in px, z over both folds.
  HeldOut GeometricHeldOut(const Spec& sp, const GeoFit& fit, ModelFolds* model) {
    HeldOut h;
    if (nf_ < 2) {  // one frame: the fitted figures stand (no held-out frames)
      h.before = model_rms_px_, h.after = FittedRmsPx(fit.res);
      h.gain = h.after > 0 ? h.before / h.after : 1.0;
      return h;
    }
    if (!model->done) model->e = HeldOutFolds(model_mask_, &model->w2), model->done = true;
    const VectorXd &e = model->e, &w2 = model->w2, r = HeldOutFolds(Union(model_mask_, sp.mask));
    if (e.size() == 0) return h;
    h.before = RmsPx(e, w2), h.after = RmsPx(r, w2);
    h.gain = h.after > 0 ? h.before / h.after : 1.0;
    h.z = HeldOutZ(e.dot(e - r), (e - r).squaredNorm(), s2_), h.z_defined = true;
    return h;
  }

  // Both folds' held-out residuals (whitened; the stars of the odd frames, then of the even ones) under
  // the camera blocks `mask` fitted on the other frames (started from the model's values), and the
  // squared centroid sigma of each residual.
  VectorXd HeldOutFolds(const CamMask& mask, VectorXd* w2 = nullptr) const {
    double start[kCam];
    StartOf(mask, start);
    std::vector<VectorXd> parts;
    std::vector<double> weights;
    for (int fold = 0; fold < 2; ++fold) {
      std::vector<bool> train(nf_), test(nf_);
      for (int f = 0; f < nf_; ++f) train[f] = f % 2 == fold, test[f] = !train[f];
      const GeoFit g = FitGeometry(set_, camera_, train, mask, start, o_);
      parts.push_back(HeldOutResiduals(set_, camera_, test, g.cam, o_));
      for (const auto& st : set_.stars) {
        if (test[st.frame]) weights.insert(weights.end(), 2, std::pow(std::max(st.sigma_px, o_.min_sigma_px), 2));
      }
    }
    VectorXd out(parts[0].size() + parts[1].size());
    out.head(parts[0].size()) = parts[0];
    out.tail(parts[1].size()) = parts[1];
    if (w2) *w2 = Eigen::Map<const VectorXd>(weights.data(), static_cast<Eigen::Index>(weights.size()));
    return out;
  }

  static double RmsPx(const VectorXd& r_whitened, const VectorXd& w2) {
    return r_whitened.size() ? std::sqrt(r_whitened.cwiseAbs2().dot(w2) / r_whitened.size()) : 0.0;
  }

  // Vignetting: the slope fitted on the even frames scored on the odd ones and vice versa (mag).
  HeldOut VignettingHeldOut() const {
    const double to_mag = 2.5 / std::log(10.0);
    HeldOut h;
    double ssb = 0, ssa = 0, ep = 0, pp = 0;
    int n = 0;
    for (int fold = 0; fold < 2; ++fold) {
      double mu = 0, my = 0, cnt = 0;
      for (size_t i = 0; i < vu_.size(); ++i) {
        if (vframe_[i] % 2 == fold) mu += vu_[i], my += vy_[i], cnt += 1;
      }
      if (cnt < 3) continue;
      mu /= cnt, my /= cnt;
      double suu = 0, suy = 0;
      for (size_t i = 0; i < vu_.size(); ++i) {
        if (vframe_[i] % 2 == fold) suu += (vu_[i] - mu) * (vu_[i] - mu), suy += (vu_[i] - mu) * (vy_[i] - my);
      }
      const double b = suu > 0 ? suy / suu : 0.0;
      double yb = 0;
      for (size_t i = 0; i < vu_.size(); ++i) {
        if (vframe_[i] % 2 == fold) yb += vy_[i] - b * vu_[i];
      }
      yb /= cnt;
      for (size_t i = 0; i < vu_.size(); ++i) {
        if (vframe_[i] % 2 == fold) continue;
        const double e = vy_[i] - my, r = vy_[i] - yb - b * vu_[i];
        ssb += e * e, ssa += r * r, ep += e * (e - r), pp += (e - r) * (e - r);
        ++n;
      }
    }
    if (n == 0) return h;
    h.before = std::sqrt(ssb / n) * to_mag, h.after = std::sqrt(ssa / n) * to_mag;
    h.gain = h.after > 0 ? h.before / h.after : 1.0;
    if (nf_ >= 2) h.z = HeldOutZ(ep, pp, vig_s_ * vig_s_), h.z_defined = true;
    return h;
  }

  // Physical bounds (docs/discrepancy.md) of the camera offsets `g` for every geometric cause of `mask`:
  // wide on purpose, they catch fits that explain noise or each other, not unusual cameras. Empty when
  // within them, else why not.
  std::string GeometryOutOfBounds(const double* g, const CamMask& mask) const {
    if (mask[0] && !(std::abs(g[0] / camera_.focal_length_px) <= 0.05)) return "focal length off by > 5 %";
    if (mask[1] && !(std::abs(g[1]) <= 0.2 * camera_.width && std::abs(g[2]) <= 0.2 * camera_.height))
      return "principal point moved by > 20 % of the frame";
    if (mask[3]) {
      // k1 r^2 at the corner (normalised coordinates): the relative displacement there.
      const double rc2 =
          std::pow(std::max(camera_.cx_px, camera_.width - 1 - camera_.cx_px) / camera_.focal_length_px, 2) +
          std::pow(std::max(camera_.cy_px, camera_.height - 1 - camera_.cy_px) / camera_.FocalYPx(), 2);
      if (!(std::abs((camera_.distortion.k1 + g[3]) * rc2) <= 0.3)) return "k1 moves the corners by > 30 %";
      if (mask[8] && !(std::abs((camera_.distortion.k2 + g[8]) * rc2 * rc2) <= 0.3))
        return "k2 moves the corners by > 30 %";
    }
    if (mask[4] && !(std::abs(g[4]) <= 0.05)) return "aspect off by > 5 %";
    if (mask[5] && !(Vec3(g[5], g[6], g[7]).norm() * kSpeedOfLightMS / 1000 <= 100)) return "speed > 100 km/s";
    return "";
  }

  std::string OutOfBounds(const FrameCandidate& c) {
    const std::string& cause = c.cause;
    if (cause == "vignetting") return vig_v_ >= 0 && vig_v_ <= 0.95 ? "" : "vignetting outside [0, 0.95]";
    if (cause == "hot_pixels")
      return hot_.parameters.count("hot_pixel_count") && hot_.parameters.at("hot_pixel_count") >= 1 ? "" : "no pixel";
    if (cause == "psf_shape") {
      const double sg = psf_.parameters.count("psf_sigma_px") ? psf_.parameters.at("psf_sigma_px") : 0;
      const double el = psf_.parameters.count("psf_ellipticity") ? psf_.parameters.at("psf_ellipticity") : 0;
      return sg >= 0.1 && sg <= 10 && el < 0.9 ? "" : "PSF sigma outside [0.1, 10] px or ellipticity >= 0.9";
    }
    // The joint fit with the cause: every named geometric cause must stay within its bounds too.
    return GeometryOutOfBounds(fits_[Key(c)].cam, Union(model_mask_, SpecOf(cause, c.term)->mask));
  }

  // Gates, in BIC order until one candidate passes: its parameters lie within the physical bounds and
  // its held-out improvement over the model is significant (one-sided z above the normal quantile of
  // gain_alpha). Returns the index of the candidate that enters (-1: none) and its held-out figures.
  int ChooseCause(std::vector<FrameCandidate>* cands, HeldOut* chosen_ho) {
    std::vector<int> order;
    for (int i = 0; i < static_cast<int>(cands->size()); ++i) {
      if ((*cands)[i].significant) order.push_back(i);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return (*cands)[a].delta_bic > (*cands)[b].delta_bic; });
    ModelFolds model;
    for (int i : order) {
      FrameCandidate& c = (*cands)[i];
      c.evaluated = true;
      const std::string why = OutOfBounds(c);
      if (!why.empty()) {
        c.verdict = "outside bounds: " + why;
        continue;
      }
      HeldOut h;
      if (const Spec* sp = SpecOf(c.cause, c.term)) {
        h = GeometricHeldOut(*sp, fits_[Key(c)], &model);
      } else if (c.cause == "vignetting") {
        h = VignettingHeldOut();
      } else {  // hot_pixels, psf_shape: their own held-out figures (no z)
        const auto& r = c.cause == "hot_pixels" ? hot_ : psf_;
        h.before = r.before, h.after = r.after, h.gain = r.gain;
      }
      c.gain = h.gain, c.gain_z = h.z;
      // From the second step on, the gain over the model is small by nature and its held-out estimate
      // carries the scatter of parameters fitted on half the frames: the z of the improvement decides.
      const bool gain_needed = d_.causes.empty() || !h.z_defined;
      if ((gain_needed && !(h.gain > 1)) || (h.z_defined && !(h.z > d_.gain_z_min))) {
        c.verdict = "held-out gain not significant";
        continue;
      }
      c.verdict = nf_ >= 2 || !SpecOf(c.cause) ? "named" : "named (one frame: gain on the fitted frame)";
      *chosen_ho = h;
      return i;
    }
    return -1;
  }

  double ArcsecPerPx() const { return kRadToArcsec / camera_.FocalMeanPx(); }

  // The cause enters the model: its step's figures (the parameters come from the final joint fit).
  void Enter(const FrameCandidate& c, const HeldOut& ho) {
    if (c.term == "k2") {  // a further term of a cause in the model: the cause's entry lists it
      model_mask_ = Union(model_mask_, SpecOf(c.cause, c.term)->mask);
      model_ = fits_[Key(c)];
      model_rms_px_ = ho.after;
      for (auto& e : d_.causes) {
        if (e.cause == c.cause) e.terms.push_back(c.term), e.residual_rms_arcsec = model_rms_px_ * ArcsecPerPx();
      }
      return;
    }
    FrameCauseStep e;
    e.cause = c.cause;
    e.step = static_cast<int>(d_.causes.size()) + 1;
    if (c.term == "k1+k2") e.terms.push_back("k2");
    e.statistic = c.statistic, e.p_value = c.p_value;
    e.gain = ho.gain, e.gain_z = ho.z;
    e.held_out_before = ho.before, e.held_out_after = ho.after;
    if (const Spec* sp = SpecOf(c.cause, c.term)) {
      model_mask_ = Union(model_mask_, sp->mask);
      model_ = fits_[Key(c)];
      model_rms_px_ = ho.after;
    } else if (c.cause == "vignetting") {
      vignetting_ = true;
    }
    e.residual_rms_arcsec = model_rms_px_ * ArcsecPerPx();
    d_.causes.push_back(e);
  }

  // The parameters of a geometric cause from the joint fit g of the camera blocks `mask`, with the
  // 1-sigmas (residual scale of the fullest model).
  void GeometricParameters(const std::string& cause, const GeoFit& g, const CamMask& mask,
                           std::map<std::string, double>* p, std::map<std::string, double>* s) const {
    constexpr double kc_kms = kSpeedOfLightMS / 1000;  // aberration: observer velocity v = b c (km/s, ICRS)
    const double aspect0 = camera_.FocalYPx() / camera_.focal_length_px;  // pixel_aspect is fy / fx
    const double nominal[kCam] = {camera_.focal_length_px, camera_.cx_px, camera_.cy_px, camera_.distortion.k1,
                                  aspect0, 0, 0, 0, camera_.distortion.k2};
    const double unit[kCam] = {1, 1, 1, 1, aspect0, kc_kms, kc_kms, kc_kms, 1};
    const double sc = std::sqrt(s2_);
    int col = 0;
    for (int k = 0; k < kCam; ++k) {
      if (!mask[k]) continue;
      if (cause == kCamCause[k]) {
        (*p)[kCamNames[k]] = nominal[k] + unit[k] * g.cam[k];
        (*s)[kCamNames[k]] = g.cov_cam.rows() > col ? unit[k] * std::sqrt(g.cov_cam(col, col)) * sc : 0.0;
      }
      ++col;
    }
    if (cause == "aberration") (*p)["speed_kms"] = Vec3(g.cam[5], g.cam[6], g.cam[7]).norm() * kc_kms;
    if (cause == "pixel_aspect") {
      (*p)["focal_length_y_px"] = Apply(camera_, g.cam).FocalYPx();
      (*s)["focal_length_y_px"] = s->at("pixel_aspect") * camera_.focal_length_px;
    }
    if (cause == "focal_length") {
      (*p)["focal_length_ppm"] = g.cam[0] / camera_.focal_length_px * 1e6;
      (*s)["focal_length_ppm"] = s->at("focal_length_px") / camera_.focal_length_px * 1e6;
    }
  }

  // Backward check of the forward steps: a geometric cause (or lens_distortion's k2) that no longer adds
  // significantly to the final joint model (it stood in for a combination of causes that entered after
  // it) leaves the model, the least significant first, at the level of the steps (alpha over the
  // geometric parts in the model).
  void Prune() {
    const std::vector<bool> all(nf_, true);
    for (;;) {
      struct Part {
        int entry;
        CamMask mask;
        bool term;  // lens_distortion's k2 alone
      };
      std::vector<Part> parts;
      for (int i = 0; i < static_cast<int>(d_.causes.size()); ++i) {
        const Spec* sp = SpecOf(d_.causes[i].cause);
        if (!sp) continue;
        CamMask m = sp->mask;
        if (d_.causes[i].cause == "lens_distortion" && model_mask_[8]) {
          m[8] = true;
          parts.push_back({i, MaskOf({8}), true});
        }
        parts.push_back({i, m, false});
      }
      if (parts.size() < 2) return;
      int worst = -1;
      double worst_p = 0;
      GeoFit worst_fit;
      for (int k = 0; k < static_cast<int>(parts.size()); ++k) {
        const CamMask without = Minus(model_mask_, parts[k].mask);
        double start[kCam];
        StartOf(without, start);
        GeoFit g = FitGeometry(set_, camera_, all, without, start, o_);
        const int dof = static_cast<int>(std::count(parts[k].mask.begin(), parts[k].mask.end(), true));
        const double p = ChiSq1or2Survival(std::max(0.0, (g.rss - model_.rss) / s2_), dof);
        if (p >= o_.alpha / parts.size() && p > worst_p) worst = k, worst_p = p, worst_fit = std::move(g);
      }
      if (worst < 0) return;
      const Part& w = parts[worst];
      FrameCauseStep& e = d_.causes[w.entry];
      d_.removed.push_back({e.cause, w.term ? "k2" : "", worst_p});
      model_mask_ = Minus(model_mask_, w.mask);
      model_ = std::move(worst_fit);
      if (w.term) {
        e.terms.erase(std::remove(e.terms.begin(), e.terms.end(), "k2"), e.terms.end());
      } else {
        d_.causes.erase(d_.causes.begin() + w.entry);
        for (size_t i = 0; i < d_.causes.size(); ++i) d_.causes[i].step = static_cast<int>(i) + 1;
      }
      if (nf_ >= 2) {
        VectorXd w2;
        const VectorXd r = HeldOutFolds(model_mask_, &w2);
        model_rms_px_ = RmsPx(r, w2);
      } else {  // one frame: the fitted figure, as the gate used
        model_rms_px_ = FittedRmsPx(model_.res);
      }
    }
  }

  // After the last step: every named cause's parameters from the final joint fit, the fitted camera,
  // the correlations, the residual test of the final model, the verdict.
  void Conclude() {
    if (!d_.causes.empty() && nf_ > 0 && d_.stars >= 10) {
      d_.fitted_camera = ModelCamera();
      if (vignetting_) {  // refitted about the final principal point
        VignettingCandidate();
      }
    }
    for (auto& e : d_.causes) {
      if (SpecOf(e.cause)) {
        GeometricParameters(e.cause, model_, model_mask_, &e.parameters, &e.sigmas);
      } else if (e.cause == "vignetting") {
        e.parameters["vignetting"] = vig_v_;
        e.sigmas["vignetting"] = vig_sigma_;
        d_.flux_rms_before_mag = e.held_out_before, d_.flux_rms_after_mag = e.held_out_after;
      } else {
        const auto& r = e.cause == "hot_pixels" ? hot_ : psf_;
        e.parameters = r.parameters, e.sigmas = r.sigmas;
        if (e.cause == "hot_pixels") {
          d_.spikes_before = r.before, d_.spikes_after = r.after;
        } else {
          d_.stamp_rms_before = r.before, d_.stamp_rms_after = r.after;
        }
      }
      for (const auto& [k, v] : e.parameters) d_.parameters[k] = v;
      for (const auto& [k, v] : e.sigmas) d_.sigmas[k] = v;
    }
    Correlations();
    FittedCameraExtras();
    if (!d_.causes.empty()) {
      d_.cause = d_.causes.front().cause;
      d_.gain = d_.causes.front().gain, d_.gain_z = d_.causes.front().gain_z;
    }
    if (nf_ == 0 || d_.stars < 10) return;
    PlotResiduals();
    // `unexplained`: the residual of the final model (every named cause), structure that no named cause
    // explains.
    d_.residual = discover_internal::TestFrameResidual(set_, d_.fitted_camera, model_.jac, model_.res, o_);
    if (d_.residual.structured) {
      d_.partial_cause = d_.cause == "none" ? "" : d_.cause;
      d_.cause = "unexplained";
    }
  }

  // fitted_camera's PSF, vignetting and hot pixels: the model's, replaced (or, for hot pixels,
  // extended) by what the named causes fitted.
  void FittedCameraExtras() {
    CameraExtras& x = d_.fitted_camera_extras;
    x.psf_sigma_px = o_.psf_sigma_px, x.psf_ellipticity = o_.psf_ellipticity, x.psf_angle_deg = o_.psf_angle_deg;
    x.vignetting = o_.vignetting;
    x.hot_pixels = o_.hot_pixels;
    const auto& p = d_.parameters;
    for (const auto& e : d_.causes) {
      if (e.cause == "psf_shape") {
        x.psf_sigma_px = p.at("psf_sigma_px"), x.psf_ellipticity = p.at("psf_ellipticity");
        x.psf_angle_deg = p.at("psf_angle_deg");
      } else if (e.cause == "vignetting") {
        x.vignetting = p.at("vignetting");
      } else if (e.cause == "hot_pixels") {
        for (const auto& h : d_.hot_pixels) x.hot_pixels.push_back({h.x, h.y});
      }
    }
  }

  // Correlations between the camera parameters of the named causes (final joint fit).
  void Correlations() {
    std::vector<int> idx;
    for (int k = 0; k < kCam; ++k) {
      if (model_mask_[k]) idx.push_back(k);
    }
    if (model_.cov_cam.rows() != static_cast<int>(idx.size())) return;
    for (size_t a = 0; a < idx.size(); ++a) {
      for (size_t b = a + 1; b < idx.size(); ++b) {
        const double den = std::sqrt(model_.cov_cam(a, a) * model_.cov_cam(b, b));
        d_.correlations.push_back({kCamNames[idx[a]], kCamNames[idx[b]], den > 0 ? model_.cov_cam(a, b) / den : 0.0});
      }
    }
  }

  // Residuals before (base) and after (the final model) for the plot, and the held-out RMS.
  void PlotResiduals() {
    for (int i = 0; i < d_.stars; ++i) {
      const auto& s = set_.stars[i];
      const double w = std::max(s.sigma_px, o_.min_sigma_px);
      d_.x_px.push_back(s.x_px);
      d_.y_px.push_back(s.y_px);
      d_.dx_before_px.push_back(base_.res(2 * i) * w);
      d_.dy_before_px.push_back(base_.res(2 * i + 1) * w);
      d_.dx_after_px.push_back(model_.res(2 * i) * w);
      d_.dy_after_px.push_back(model_.res(2 * i + 1) * w);
    }
    // Held-out RMS (even/odd frames) of the base and of the final model; one frame: the fitted figures.
    d_.residual_rms_before_arcsec = base_rms_px_ * ArcsecPerPx();
    d_.residual_rms_after_arcsec = model_rms_px_ * ArcsecPerPx();
  }

  static constexpr const char* kCamNames[kCam] = {"focal_length_px", "cx_px",          "cy_px",
                                                  "k1",              "pixel_aspect",   "velocity_x_kms",
                                                  "velocity_y_kms",  "velocity_z_kms", "k2"};

  const SolvedFrameSet& set_;
  const Camera& camera_;
  const FrameDiscoverOptions& o_;
  const int nf_;
  FrameDiscovery d_;
  discover_internal::CauseResult hot_, psf_;
  bool aberration_testable_ = false;
  std::vector<Spec> specs_;
  GeoFit base_, model_;  // the base and the current (finally the final) joint model
  CamMask model_mask_ = kNoCam;
  bool vignetting_ = false;
  double base_rms_px_ = 0, model_rms_px_ = 0;  // held-out position RMS of the base and of the model
  double s2_ = 0;                               // residual variance of the fullest model (whitened units)
  std::map<std::string, GeoFit> fits_;          // this step's joint fits, model + cause
  std::vector<double> vu_, vy_;                 // vignetting: squared field radius and flux-magnitude residual
  std::vector<int> vframe_;                     // and the frame of each
  double vig_s_ = 0, vig_v_ = 0, vig_sigma_ = 0;
};

}  // namespace

void FrameDiscoverOptions::Check() const {
  if (!(alpha > 0 && alpha < 0.5)) Fail("alpha must be in (0, 0.5)");
  if (iterations < 1) Fail("iterations must be >= 1");
  if (!(min_sigma_px > 0)) Fail("min_sigma_px must be > 0");
  if (!(psf_sigma_px >= 0 && psf_sigma_px < 50)) Fail("psf_sigma_px must be in [0, 50) (0 = not tested)");
  if (!(psf_ellipticity >= 0 && psf_ellipticity < 1)) Fail("psf_ellipticity must be in [0, 1)");
  if (!std::isfinite(psf_angle_deg)) Fail("psf_angle_deg must be finite");
  if (!(vignetting >= 0 && vignetting < 1)) Fail("vignetting must be in [0, 1)");
  if (!(psf_width_floor_pct >= 0 && psf_width_floor_pct < 100)) Fail("psf_width_floor_pct must be in [0, 100)");
  if (!(psf_ellipticity_floor >= 0 && psf_ellipticity_floor < 1)) Fail("psf_ellipticity_floor must be in [0, 1)");
  if (!(gain_alpha > 0 && gain_alpha < 0.5)) Fail("gain_alpha must be in (0, 0.5)");
  if (!(residual_alpha > 0 && residual_alpha < 0.5)) Fail("residual_alpha must be in (0, 0.5)");
  if (residual_min_stars_per_cell < 3) Fail("residual_min_stars_per_cell must be >= 3");
}


FrameDiscovery DiscoverFrames(const SolvedFrameSet& set, const Camera& camera, const FrameDiscoverOptions& o) {
  o.Check();
  return FrameCauseSearch(set, camera, o).Run();
}

}  // namespace ssiu
