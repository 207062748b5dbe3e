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
// an observer velocity the catalog directions were not corrected for).
constexpr int kCam = 8;
using CamMask = std::array<bool, kCam>;
constexpr CamMask kNoCam = {false, false, false, false, false, false, false, false};

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
  double cam[kCam] = {0, 0, 0, 0, 0, 0, 0, 0};
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
    const double h_cam[kCam] = {1e-3, 1e-3, 1e-3, 1e-7, 1e-7, 1e-7, 1e-7, 1e-7};
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

// The steps of DiscoverFrames (docs/discrepancy.md): the candidates' tests, the measured figures,
// the gates (bounds, held-out gain) in BIC order, the named cause's parameters and the residual test.
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
    // Bonferroni over the candidates actually tested (5 geometric/photometric + these).
    alpha_each_ = o_.alpha / (5 + aberration_testable_ + hot_.tested + psf_.tested);
    if (nf_ == 0 || d_.stars < 10) {
      d_.cause = "none";
      if (hot_.tested && hot_.candidate.p_value < alpha_each_) NameOther(hot_);
      return d_;
    }
    GeometricCandidates();
    VignettingCandidate();
    MeasuredFigures();
    for (const auto* c : {&hot_, &psf_}) {
      if (!c->tested) continue;
      d_.candidates.push_back(c->candidate);
      d_.candidates.back().significant = c->candidate.p_value < alpha_each_;
    }
    HeldOut chosen_ho;
    const FrameCandidate* chosen = ChooseCause(&chosen_ho);
    PlotResiduals(chosen);
    // `unexplained`: the residual of the fullest model of the vocabulary (every geometric cause, the
    // vignetting law), whatever was named: structure that no cause explains.
    d_.residual = discover_internal::TestFrameResidual(set_, camera_, fullest_.jac, fullest_.res, o_);
    if (chosen) NameCause(*chosen, chosen_ho);
    if (d_.residual.structured) {
      d_.partial_cause = d_.cause == "none" ? "" : d_.cause;
      d_.cause = "unexplained";
    }
    return d_;
  }

 private:
  struct Spec {
    std::string cause;
    CamMask mask;
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

  // Names a cause found without the geometric fits (hot_pixels, psf_shape).
  void NameOther(const discover_internal::CauseResult& c) {
    d_.cause = c.candidate.cause;
    d_.parameters = c.parameters;
    d_.sigmas = c.sigmas;
    d_.gain = c.gain;
    if (d_.cause == "hot_pixels") {
      d_.spikes_before = c.before, d_.spikes_after = c.after;
    } else {
      d_.stamp_rms_before = c.before, d_.stamp_rms_after = c.after;
    }
  }

  // The camera causes: each block of camera parameters fitted with every frame's rotation, its
  // chi-square against the base (camera as given) scaled by the fullest model's residual variance.
  void GeometricCandidates() {
    specs_ = {{"focal_length", {true, false, false, false, false, false, false, false}},
              {"principal_point", {false, true, true, false, false, false, false, false}},
              {"lens_distortion", {false, false, false, true, false, false, false, false}},
              {"pixel_aspect", {false, false, false, false, true, false, false, false}}};
    const bool ab = aberration_testable_;
    if (ab) specs_.push_back({"aberration", {false, false, false, false, false, true, true, true}});
    const std::vector<bool> all(nf_, true);
    base_ = FitGeometry(set_, camera_, all, kNoCam, nullptr, o_);
    fullest_ = FitGeometry(set_, camera_, all, {true, true, true, true, true, ab, ab, ab}, nullptr, o_);
    const int nobs = 2 * d_.stars;
    const int npar = 3 * nf_ + kCam;
    s2_ = fullest_.rss / std::max(1, nobs - npar);
    for (const auto& sp : specs_) {
      FrameCandidate c;
      c.cause = sp.cause;
      c.dof = static_cast<int>(std::count(sp.mask.begin(), sp.mask.end(), true));
      const GeoFit g = FitGeometry(set_, camera_, all, sp.mask, nullptr, o_);
      c.statistic = std::max(0.0, (base_.rss - g.rss) / s2_);
      c.p_value = ChiSq1or2Survival(c.statistic, c.dof);
      c.delta_bic = c.statistic - c.dof * std::log(static_cast<double>(nobs));
      c.significant = c.p_value < alpha_each_;
      fits_[sp.cause] = g;
      d_.candidates.push_back(c);
    }
  }

  // Vignetting: y = ln(flux) + 0.4 ln(10) V against u = (r / r_corner)^2.
  void VignettingCandidate() {
    for (const auto& s : set_.stars) {
      if (!(s.flux > 0)) continue;
      vu_.push_back(discover_internal::FieldRadius2(camera_, s.x_px, s.y_px));
      vy_.push_back(std::log(s.flux) + 0.4 * std::log(10.0) * s.mag);
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
      c.significant = c.p_value < alpha_each_;
    }
    d_.candidates.push_back(c);
    vig_v_ = vu_.size() >= 10 ? discover_internal::FitVignettingLaw(vu_, vy_, &vig_sigma_) : 0.0;
  }

  // Measured figures for the comparison with the simulator.
  void MeasuredFigures() {
    if (!vy_.empty()) {
      double m = 0, ss = 0;
      for (double v : vy_) m += v / vy_.size();
      for (double v : vy_) ss += (v - m) * (v - m);
      d_.zero_point_adu = std::exp(m);
      d_.photometric_scatter_mag = std::sqrt(ss / vy_.size()) * 2.5 / std::log(10.0);
    }
    std::vector<double> ps;
    for (const auto& s : set_.stars) {
      if (s.psf_sigma_px > 0) ps.push_back(s.psf_sigma_px);
    }
    d_.psf_sigma_median_px = Median(ps);
    d_.background_median_adu = Median(set_.background_adu);
    d_.noise_median_adu = Median(set_.noise_adu);
  }

  const Spec* SpecOf(const std::string& cause) const {
    for (const auto& sp : specs_) {
      if (sp.cause == cause) return &sp;
    }
    return nullptr;
  }

  // Geometric: the camera fitted on the even frames scored on the odd ones and vice versa (rotations
  // refitted there with the camera held); RMS in px, z over both folds.
  HeldOut GeometricHeldOut(const Spec& sp) {
    HeldOut h;
    if (nf_ < 2) {  // one frame: the fitted figures stand (no held-out frames)
      double sb = 0, sa = 0;
      for (int i = 0; i < d_.stars; ++i) {
        const double w = std::max(set_.stars[i].sigma_px, o_.min_sigma_px);
        sb += (std::pow(base_.res(2 * i), 2) + std::pow(base_.res(2 * i + 1), 2)) * w * w;
        sa += (std::pow(fits_[sp.cause].res(2 * i), 2) + std::pow(fits_[sp.cause].res(2 * i + 1), 2)) * w * w;
      }
      h.before = std::sqrt(sb / (2 * d_.stars)), h.after = std::sqrt(sa / (2 * d_.stars));
      h.gain = h.after > 0 ? h.before / h.after : 1.0;
      return h;
    }
    double ssb = 0, ssa = 0, ep = 0, pp = 0;
    int cnt = 0;
    const double zero[kCam] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (int fold = 0; fold < 2; ++fold) {
      std::vector<bool> train(nf_), test(nf_);
      for (int f = 0; f < nf_; ++f) train[f] = f % 2 == fold, test[f] = !train[f];
      const GeoFit gt = FitGeometry(set_, camera_, train, sp.mask, nullptr, o_);
      const VectorXd e = HeldOutResiduals(set_, camera_, test, zero, o_),
                     r = HeldOutResiduals(set_, camera_, test, gt.cam, o_);
      int k = 0;
      for (const auto& st : set_.stars) {
        if (!test[st.frame]) continue;
        const double w2 = std::pow(std::max(st.sigma_px, o_.min_sigma_px), 2);
        for (int c = 0; c < 2; ++c, ++k) ssb += e(k) * e(k) * w2, ssa += r(k) * r(k) * w2;
        cnt += 2;
      }
      ep += e.dot(e - r), pp += (e - r).squaredNorm();
    }
    if (cnt == 0) return h;
    h.before = std::sqrt(ssb / cnt), h.after = std::sqrt(ssa / cnt);
    h.gain = h.after > 0 ? h.before / h.after : 1.0;
    h.z = HeldOutZ(ep, pp, s2_), h.z_defined = true;
    return h;
  }

  // Vignetting: the slope fitted on the even frames scored on the odd ones and vice versa (mag).
  HeldOut VignettingHeldOut() const {
    const double to_mag = 2.5 / std::log(10.0);
    HeldOut h;
    double ssb = 0, ssa = 0, ep = 0, pp = 0;
    int n = 0;
    std::vector<int> frame_of;
    for (const auto& st : set_.stars) {
      if (st.flux > 0) frame_of.push_back(st.frame);
    }
    for (int fold = 0; fold < 2; ++fold) {
      double mu = 0, my = 0, cnt = 0;
      for (size_t i = 0; i < vu_.size(); ++i) {
        if (frame_of[i] % 2 == fold) mu += vu_[i], my += vy_[i], cnt += 1;
      }
      if (cnt < 3) continue;
      mu /= cnt, my /= cnt;
      double suu = 0, suy = 0;
      for (size_t i = 0; i < vu_.size(); ++i) {
        if (frame_of[i] % 2 == fold) suu += (vu_[i] - mu) * (vu_[i] - mu), suy += (vu_[i] - mu) * (vy_[i] - my);
      }
      const double b = suu > 0 ? suy / suu : 0.0;
      double yb = 0;
      for (size_t i = 0; i < vu_.size(); ++i) {
        if (frame_of[i] % 2 == fold) yb += vy_[i] - b * vu_[i];
      }
      yb /= cnt;
      for (size_t i = 0; i < vu_.size(); ++i) {
        if (frame_of[i] % 2 == fold) continue;
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

  // Physical bounds (docs/discrepancy.md): wide on purpose, they catch fits that explain noise or
  // each other, not unusual cameras. Empty when within them, else why not.
  std::string OutOfBounds(const std::string& cause) {
    if (cause == "vignetting") return vig_v_ >= 0 && vig_v_ <= 0.95 ? "" : "vignetting outside [0, 0.95]";
    if (cause == "hot_pixels")
      return hot_.parameters.count("hot_pixel_count") && hot_.parameters.at("hot_pixel_count") >= 1 ? "" : "no pixel";
    if (cause == "psf_shape") {
      const double sg = psf_.parameters.count("psf_sigma_px") ? psf_.parameters.at("psf_sigma_px") : 0;
      const double el = psf_.parameters.count("psf_ellipticity") ? psf_.parameters.at("psf_ellipticity") : 0;
      return sg >= 0.1 && sg <= 10 && el < 0.9 ? "" : "PSF sigma outside [0.1, 10] px or ellipticity >= 0.9";
    }
    const double* g = fits_[cause].cam;
    if (cause == "focal_length")
      return std::abs(g[0] / camera_.focal_length_px) <= 0.05 ? "" : "focal length off by > 5 %";
    if (cause == "principal_point")
      return std::abs(g[1]) <= 0.2 * camera_.width && std::abs(g[2]) <= 0.2 * camera_.height
                 ? ""
                 : "principal point moved by > 20 % of the frame";
    if (cause == "lens_distortion") {
      // k1 r^2 at the corner (normalised coordinates): the relative displacement there.
      const double rc2 =
          std::pow(std::max(camera_.cx_px, camera_.width - 1 - camera_.cx_px) / camera_.focal_length_px, 2) +
          std::pow(std::max(camera_.cy_px, camera_.height - 1 - camera_.cy_px) / camera_.FocalYPx(), 2);
      return std::abs((camera_.distortion.k1 + g[3]) * rc2) <= 0.3 ? "" : "k1 moves the corners by > 30 %";
    }
    if (cause == "pixel_aspect") return std::abs(g[4]) <= 0.05 ? "" : "aspect off by > 5 %";
    if (cause == "aberration")
      return Vec3(g[5], g[6], g[7]).norm() * kSpeedOfLightMS / 1000 <= 100 ? "" : "speed > 100 km/s";
    return "";
  }

  // Gates, in BIC order until one candidate passes: its parameters lie within the physical bounds and
  // its held-out improvement is significant (one-sided z above the normal quantile of gain_alpha).
  // Returns the named candidate (nullptr: none) and its held-out figures.
  const FrameCandidate* ChooseCause(HeldOut* chosen_ho) {
    d_.gain_z_min = boost::math::quantile(boost::math::complement(boost::math::normal(), o_.gain_alpha));
    std::vector<int> order;
    for (int i = 0; i < static_cast<int>(d_.candidates.size()); ++i) {
      if (d_.candidates[i].significant) order.push_back(i);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return d_.candidates[a].delta_bic > d_.candidates[b].delta_bic; });
    for (int i : order) {
      FrameCandidate& c = d_.candidates[i];
      c.evaluated = true;
      const std::string why = OutOfBounds(c.cause);
      if (!why.empty()) {
        c.verdict = "outside bounds: " + why;
        continue;
      }
      HeldOut h;
      if (const Spec* sp = SpecOf(c.cause)) {
        h = GeometricHeldOut(*sp);
      } else if (c.cause == "vignetting") {
        h = VignettingHeldOut();
      } else {  // hot_pixels, psf_shape: their own held-out figures (no z)
        const auto& r = c.cause == "hot_pixels" ? hot_ : psf_;
        h.before = r.before, h.after = r.after, h.gain = r.gain;
      }
      c.gain = h.gain, c.gain_z = h.z;
      if (!(h.gain > 1) || (h.z_defined && !(h.z > d_.gain_z_min))) {
        c.verdict = "held-out gain not significant";
        continue;
      }
      c.verdict = nf_ >= 2 || !SpecOf(c.cause) ? "named" : "named (one frame: gain on the fitted frame)";
      *chosen_ho = h;
      return &c;
    }
    return nullptr;
  }

  // Residuals before (base) and after (the named geometric cause) for the plot, and their RMS.
  void PlotResiduals(const FrameCandidate* chosen) {
    const GeoFit* after = &base_;
    if (chosen && fits_.count(chosen->cause)) after = &fits_[chosen->cause];
    for (int i = 0; i < d_.stars; ++i) {
      const auto& s = set_.stars[i];
      const double w = std::max(s.sigma_px, o_.min_sigma_px);
      d_.x_px.push_back(s.x_px);
      d_.y_px.push_back(s.y_px);
      d_.dx_before_px.push_back(base_.res(2 * i) * w);
      d_.dy_before_px.push_back(base_.res(2 * i + 1) * w);
      d_.dx_after_px.push_back(after->res(2 * i) * w);
      d_.dy_after_px.push_back(after->res(2 * i + 1) * w);
    }
    double ss = 0;
    for (size_t i = 0; i < d_.dx_before_px.size(); ++i) {
      ss += d_.dx_before_px[i] * d_.dx_before_px[i] + d_.dy_before_px[i] * d_.dy_before_px[i];
    }
    d_.residual_rms_before_arcsec = std::sqrt(ss / std::max<size_t>(1, 2 * d_.dx_before_px.size())) * ArcsecPerPx();
    d_.residual_rms_after_arcsec = d_.residual_rms_before_arcsec;
  }

  double ArcsecPerPx() const { return kRadToArcsec / camera_.FocalMeanPx(); }

  // The named cause's parameters, sigmas and held-out figures.
  void NameCause(const FrameCandidate& chosen, const HeldOut& ho) {
    d_.gain_z = ho.z;
    if (chosen.cause == "hot_pixels" || chosen.cause == "psf_shape") {
      NameOther(chosen.cause == "hot_pixels" ? hot_ : psf_);
      return;
    }
    d_.cause = chosen.cause;
    if (d_.cause == "vignetting") {
      d_.parameters["vignetting"] = vig_v_;
      d_.sigmas["vignetting"] = vig_sigma_;
      d_.flux_rms_before_mag = ho.before, d_.flux_rms_after_mag = ho.after;
      d_.gain = ho.gain;
      return;
    }
    const GeoFit& g = fits_[d_.cause];
    d_.fitted_camera = Apply(camera_, g.cam);
    const double sc = std::sqrt(s2_);
    std::vector<int> idx;
    for (int k = 0; k < kCam; ++k) {
      if (SpecOf(d_.cause)->mask[k]) idx.push_back(k);
    }
    // aberration: the uncorrected observer velocity v = b c (km/s, ICRS).
    constexpr double kc_kms = kSpeedOfLightMS / 1000;
    const char* names[kCam] = {"focal_length_px", "cx_px",          "cy_px",          "k1",
                               "pixel_aspect",    "velocity_x_kms", "velocity_y_kms", "velocity_z_kms"};
    // pixel_aspect is fy / fx: the nominal aspect times (1 + da).
    const double aspect0 = camera_.FocalYPx() / camera_.focal_length_px;
    const double nominal[kCam] = {
        camera_.focal_length_px, camera_.cx_px, camera_.cy_px, camera_.distortion.k1, aspect0, 0, 0, 0};
    const double unit[kCam] = {1, 1, 1, 1, aspect0, kc_kms, kc_kms, kc_kms};
    for (size_t k = 0; k < idx.size(); ++k) {
      d_.parameters[names[idx[k]]] = nominal[idx[k]] + unit[idx[k]] * g.cam[idx[k]];
      d_.sigmas[names[idx[k]]] = unit[idx[k]] * std::sqrt(g.cov_cam(k, k)) * sc;
    }
    if (d_.cause == "aberration") {
      d_.fitted_camera = camera_;  // not a camera property: the frames' time and velocity were not given
      d_.parameters["speed_kms"] = Vec3(g.cam[5], g.cam[6], g.cam[7]).norm() * kc_kms;
    }
    if (d_.cause == "pixel_aspect") {
      d_.parameters["focal_length_y_px"] = d_.fitted_camera.FocalYPx();
      d_.sigmas["focal_length_y_px"] = d_.sigmas["pixel_aspect"] * camera_.focal_length_px;
    }
    if (d_.cause == "focal_length") {
      d_.parameters["focal_length_ppm"] = g.cam[0] / camera_.focal_length_px * 1e6;
      d_.sigmas["focal_length_ppm"] = d_.sigmas["focal_length_px"] / camera_.focal_length_px * 1e6;
    }
    // Held-out RMS (even/odd frames); with a single frame, the fitted figures.
    d_.residual_rms_before_arcsec = ho.before * ArcsecPerPx();
    d_.residual_rms_after_arcsec = ho.after * ArcsecPerPx();
    d_.gain = ho.gain;
  }

  const SolvedFrameSet& set_;
  const Camera& camera_;
  const FrameDiscoverOptions& o_;
  const int nf_;
  FrameDiscovery d_;
  discover_internal::CauseResult hot_, psf_;
  bool aberration_testable_ = false;
  double alpha_each_ = 0;
  std::vector<Spec> specs_;
  GeoFit base_, fullest_;
  double s2_ = 0;  // residual variance of the fullest model (whitened units)
  std::map<std::string, GeoFit> fits_;
  std::vector<double> vu_, vy_;  // vignetting: squared field radius and flux-magnitude residual
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
  if (!(psf_width_floor_pct >= 0 && psf_width_floor_pct < 100)) Fail("psf_width_floor_pct must be in [0, 100)");
  if (!(psf_ellipticity_floor >= 0 && psf_ellipticity_floor < 1)) Fail("psf_ellipticity_floor must be in [0, 1)");
  if (!(gain_alpha > 0 && gain_alpha < 0.5)) Fail("gain_alpha must be in (0, 0.5)");
  if (!(residual_alpha > 0 && residual_alpha < 0.5)) Fail("residual_alpha must be in (0, 0.5)");
  if (residual_min_stars_per_cell < 3) Fail("residual_min_stars_per_cell must be >= 3");
}

SolvedFrameSet SolveFrameSet(const StarIdentifier& id, const std::vector<ImageView>& images,
                             const std::vector<std::string>& names, const Camera& camera, const SolveOptions& options,
                             const DefectMap* known_defects) {
  if (known_defects && !known_defects->empty() &&
      (known_defects->width != camera.width || known_defects->height != camera.height ||
       known_defects->mask.size() != static_cast<size_t>(camera.width) * camera.height)) {
    throw InputError("defect map", "size differs from the camera's width/height");
  }
  for (size_t i = 0; i < images.size(); ++i) {
    if (images[i].width != camera.width || images[i].height != camera.height) {
      throw InputError(i < names.size() ? names[i] : "frame", "frame size differs from the camera's width/height");
    }
  }
  SolvedFrameSet set;
  set.names = names;
  set.width = camera.width, set.height = camera.height;
  constexpr int kStampHalf = 5;  // 11 x 11: +-3 sigma of a 1.8 px PSF
  for (size_t i = 0; i < images.size(); ++i) {
    const ImageView& img = images[i];
    const SolveResult r = SolveFrame(id, img, camera, options, known_defects);
    set.status.push_back(r.status);
    std::vector<PixelSource> spikes;
    for (const auto& rej : r.detections.rejected) {
      if (rej.reason == RejectReason::kHotPixel) {
        spikes.push_back(
            {static_cast<int>(std::lround(rej.x_px)), static_cast<int>(std::lround(rej.y_px)), rej.flux_adu});
      }
    }
    set.spikes.push_back(spikes);
    if (r.status != SolveStatus::kSolved) continue;
    const int f = static_cast<int>(set.q.size());
    set.q.push_back(r.attitude.q_inertial_from_sensor);
    set.solved_index.push_back(static_cast<int>(i));
    set.background_adu.push_back(r.detections.background_adu);
    set.noise_adu.push_back(r.detections.noise_adu);
    const auto& dets = r.detections.stars;
    for (const auto& m : r.identification.matches) {
      FrameStar s;
      s.frame = f;
      s.x_px = m.x_px;
      s.y_px = m.y_px;
      s.mag = m.mag;
      s.r_inertial = m.r_inertial;
      s.noise_adu = r.detections.noise_adu;
      if (m.centroid >= 0 && m.centroid < static_cast<int>(r.centroids.size())) {
        s.flux = r.centroids[m.centroid].flux;
        s.sigma_px = r.centroids[m.centroid].sigma_px > 0 ? r.centroids[m.centroid].sigma_px : 0.1;
      }
      if (m.centroid >= 0 && m.centroid < static_cast<int>(dets.size())) {
        const StarDetection& det = dets[m.centroid];  // centroids are the detections in order
        s.psf_sigma_px = det.sigma_px;
        s.saturated = det.saturated;
        // Stamp for the PSF analysis: unsaturated, inside the image, no other source within it.
        const int cx = static_cast<int>(std::lround(det.x_px)), cy = static_cast<int>(std::lround(det.y_px));
        const int x0 = cx - kStampHalf, y0 = cy - kStampHalf, wd = 2 * kStampHalf + 1, guard = kStampHalf + 2;
        bool ok = !det.saturated && x0 >= 0 && y0 >= 0 && x0 + wd <= img.width && y0 + wd <= img.height;
        for (size_t k = 0; ok && k < dets.size(); ++k) {
          ok = static_cast<int>(k) == m.centroid || std::abs(dets[k].x_px - det.x_px) > guard ||
               std::abs(dets[k].y_px - det.y_px) > guard;
        }
        for (const auto& rej : r.detections.rejected) {
          if (ok && rej.reason != RejectReason::kHotPixel) {
            ok = std::abs(rej.x_px - det.x_px) > guard || std::abs(rej.y_px - det.y_px) > guard;
          }
        }
        if (ok) {
          s.stamp_x0 = x0, s.stamp_y0 = y0, s.stamp_half = kStampHalf;
          s.stamp.resize(static_cast<size_t>(wd) * wd);
          for (int y = 0; y < wd; ++y) {
            for (int x = 0; x < wd; ++x) {
              const bool bad = (known_defects && !known_defects->empty() && known_defects->at(x0 + x, y0 + y)) ||
                               std::any_of(spikes.begin(), spikes.end(),
                                           [&](const PixelSource& p) { return p.x == x0 + x && p.y == y0 + y; });
              s.stamp[static_cast<size_t>(y) * wd + x] =
                  bad ? std::numeric_limits<float>::quiet_NaN() : static_cast<float>(img.at(x0 + x, y0 + y));
            }
          }
        }
      }
      set.stars.push_back(s);
    }
  }
  return set;
}

FrameDiscovery DiscoverFrames(const SolvedFrameSet& set, const Camera& camera, const FrameDiscoverOptions& o) {
  o.Check();
  return FrameCauseSearch(set, camera, o).Run();
}

double discover_internal::FitVignettingLaw(const std::vector<double>& vu, const std::vector<double>& vy,
                                           double* sigma) {
  // y = c + ln(1 - v u) by a 1-D search over v (c is the mean for each v); sigma from the curvature of
  // the sum of squares with the residual scale.
  auto ss_of = [&](double v) {
    const int n = static_cast<int>(vu.size());
    double c = 0;
    for (int i = 0; i < n; ++i) c += (vy[i] - std::log(1 - v * vu[i])) / n;
    double ss = 0;
    for (int i = 0; i < n; ++i) ss += std::pow(vy[i] - c - std::log(1 - v * vu[i]), 2);
    return ss;
  };
  double lo = -1.0, hi = 0.95;
  for (int it = 0; it < 100; ++it) {  // golden section
    const double a = hi - 0.618 * (hi - lo), b = lo + 0.618 * (hi - lo);
    (ss_of(a) < ss_of(b) ? hi : lo) = ss_of(a) < ss_of(b) ? b : a;
  }
  const double v = 0.5 * (lo + hi), h = 1e-3;
  if (sigma) {
    const double curv = (ss_of(v + h) - 2 * ss_of(v) + ss_of(v - h)) / (h * h);
    const double s2v = ss_of(v) / std::max<size_t>(1, vu.size() - 2);
    *sigma = curv > 0 ? std::sqrt(2 * s2v / curv) : 1.0;
  }
  return v;
}

double discover_internal::FieldRadius2(const Camera& camera, double x_px, double y_px) {
  const double rc2 = std::pow(std::max(camera.cx_px, camera.width - 1 - camera.cx_px), 2) +
                     std::pow(std::max(camera.cy_px, camera.height - 1 - camera.cy_px), 2);
  return (std::pow(x_px - camera.cx_px, 2) + std::pow(y_px - camera.cy_px, 2)) / rc2;
}

Json FrameDiscoveryToJson(const FrameDiscovery& d) {
  Json j = discover_internal::DiscoveryVerdictJson(d.cause, d.parameters, d.sigmas, d.gain, d.gain_z, d.gain_z_min,
                                                   d.partial_cause);
  j["fitted_camera"] = CameraToJson(d.fitted_camera);
  j["residual_rms_before_arcsec"] = d.residual_rms_before_arcsec;
  j["residual_rms_after_arcsec"] = d.residual_rms_after_arcsec;
  {
    const FrameResidual& r = d.residual;
    Json rj = discover_internal::ResidualVerdictJson(r.structured, r.p_value, r.finding);
    rj.update(Json{{"position_rms_px", r.position_rms_px},
                   {"position_rms_arcsec", r.position_rms_arcsec},
                   {"position_max_px", r.position_max_px},
                   {"position_max_arcsec", r.position_max_arcsec},
                   {"position_max_at_px", {r.position_max_x_px, r.position_max_y_px}},
                   {"position_max_angle_deg", r.position_max_angle_deg},
                   {"position_per_mag_px", r.position_per_mag_px},
                   {"photometry_rms_mag", r.photometry_rms_mag},
                   {"photometry_max_mag", r.photometry_max_mag},
                   {"photometry_max_at_px", {r.photometry_max_x_px, r.photometry_max_y_px}},
                   {"photometry_per_mag", r.photometry_per_mag},
                   {"grid", r.grid},
                   {"worst_cell",
                    {{"centre_px", {r.cell_x_px, r.cell_y_px}},
                     {"stars", r.cell_stars},
                     {"mean_dx_px", r.cell_dx_px},
                     {"mean_dy_px", r.cell_dy_px},
                     {"chi2", r.cell_chi2}}}});
    rj["tests"] = Json::array();
    for (const auto& t : r.tests) {
      rj["tests"].push_back(
          {{"test", t.name}, {"f", t.f}, {"dof", t.dof}, {"dof_residual", t.dof_resid}, {"p_value", t.p_value}});
    }
    j["residual"] = rj;
  }
  j["gain_method"] = d.frames_solved >= 2 ? "held-out frames (even/odd)" : "fitted frame (one frame solved)";
  if (d.cause == "psf_shape") {
    j["gain_method"] = std::string(d.frames_solved >= 2 ? "held-out frames (even/odd)" : "fitted frame") +
                       ": stamp residual RMS in noise sigmas, model PSF vs fitted shape";
    j["stamp_rms_before"] = d.stamp_rms_before;
    j["stamp_rms_after"] = d.stamp_rms_after;
    j["fitted_camera"]["psf_sigma_px"] = d.parameters.at("psf_sigma_px");
    j["fitted_camera"]["psf_ellipticity"] = d.parameters.at("psf_ellipticity");
    j["fitted_camera"]["psf_angle_deg"] = d.parameters.at("psf_angle_deg");
  }
  if (d.cause == "hot_pixels") {
    j["gain_method"] =
        "held-out frames (even/odd): single-pixel spikes per frame, (before + 1) / (after + 1) after "
        "masking the pixels found on the other frames";
    j["spikes_per_frame_before"] = d.spikes_before;
    j["spikes_per_frame_after"] = d.spikes_after;
  }
  j["hot_pixels"] = Json::array();
  for (size_t i = 0; i < d.hot_pixels.size(); ++i) {
    j["hot_pixels"].push_back({{"x_px", d.hot_pixels[i].x},
                               {"y_px", d.hot_pixels[i].y},
                               {"excess_adu", d.hot_pixels[i].excess_adu},
                               {"frames", d.hot_pixel_frames[i]}});
  }
  if (d.cause == "hot_pixels") {
    j["fitted_camera"]["hot_pixels"] = Json::array();
    for (const auto& h : d.hot_pixels) j["fitted_camera"]["hot_pixels"].push_back({h.x, h.y});
  }
  if (d.cause == "vignetting") {
    j["flux_rms_before_mag"] = d.flux_rms_before_mag;
    j["flux_rms_after_mag"] = d.flux_rms_after_mag;
    j["fitted_camera"]["vignetting"] = d.parameters.at("vignetting");
  }
  j["measured"] = {{"zero_point_adu_v0", d.zero_point_adu},
                   {"photometric_scatter_mag", d.photometric_scatter_mag},
                   {"psf_sigma_median_px", d.psf_sigma_median_px},
                   {"psf_sigma_stamp_fit_px", d.psf_sigma_fit_px},
                   {"psf_e1", d.psf_e1},
                   {"psf_e2", d.psf_e2},
                   {"psf_stars", d.psf_stars},
                   {"background_median_adu", d.background_median_adu},
                   {"noise_median_adu", d.noise_median_adu}};
  j["frames"] = d.frames;
  j["frames_solved"] = d.frames_solved;
  j["stars"] = d.stars;
  j["candidates"] = Json::array();
  for (const auto& c : d.candidates) {
    Json cj = {{"cause", c.cause},
               {"statistic", c.statistic},
               {"p_value", c.p_value},
               {"delta_bic", c.delta_bic},
               {"significant", c.significant}};
    if (c.evaluated) {
      cj["gain"] = c.gain;
      cj["gain_z"] = c.gain_z;
      cj["verdict"] = c.verdict;
    }
    j["candidates"].push_back(cj);
  }
  j["not_tested"] = d.not_tested;
  return j;
}

}  // namespace ssiu
