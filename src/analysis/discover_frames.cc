#include "analysis/discover_frames.h"

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <limits>

#include "analysis/discover_frames_internal.h"
#include "core/astrometry.h"
#include "core/error.h"
#include "core/types.h"

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
  std::vector<double> rot;        // 3 per frame
  double cam[kCam] = {0, 0, 0, 0, 0, 0, 0, 0};
  double rss = 0;                 // weighted
  MatrixXd cov_cam;               // unscaled covariance of the active camera parameters
  VectorXd res;                   // 2 per star, measured - model over the centroid sigma
  MatrixXd jac;                   // d res / d parameters at the last iteration (rotations, then camera)
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
        spikes.push_back({static_cast<int>(std::lround(rej.x_px)), static_cast<int>(std::lround(rej.y_px)), rej.flux_adu});
      }
    }
    set.spikes.push_back(spikes);
    if (r.status != "solved") continue;
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
  FrameDiscovery d;
  d.frames = static_cast<int>(set.status.size());
  d.frames_solved = static_cast<int>(set.q.size());
  d.stars = static_cast<int>(set.stars.size());
  d.fitted_camera = camera;
  const int nf = d.frames_solved;
  const discover_internal::CauseResult hot = discover_internal::AnalyseHotPixels(set, o, &d);
  const discover_internal::CauseResult psf = discover_internal::AnalysePsfShape(set, camera, o, &d);
  if (!hot.tested) d.not_tested.push_back("hot_pixels");
  if (!psf.tested) d.not_tested.push_back("psf_shape");
  // aberration needs frames pointing in several directions (else it is a focal length): the
  // boresights' scatter matrix must have no small eigenvalue, and more frames than its 3 parameters
  // plus a focal length (with 3 frames it fits any per-frame scale).
  bool aberration_testable = false;
  if (set.q.size() >= 6) {
    Mat3 scatter = Mat3::Zero();
    for (const auto& q : set.q) scatter += (q * Vec3::UnitZ()) * (q * Vec3::UnitZ()).transpose() / set.q.size();
    aberration_testable = Eigen::SelfAdjointEigenSolver<Mat3>(scatter).eigenvalues().minCoeff() > 0.02;
  }
  if (!aberration_testable) d.not_tested.push_back("aberration");
  // Bonferroni over the candidates actually tested (5 geometric/photometric + these).
  const double alpha_each = o.alpha / (5 + aberration_testable + hot.tested + psf.tested);
  // Names a cause found without the geometric fits (hot_pixels, psf_shape).
  auto name_other = [&](const discover_internal::CauseResult& c) {
    d.cause = c.candidate.cause;
    d.parameters = c.parameters;
    d.sigmas = c.sigmas;
    d.gain = c.gain;
    if (d.cause == "hot_pixels") {
      d.spikes_before = c.before, d.spikes_after = c.after;
    } else {
      d.stamp_rms_before = c.before, d.stamp_rms_after = c.after;
    }
  };
  if (nf == 0 || d.stars < 10) {
    d.cause = "none";
    if (hot.tested && hot.candidate.p_value < alpha_each) name_other(hot);
    return d;
  }
  const std::vector<bool> all(nf, true);
  const double arcsec_per_px = kRadToArcsec / camera.FocalMeanPx();
  struct Spec {
    std::string cause;
    CamMask mask;
  };
  std::vector<Spec> specs = {{"focal_length", {true, false, false, false, false, false, false, false}},
                             {"principal_point", {false, true, true, false, false, false, false, false}},
                             {"lens_distortion", {false, false, false, true, false, false, false, false}},
                             {"pixel_aspect", {false, false, false, false, true, false, false, false}}};
  const bool ab = aberration_testable;
  if (ab) specs.push_back({"aberration", {false, false, false, false, false, true, true, true}});
  const GeoFit base = FitGeometry(set, camera, all, kNoCam, nullptr, o);
  const GeoFit fullest = FitGeometry(set, camera, all, {true, true, true, true, true, ab, ab, ab}, nullptr, o);
  const int nobs = 2 * d.stars;
  const int npar = 3 * nf + kCam;
  const double s2 = fullest.rss / std::max(1, nobs - npar);
  std::map<std::string, GeoFit> fits;
  for (const auto& sp : specs) {
    FrameCandidate c;
    c.cause = sp.cause;
    c.dof = static_cast<int>(std::count(sp.mask.begin(), sp.mask.end(), true));
    const GeoFit g = FitGeometry(set, camera, all, sp.mask, nullptr, o);
    c.statistic = std::max(0.0, (base.rss - g.rss) / s2);
    c.p_value = ChiSq1or2Survival(c.statistic, c.dof);
    c.delta_bic = c.statistic - c.dof * std::log(static_cast<double>(nobs));
    c.significant = c.p_value < alpha_each;
    fits[sp.cause] = g;
    d.candidates.push_back(c);
  }
  // Vignetting: y = ln(flux) + 0.4 ln(10) V against u = (r / r_corner)^2.
  double vig_slope = 0, vig_se = 0, vig_s = 0;
  std::vector<double> vu, vy;
  {
    for (const auto& s : set.stars) {
      if (!(s.flux > 0)) continue;
      vu.push_back(discover_internal::FieldRadius2(camera, s.x_px, s.y_px));
      vy.push_back(std::log(s.flux) + 0.4 * std::log(10.0) * s.mag);
    }
    FrameCandidate c;
    c.cause = "vignetting";
    c.dof = 1;
    const int n = static_cast<int>(vu.size());
    if (n >= 10) {
      double mu = 0, my = 0;
      for (int i = 0; i < n; ++i) mu += vu[i] / n, my += vy[i] / n;
      double suu = 0, suy = 0;
      for (int i = 0; i < n; ++i) suu += (vu[i] - mu) * (vu[i] - mu), suy += (vu[i] - mu) * (vy[i] - my);
      vig_slope = suy / suu;
      double ss = 0;
      for (int i = 0; i < n; ++i) ss += std::pow(vy[i] - my - vig_slope * (vu[i] - mu), 2);
      vig_s = std::sqrt(ss / (n - 2));
      vig_se = vig_s / std::sqrt(suu);
      c.statistic = std::pow(vig_slope / vig_se, 2);
      c.p_value = ChiSq1or2Survival(c.statistic, 1);
      c.delta_bic = c.statistic - std::log(static_cast<double>(n));
      c.significant = c.p_value < alpha_each;
    }
    d.candidates.push_back(c);
  }
  {  // measured figures for the comparison with the simulator
    auto median = [](std::vector<double> v) {
      if (v.empty()) return 0.0;
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      return v[v.size() / 2];
    };
    if (!vy.empty()) {
      double m = 0, ss = 0;
      for (double v : vy) m += v / vy.size();
      for (double v : vy) ss += (v - m) * (v - m);
      d.zero_point_adu = std::exp(m);
      d.photometric_scatter_mag = std::sqrt(ss / vy.size()) * 2.5 / std::log(10.0);
    }
    std::vector<double> ps;
    for (const auto& s : set.stars) {
      if (s.psf_sigma_px > 0) ps.push_back(s.psf_sigma_px);
    }
    d.psf_sigma_median_px = median(ps);
    d.background_median_adu = median(set.background_adu);
    d.noise_median_adu = median(set.noise_adu);
  }
  for (const auto* c : {&hot, &psf}) {
    if (!c->tested) continue;
    d.candidates.push_back(c->candidate);
    d.candidates.back().significant = c->candidate.p_value < alpha_each;
  }
  // Gates, in BIC order until one candidate passes: its parameters lie within the physical bounds
  // and its held-out improvement is significant (one-sided z above the normal quantile of gain_alpha).
  d.gain_z_min = boost::math::quantile(boost::math::complement(boost::math::normal(), o.gain_alpha));
  std::vector<int> order;
  for (int i = 0; i < static_cast<int>(d.candidates.size()); ++i) {
    if (d.candidates[i].significant) order.push_back(i);
  }
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return d.candidates[a].delta_bic > d.candidates[b].delta_bic; });
  const double sc2 = s2;  // residual variance of the fullest model (whitened units)
  auto spec_of = [&](const std::string& cause) -> const Spec* {
    for (const auto& sp : specs) {
      if (sp.cause == cause) return &sp;
    }
    return nullptr;
  };
  // Geometric: the camera fitted on the even frames scored on the odd ones and vice versa (rotations
  // refitted there with the camera held); RMS in px, z over both folds.
  auto geometric_held_out = [&](const Spec& sp) {
    HeldOut h;
    if (nf < 2) {  // one frame: the fitted figures stand (no held-out frames)
      double sb = 0, sa = 0;
      for (int i = 0; i < d.stars; ++i) {
        const double w = std::max(set.stars[i].sigma_px, o.min_sigma_px);
        sb += (std::pow(base.res(2 * i), 2) + std::pow(base.res(2 * i + 1), 2)) * w * w;
        sa += (std::pow(fits[sp.cause].res(2 * i), 2) + std::pow(fits[sp.cause].res(2 * i + 1), 2)) * w * w;
      }
      h.before = std::sqrt(sb / (2 * d.stars)), h.after = std::sqrt(sa / (2 * d.stars));
      h.gain = h.after > 0 ? h.before / h.after : 1.0;
      return h;
    }
    double ssb = 0, ssa = 0, ep = 0, pp = 0;
    int cnt = 0;
    const double zero[kCam] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (int fold = 0; fold < 2; ++fold) {
      std::vector<bool> train(nf), test(nf);
      for (int f = 0; f < nf; ++f) train[f] = f % 2 == fold, test[f] = !train[f];
      const GeoFit gt = FitGeometry(set, camera, train, sp.mask, nullptr, o);
      const VectorXd e = HeldOutResiduals(set, camera, test, zero, o), r = HeldOutResiduals(set, camera, test, gt.cam, o);
      int k = 0;
      for (const auto& st : set.stars) {
        if (!test[st.frame]) continue;
        const double w2 = std::pow(std::max(st.sigma_px, o.min_sigma_px), 2);
        for (int c = 0; c < 2; ++c, ++k) ssb += e(k) * e(k) * w2, ssa += r(k) * r(k) * w2;
        cnt += 2;
      }
      ep += e.dot(e - r), pp += (e - r).squaredNorm();
    }
    if (cnt == 0) return h;
    h.before = std::sqrt(ssb / cnt), h.after = std::sqrt(ssa / cnt);
    h.gain = h.after > 0 ? h.before / h.after : 1.0;
    h.z = HeldOutZ(ep, pp, sc2), h.z_defined = true;
    return h;
  };
  // Vignetting: the slope fitted on the even frames scored on the odd ones and vice versa (mag).
  const double to_mag = 2.5 / std::log(10.0);
  auto vignetting_held_out = [&] {
    HeldOut h;
    double ssb = 0, ssa = 0, ep = 0, pp = 0;
    int n = 0;
    std::vector<int> frame_of;
    for (const auto& st : set.stars) {
      if (st.flux > 0) frame_of.push_back(st.frame);
    }
    for (int fold = 0; fold < 2; ++fold) {
      double mu = 0, my = 0, cnt = 0;
      for (size_t i = 0; i < vu.size(); ++i) {
        if (frame_of[i] % 2 == fold) mu += vu[i], my += vy[i], cnt += 1;
      }
      if (cnt < 3) continue;
      mu /= cnt, my /= cnt;
      double suu = 0, suy = 0;
      for (size_t i = 0; i < vu.size(); ++i) {
        if (frame_of[i] % 2 == fold) suu += (vu[i] - mu) * (vu[i] - mu), suy += (vu[i] - mu) * (vy[i] - my);
      }
      const double b = suu > 0 ? suy / suu : 0.0;
      double yb = 0;
      for (size_t i = 0; i < vu.size(); ++i) {
        if (frame_of[i] % 2 == fold) yb += vy[i] - b * vu[i];
      }
      yb /= cnt;
      for (size_t i = 0; i < vu.size(); ++i) {
        if (frame_of[i] % 2 == fold) continue;
        const double e = vy[i] - my, r = vy[i] - yb - b * vu[i];
        ssb += e * e, ssa += r * r, ep += e * (e - r), pp += (e - r) * (e - r);
        ++n;
      }
    }
    if (n == 0) return h;
    h.before = std::sqrt(ssb / n) * to_mag, h.after = std::sqrt(ssa / n) * to_mag;
    h.gain = h.after > 0 ? h.before / h.after : 1.0;
    if (nf >= 2) h.z = HeldOutZ(ep, pp, vig_s * vig_s), h.z_defined = true;
    return h;
  };
  double vig_sigma = 0;
  const double vig_v = vu.size() >= 10 ? discover_internal::FitVignettingLaw(vu, vy, &vig_sigma) : 0.0;
  // Physical bounds (docs/discrepancy.md): wide on purpose, they catch fits that explain noise or
  // each other, not unusual cameras.
  auto out_of_bounds = [&](const std::string& cause) -> std::string {
    if (cause == "vignetting") return vig_v >= 0 && vig_v <= 0.95 ? "" : "vignetting outside [0, 0.95]";
    if (cause == "hot_pixels") return hot.parameters.count("hot_pixel_count") && hot.parameters.at("hot_pixel_count") >= 1 ? "" : "no pixel";
    if (cause == "psf_shape") {
      const double sg = psf.parameters.count("psf_sigma_px") ? psf.parameters.at("psf_sigma_px") : 0;
      const double el = psf.parameters.count("psf_ellipticity") ? psf.parameters.at("psf_ellipticity") : 0;
      return sg >= 0.1 && sg <= 10 && el < 0.9 ? "" : "PSF sigma outside [0.1, 10] px or ellipticity >= 0.9";
    }
    const double* g = fits[cause].cam;
    if (cause == "focal_length") return std::abs(g[0] / camera.focal_length_px) <= 0.05 ? "" : "focal length off by > 5 %";
    if (cause == "principal_point")
      return std::abs(g[1]) <= 0.2 * camera.width && std::abs(g[2]) <= 0.2 * camera.height
                 ? ""
                 : "principal point moved by > 20 % of the frame";
    if (cause == "lens_distortion") {
      // k1 r^2 at the corner (normalised coordinates): the relative displacement there.
      const double rc2 = std::pow(std::max(camera.cx_px, camera.width - 1 - camera.cx_px) / camera.focal_length_px, 2) +
                         std::pow(std::max(camera.cy_px, camera.height - 1 - camera.cy_px) / camera.FocalYPx(), 2);
      return std::abs((camera.distortion.k1 + g[3]) * rc2) <= 0.3 ? "" : "k1 moves the corners by > 30 %";
    }
    if (cause == "pixel_aspect") return std::abs(g[4]) <= 0.05 ? "" : "aspect off by > 5 %";
    if (cause == "aberration")
      return Vec3(g[5], g[6], g[7]).norm() * kSpeedOfLightMS / 1000 <= 100 ? "" : "speed > 100 km/s";
    return "";
  };
  const FrameCandidate* chosen = nullptr;
  HeldOut chosen_ho;
  for (int i : order) {
    FrameCandidate& c = d.candidates[i];
    c.evaluated = true;
    const std::string why = out_of_bounds(c.cause);
    if (!why.empty()) {
      c.verdict = "outside bounds: " + why;
      continue;
    }
    HeldOut h;
    if (const Spec* sp = spec_of(c.cause)) {
      h = geometric_held_out(*sp);
    } else if (c.cause == "vignetting") {
      h = vignetting_held_out();
    } else {  // hot_pixels, psf_shape: their own held-out figures (no z)
      const auto& r = c.cause == "hot_pixels" ? hot : psf;
      h.before = r.before, h.after = r.after, h.gain = r.gain;
    }
    c.gain = h.gain, c.gain_z = h.z;
    if (!(h.gain > 1) || (h.z_defined && !(h.z > d.gain_z_min))) {
      c.verdict = "held-out gain not significant";
      continue;
    }
    c.verdict = nf >= 2 || !spec_of(c.cause) ? "named" : "named (one frame: gain on the fitted frame)";
    chosen = &c;
    chosen_ho = h;
    break;
  }
  // Residuals before (base) and after (the named geometric cause) for the plot.
  const GeoFit* after = &base;
  if (chosen && fits.count(chosen->cause)) after = &fits[chosen->cause];
  for (int i = 0; i < d.stars; ++i) {
    const auto& s = set.stars[i];
    const double w = std::max(s.sigma_px, o.min_sigma_px);
    d.x_px.push_back(s.x_px);
    d.y_px.push_back(s.y_px);
    d.dx_before_px.push_back(base.res(2 * i) * w);
    d.dy_before_px.push_back(base.res(2 * i + 1) * w);
    d.dx_after_px.push_back(after->res(2 * i) * w);
    d.dy_after_px.push_back(after->res(2 * i + 1) * w);
  }
  auto rms_of = [&](const std::vector<double>& a, const std::vector<double>& b) {
    double ss = 0;
    for (size_t i = 0; i < a.size(); ++i) ss += a[i] * a[i] + b[i] * b[i];
    return std::sqrt(ss / std::max<size_t>(1, 2 * a.size())) * arcsec_per_px;
  };
  d.residual_rms_before_arcsec = rms_of(d.dx_before_px, d.dy_before_px);
  d.residual_rms_after_arcsec = d.residual_rms_before_arcsec;
  // `unexplained`: the residual of the fullest model of the vocabulary (every geometric cause, the
  // vignetting law), whatever was named: structure that no cause explains.
  d.residual = discover_internal::TestFrameResidual(set, camera, fullest.jac, fullest.res, o);
  auto finish = [&] {
    if (d.residual.structured) {
      d.partial_cause = d.cause == "none" ? "" : d.cause;
      d.cause = "unexplained";
    }
    return d;
  };
  if (!chosen) return finish();
  d.gain_z = chosen_ho.z;
  if (chosen->cause == "hot_pixels" || chosen->cause == "psf_shape") {
    name_other(chosen->cause == "hot_pixels" ? hot : psf);
    return finish();
  }
  d.cause = chosen->cause;
  if (d.cause == "vignetting") {
    d.parameters["vignetting"] = vig_v;
    d.sigmas["vignetting"] = vig_sigma;
    d.flux_rms_before_mag = chosen_ho.before, d.flux_rms_after_mag = chosen_ho.after;
    d.gain = chosen_ho.gain;
    return finish();
  }
  const GeoFit& g = fits[d.cause];
  d.fitted_camera = Apply(camera, g.cam);
  const double sc = std::sqrt(s2);
  std::vector<int> idx;
  for (int k = 0; k < kCam; ++k) {
    if (spec_of(d.cause)->mask[k]) idx.push_back(k);
  }
  // aberration: the uncorrected observer velocity v = b c (km/s, ICRS).
  constexpr double kc_kms = kSpeedOfLightMS / 1000;
  const char* names[kCam] = {"focal_length_px", "cx_px", "cy_px", "k1", "pixel_aspect",
                             "velocity_x_kms", "velocity_y_kms", "velocity_z_kms"};
  // pixel_aspect is fy / fx: the nominal aspect times (1 + da).
  const double aspect0 = camera.FocalYPx() / camera.focal_length_px;
  const double nominal[kCam] = {camera.focal_length_px, camera.cx_px, camera.cy_px, camera.distortion.k1, aspect0, 0, 0, 0};
  const double unit[kCam] = {1, 1, 1, 1, aspect0, kc_kms, kc_kms, kc_kms};
  for (size_t k = 0; k < idx.size(); ++k) {
    d.parameters[names[idx[k]]] = nominal[idx[k]] + unit[idx[k]] * g.cam[idx[k]];
    d.sigmas[names[idx[k]]] = unit[idx[k]] * std::sqrt(g.cov_cam(k, k)) * sc;
  }
  if (d.cause == "aberration") {
    d.fitted_camera = camera;  // not a camera property: the frames' time and velocity were not given
    d.parameters["speed_kms"] = Vec3(g.cam[5], g.cam[6], g.cam[7]).norm() * kc_kms;
  }
  if (d.cause == "pixel_aspect") {
    d.parameters["focal_length_y_px"] = d.fitted_camera.FocalYPx();
    d.sigmas["focal_length_y_px"] = d.sigmas["pixel_aspect"] * camera.focal_length_px;
  }
  if (d.cause == "focal_length") {
    d.parameters["focal_length_ppm"] = g.cam[0] / camera.focal_length_px * 1e6;
    d.sigmas["focal_length_ppm"] = d.sigmas["focal_length_px"] / camera.focal_length_px * 1e6;
  }
  // Held-out RMS (even/odd frames); with a single frame, the fitted figures.
  d.residual_rms_before_arcsec = chosen_ho.before * arcsec_per_px;
  d.residual_rms_after_arcsec = chosen_ho.after * arcsec_per_px;
  d.gain = chosen_ho.gain;
  return finish();
}

double discover_internal::FitVignettingLaw(const std::vector<double>& vu, const std::vector<double>& vy, double* sigma) {
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
  Json j;
  j["cause"] = d.cause;
  j["parameters"] = Json::object();
  for (const auto& [k, v] : d.parameters) j["parameters"][k] = v;
  j["parameter_sigmas"] = Json::object();
  for (const auto& [k, v] : d.sigmas) j["parameter_sigmas"][k] = v;
  j["fitted_camera"] = CameraToJson(d.fitted_camera);
  j["residual_rms_before_arcsec"] = d.residual_rms_before_arcsec;
  j["residual_rms_after_arcsec"] = d.residual_rms_after_arcsec;
  j["gain"] = d.gain;
  j["gain_z"] = d.gain_z;
  j["gain_z_min"] = d.gain_z_min;
  if (!d.partial_cause.empty()) j["partial_cause"] = d.partial_cause;
  {
    const FrameResidual& r = d.residual;
    Json rj = {{"structured", r.structured},
               {"p_value", r.p_value},
               {"finding", r.finding},
               {"position_rms_px", r.position_rms_px},
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
               {"worst_cell", {{"centre_px", {r.cell_x_px, r.cell_y_px}},
                               {"stars", r.cell_stars},
                               {"mean_dx_px", r.cell_dx_px},
                               {"mean_dy_px", r.cell_dy_px},
                               {"chi2", r.cell_chi2}}}};
    rj["tests"] = Json::array();
    for (const auto& t : r.tests) {
      rj["tests"].push_back({{"test", t.name}, {"f", t.f}, {"dof", t.dof}, {"dof_residual", t.dof_resid}, {"p_value", t.p_value}});
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
    j["gain_method"] = "held-out frames (even/odd): single-pixel spikes per frame, (before + 1) / (after + 1) after "
                       "masking the pixels found on the other frames";
    j["spikes_per_frame_before"] = d.spikes_before;
    j["spikes_per_frame_after"] = d.spikes_after;
  }
  j["hot_pixels"] = Json::array();
  for (size_t i = 0; i < d.hot_pixels.size(); ++i) {
    j["hot_pixels"].push_back(
        {{"x_px", d.hot_pixels[i].x}, {"y_px", d.hot_pixels[i].y}, {"excess_adu", d.hot_pixels[i].excess_adu},
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
