#include "attitude/calibrate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <set>

#include "core/attitude.h"
#include "core/error.h"

namespace ssiu {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

// Camera parameters of the fit, in this order.
constexpr int kCam = 8;
const char* const kNames[kCam] = {"fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "p1", "p2"};
using CamMask = std::array<bool, kCam>;

std::array<double, kCam> CamVector(const Camera& c) {
  const Distortion& d = c.distortion;
  return {c.focal_length_px, c.FocalYPx(), c.cx_px, c.cy_px, d.k1, d.k2, d.p1, d.p2};
}

Camera CamFromVector(Camera c, const std::array<double, kCam>& v) {
  c.focal_length_px = v[0];
  c.focal_length_y_px = v[1];
  c.cx_px = v[2], c.cy_px = v[3];
  c.distortion.k1 = v[4], c.distortion.k2 = v[5], c.distortion.p1 = v[6], c.distortion.p2 = v[7];
  return c;
}

Mat3 Exp(const Vec3& w) {
  const double a = w.norm();
  return a < 1e-300 ? Mat3::Identity() : Mat3(Eigen::AngleAxisd(a, w / a));
}

struct Obs {
  int frame = 0;  // index into the fit's frames
  Vec2 px;
  Vec3 r_inertial;
  double sigma_px = 0.3;
};

struct Fit {
  Camera cam;
  std::vector<Mat3> rot;  // inertial from sensor, per frame
  MatrixXd cam_cov;       // of the free camera parameters (in mask order), scaled by max(1, chi2/dof)
  std::vector<int> free_index;
  double chi2 = 0;
  int dof = 0;
  double rms_px = 0;
  std::vector<double> frame_rms_px;
  std::vector<char> used;  // per observation: not an outlier
};

bool Residual(const Camera& cam, const Mat3& rot, const Obs& o, Vec2* r) {
  const auto p = cam.Project(rot.transpose() * o.r_inertial);
  if (!p) return false;
  *r = *p - o.px;
  return true;
}

// Levenberg-Marquardt over the free camera parameters and every frame's rotation (right
// perturbation R Exp(dtheta)); numerical Jacobians. Observations with used[i] == 0 are left out.
void Solve(const std::vector<Obs>& obs, const CamMask& mask, int n_frames, Fit* f) {
  std::vector<int> fi;
  for (int k = 0; k < kCam; ++k)
    if (mask[k]) fi.push_back(k);
  const int nc = static_cast<int>(fi.size()), n = nc + 3 * n_frames;
  const std::array<double, kCam> step = {
      1e-4 * f->cam.focal_length_px, 1e-4 * f->cam.FocalYPx(), 1e-3, 1e-3, 1e-6, 1e-6, 1e-6, 1e-6};
  auto cost = [&](const Camera& cam, const std::vector<Mat3>& rot) {
    double c = 0;
    for (size_t i = 0; i < obs.size(); ++i) {
      if (!f->used[i]) continue;
      Vec2 r;
      c += Residual(cam, rot[obs[i].frame], obs[i], &r) ? r.squaredNorm() / (obs[i].sigma_px * obs[i].sigma_px) : 1e6;
    }
    return c;
  };
  double lambda = 1e-3;
  MatrixXd h(n, n);
  VectorXd g(n);
  double c0 = cost(f->cam, f->rot);
  for (int iter = 0; iter < 60; ++iter) {
    h.setZero();
    g.setZero();
    const auto v0 = CamVector(f->cam);
    for (size_t i = 0; i < obs.size(); ++i) {
      if (!f->used[i]) continue;
      const Obs& o = obs[i];
      Vec2 r0;
      if (!Residual(f->cam, f->rot[o.frame], o, &r0)) continue;
      Eigen::Matrix<double, 2, Eigen::Dynamic> j(2, nc + 3);
      for (int a = 0; a < nc; ++a) {
        auto vp = v0, vm = v0;
        vp[fi[a]] += step[fi[a]], vm[fi[a]] -= step[fi[a]];
        Vec2 rp, rm;
        Residual(CamFromVector(f->cam, vp), f->rot[o.frame], o, &rp);
        Residual(CamFromVector(f->cam, vm), f->rot[o.frame], o, &rm);
        j.col(a) = (rp - rm) / (2 * step[fi[a]]);
      }
      for (int a = 0; a < 3; ++a) {
        Vec3 d = Vec3::Zero();
        d[a] = 1e-7;
        Vec2 rp, rm;
        Residual(f->cam, f->rot[o.frame] * Exp(d), o, &rp);
        Residual(f->cam, f->rot[o.frame] * Exp(-d), o, &rm);
        j.col(nc + a) = (rp - rm) / 2e-7;
      }
      const double w = 1.0 / (o.sigma_px * o.sigma_px);
      const int fo = nc + 3 * o.frame;
      const MatrixXd jc = j.leftCols(nc), jr = j.rightCols(3);
      h.topLeftCorner(nc, nc) += w * jc.transpose() * jc;
      h.block(0, fo, nc, 3) += w * jc.transpose() * jr;
      h.block(fo, 0, 3, nc) += w * jr.transpose() * jc;
      h.block(fo, fo, 3, 3) += w * jr.transpose() * jr;
      g.head(nc) += w * jc.transpose() * r0;
      g.segment(fo, 3) += w * jr.transpose() * r0;
    }
    bool improved = false;
    for (int tries = 0; tries < 10 && !improved; ++tries) {
      MatrixXd hd = h;
      for (int k = 0; k < n; ++k) hd(k, k) += lambda * std::max(h(k, k), 1e-12);
      const VectorXd dx = -hd.ldlt().solve(g);
      if (!dx.allFinite()) {
        lambda *= 10;
        continue;
      }
      auto v1 = v0;
      for (int a = 0; a < nc; ++a) v1[fi[a]] += dx[a];
      Camera cam1 = CamFromVector(f->cam, v1);
      std::vector<Mat3> rot1 = f->rot;
      for (int k = 0; k < n_frames; ++k) rot1[k] = f->rot[k] * Exp(dx.segment<3>(nc + 3 * k));
      const double c1 = cost(cam1, rot1);
      if (c1 <= c0) {
        improved = true;
        const bool done = c0 - c1 < 1e-10 * std::max(1.0, c0);
        f->cam = cam1, f->rot = rot1, c0 = c1;
        lambda = std::max(1e-9, lambda / 10);
        if (done) iter = 1000;
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
  }
  // Statistics and the covariance of the camera block (Schur complement = the top-left block of H^-1).
  int m = 0;
  double ss = 0;
  std::vector<double> fss(n_frames, 0.0);
  std::vector<int> fn(n_frames, 0);
  f->chi2 = 0;
  for (size_t i = 0; i < obs.size(); ++i) {
    if (!f->used[i]) continue;
    Vec2 r;
    if (!Residual(f->cam, f->rot[obs[i].frame], obs[i], &r)) continue;
    ++m;
    ss += r.squaredNorm();
    fss[obs[i].frame] += r.squaredNorm();
    ++fn[obs[i].frame];
    f->chi2 += r.squaredNorm() / (obs[i].sigma_px * obs[i].sigma_px);
  }
  f->dof = std::max(1, 2 * m - n);
  f->rms_px = m ? std::sqrt(ss / (2 * m)) : 0;
  f->frame_rms_px.assign(n_frames, 0.0);
  for (int k = 0; k < n_frames; ++k) f->frame_rms_px[k] = fn[k] ? std::sqrt(fss[k] / (2 * fn[k])) : 0;
  f->free_index = fi;
  if (nc > 0) {
    const MatrixXd hinv = h.ldlt().solve(MatrixXd::Identity(n, n));
    f->cam_cov = hinv.topLeftCorner(nc, nc) * std::max(1.0, f->chi2 / f->dof);
  } else {
    f->cam_cov.resize(0, 0);
  }
}

// Solve, then leave out the outliers (relative to the fit's own scatter) and solve again.
Fit FitAll(const Camera& cam0, const std::vector<Mat3>& rot0, const std::vector<Obs>& obs, const CamMask& mask,
           int n_frames, double outlier_sigmas) {
  Fit f;
  f.cam = cam0;
  f.rot = rot0;
  f.used.assign(obs.size(), 1);
  Solve(obs, mask, n_frames, &f);
  for (int pass = 0; pass < 2; ++pass) {
    const double scale = std::sqrt(std::max(1.0, f.chi2 / f.dof));
    int dropped = 0;
    for (size_t i = 0; i < obs.size(); ++i) {
      Vec2 r;
      const bool ok =
          Residual(f.cam, f.rot[obs[i].frame], obs[i], &r) && r.norm() / obs[i].sigma_px <= outlier_sigmas * scale;
      if (f.used[i] && !ok) ++dropped;
      f.used[i] = ok;
    }
    if (dropped == 0) break;
    Solve(obs, mask, n_frames, &f);
  }
  return f;
}

double SigmaOf(const Fit& f, int k) {
  for (size_t a = 0; a < f.free_index.size(); ++a)
    if (f.free_index[a] == k) return std::sqrt(f.cam_cov(a, a));
  return 0;
}

struct SolvedSet {
  std::vector<int> frame;  // index into the input frames, per solved frame
  std::vector<SolveResult> results;
  int solved = 0;
};

SolvedSet SolveAll(const StarIdentifier& id, const std::vector<CalibrationFrame>& frames, const Camera& cam,
                   const CalibrateOptions& o, double tol_pct) {
  SolveOptions so = o.solve;
  so.identify.fov_tolerance_pct = tol_pct;
  so.identify.refine_focal_p = 0;  // the calibration fits the focal length over all frames jointly
  SolvedSet s;
  for (size_t i = 0; i < frames.size(); ++i) {
    SolveResult r = SolveCentroids(id, frames[i].centroids, cam, so);
    s.results.push_back(r);
    if (r.status == SolveStatus::kSolved) ++s.solved;
  }
  return s;
}

// The matches of the solved frames as observations; rot0 their attitudes.
std::vector<Obs> Observations(const std::vector<CalibrationFrame>& frames, const SolvedSet& s,
                              const CalibrateOptions& o, const std::vector<char>& include, std::vector<int>* fit_frame,
                              std::vector<Mat3>* rot0) {
  std::vector<Obs> obs;
  fit_frame->clear();
  rot0->clear();
  for (size_t i = 0; i < frames.size(); ++i) {
    const SolveResult& r = s.results[i];
    if (r.status != SolveStatus::kSolved || !include[i]) continue;
    const int k = static_cast<int>(fit_frame->size());
    fit_frame->push_back(static_cast<int>(i));
    rot0->push_back(r.attitude.q_inertial_from_sensor.toRotationMatrix());
    for (const auto& m : r.identification.matches) {
      Obs ob;
      ob.frame = k;
      ob.px = Vec2(m.x_px, m.y_px);
      ob.r_inertial = m.r_inertial;
      const double sc = frames[i].centroids[m.centroid].sigma_px;
      ob.sigma_px = sc > 0 ? sc : o.solve.identify.centroid_sigma_px;
      obs.push_back(ob);
    }
  }
  return obs;
}

// The full model with parameters dropped by observability and significance.
Fit SelectAndFit(const Camera& cam0, const std::vector<Mat3>& rot0, const std::vector<Obs>& obs, int n_frames,
                 const CalibrateOptions& o, std::vector<std::string>* unobservable, std::vector<std::string>* dropped,
                 CamMask* mask_out) {
  CamMask mask;
  mask.fill(true);
  Fit f = FitAll(cam0, rot0, obs, mask, n_frames, o.outlier_sigmas);
  auto hold = [&](std::initializer_list<int> ks) {
    auto v = CamVector(f.cam);
    const auto g = CamVector(cam0);
    for (int k : ks) mask[k] = false, v[k] = g[k];
    f.cam = CamFromVector(f.cam, v);
  };
  char buf[200];
  const double spp = std::max(SigmaOf(f, 2), SigmaOf(f, 3));
  if (!(spp <= o.max_principal_point_sigma_px)) {
    std::snprintf(buf, sizeof buf,
                  "principal_point: sigma %.3g px > %.3g px (degenerate with the frames' attitudes for this field); "
                  "held at the guess",
                  spp, o.max_principal_point_sigma_px);
    unobservable->push_back(buf);
    hold({2, 3});
    f = FitAll(f.cam, f.rot, obs, mask, n_frames, o.outlier_sigmas);
  }
  for (int k : {0, 1}) {
    const double s = SigmaOf(f, k) / CamVector(f.cam)[k] * 100;
    if (!(s <= o.max_focal_sigma_pct)) {
      std::snprintf(buf, sizeof buf, "%s: sigma %.3g %% > %.3g %%; held at the guess", kNames[k], s,
                    o.max_focal_sigma_pct);
      unobservable->push_back(buf);
      hold({k});
      f = FitAll(f.cam, f.rot, obs, mask, n_frames, o.outlier_sigmas);
    }
  }
  // Backward elimination of the distortion terms: the least significant first.
  auto eliminate = [&] {
    for (;;) {
      int worst = -1;
      double worst_z = o.significance_sigmas;
      for (int k = 4; k < kCam; ++k) {
        if (!mask[k]) continue;
        const double s = SigmaOf(f, k), z = s > 0 ? std::abs(CamVector(f.cam)[k]) / s : 0;
        if (z < worst_z) worst = k, worst_z = z;
      }
      if (worst < 0) break;
      std::snprintf(buf, sizeof buf, "%s (%.2f sigma)", kNames[worst], worst_z);
      dropped->push_back(buf);
      hold({worst});
      f = FitAll(f.cam, f.rot, obs, mask, n_frames, o.outlier_sigmas);
    }
  };
  eliminate();
  // A principal point not significantly off the guess is held there (every attitude moves with it:
  // a fitted but insignificant offset only adds its noise to the solutions' boresights).
  if (mask[2] && mask[3]) {
    const auto v = CamVector(f.cam), g = CamVector(cam0);
    const double z = std::max(std::abs(v[2] - g[2]) / SigmaOf(f, 2), std::abs(v[3] - g[3]) / SigmaOf(f, 3));
    if (z < o.significance_sigmas) {
      std::snprintf(buf, sizeof buf, "principal_point (%.2f sigma)", z);
      dropped->push_back(buf);
      hold({2, 3});
      f = FitAll(f.cam, f.rot, obs, mask, n_frames, o.outlier_sigmas);
      eliminate();  // without the principal point, a distortion term may now tell
    }
  }
  *mask_out = mask;
  return f;
}

double RmsOf(const std::vector<double>& ss, const std::vector<int>& n) {
  double s = 0;
  int m = 0;
  for (size_t i = 0; i < ss.size(); ++i) s += ss[i], m += n[i];
  return m ? std::sqrt(s / (2 * m)) : 0;
}

}  // namespace

void CalibrateOptions::Check() const {
  auto bad = [](const std::string& f, const std::string& w) { throw InputError("calibrate options", f + " " + w); };
  if (!(fov_tolerance_pct >= 0 && fov_tolerance_pct <= 30)) bad("fov_tolerance_pct", "must be in [0, 30]");
  if (rounds < 1 || rounds > 10) bad("rounds", "must be in [1, 10]");
  if (!(significance_sigmas > 0 && significance_sigmas < 100)) bad("significance_sigmas", "must be in (0, 100)");
  if (!(outlier_sigmas >= 2 && outlier_sigmas < 100)) bad("outlier_sigmas", "must be in [2, 100)");
  if (holdout_every < 0 || holdout_every == 1) bad("holdout_every", "must be 0 or >= 2");
  if (!(max_principal_point_sigma_px > 0)) bad("max_principal_point_sigma_px", "must be > 0");
  if (!(max_focal_sigma_pct > 0)) bad("max_focal_sigma_pct", "must be > 0");
  solve.Check();
}

CameraCalibration CalibrateCamera(const StarIdentifier& id, const std::vector<CalibrationFrame>& frames,
                                  const Camera& guess, const CalibrateOptions& o) {
  o.Check();
  guess.Check("camera guess");
  CameraCalibration out;
  out.guess = guess;
  out.camera = guess;
  const int nf = static_cast<int>(frames.size());
  // Round 0: the guess (and, when it solves too little, its aspect alternatives).
  SolvedSet s = SolveAll(id, frames, guess, o, o.fov_tolerance_pct);
  if (o.try_aspects && 2 * s.solved < nf) {
    for (double aspect : {1.0, 0.5, 2.0}) {
      Camera alt = guess;
      alt.focal_length_y_px = guess.focal_length_px * aspect;
      if (std::abs(alt.FocalYPx() - guess.FocalYPx()) < 1e-6 * guess.FocalYPx()) continue;
      try {
        alt.Check();
      } catch (const InputError&) {
        continue;
      }
      SolvedSet sa = SolveAll(id, frames, alt, o, o.fov_tolerance_pct);
      if (sa.solved > s.solved) s = std::move(sa), out.guess = alt;
    }
  }
  Camera cam = out.guess;
  const std::vector<char> all(nf, 1);
  std::vector<int> fit_frame;
  std::vector<Mat3> rot0;
  std::vector<Obs> obs;
  Fit fit;
  CamMask mask{};
  bool fitted = false;
  for (int round = 0; round < o.rounds; ++round) {
    if (round > 0) s = SolveAll(id, frames, cam, o, std::min(1.0, o.fov_tolerance_pct));
    obs = Observations(frames, s, o, all, &fit_frame, &rot0);
    if (s.solved < 2 || static_cast<int>(obs.size()) < 3 * kCam) break;
    out.unobservable.clear();
    out.dropped.clear();
    fit = SelectAndFit(out.guess, rot0, obs, static_cast<int>(fit_frame.size()), o, &out.unobservable, &out.dropped,
                       &mask);
    cam = fit.cam;
    fitted = true;
  }
  if (!fitted) {
    out.message = std::to_string(s.solved) + " of " + std::to_string(nf) +
                  " frames solved with the guess: too few to fit (need 2 with 24 matched stars in all)";
    for (int i = 0; i < nf; ++i) {  // the guess's solutions (head alignment can still use them)
      CalibratedFrame cf;
      cf.name = frames[i].name;
      cf.status = s.results[i].status;
      if (cf.status == SolveStatus::kSolved) {
        cf.q_inertial_from_sensor = s.results[i].attitude.q_inertial_from_sensor;
        cf.covariance_rad2 = s.results[i].attitude.covariance_rad2;
        cf.matches = static_cast<int>(s.results[i].identification.matches.size());
      }
      out.frames.push_back(cf);
    }
    return out;
  }
  out.status = CalibrationStatus::kCalibrated;
  out.camera = cam;
  out.camera.Check("fitted camera");
  for (size_t a = 0; a < fit.free_index.size(); ++a) out.parameters.push_back(kNames[fit.free_index[a]]);
  out.covariance = fit.cam_cov;
  const auto v = CamVector(cam);
  for (int k = 0; k < kCam; ++k) {
    out.value[kNames[k]] = v[k];
    out.sigma[kNames[k]] = SigmaOf(fit, k);
  }
  out.reduced_chi2 = fit.chi2 / fit.dof;
  out.rms_px = fit.rms_px;
  out.stars_used = static_cast<int>(std::count(fit.used.begin(), fit.used.end(), 1));

  // Held-out frames: the camera fitted without them, their attitudes fitted alone with it and with the guess.
  if (o.holdout_every >= 2 && fit_frame.size() >= static_cast<size_t>(2 * o.holdout_every)) {
    std::vector<char> train(nf, 0), test(nf, 0);
    for (size_t k = 0; k < fit_frame.size(); ++k)
      (k % o.holdout_every == static_cast<size_t>(o.holdout_every - 1) ? test : train)[fit_frame[k]] = 1;
    std::vector<int> tf;
    std::vector<Mat3> tr;
    const std::vector<Obs> tobs = Observations(frames, s, o, train, &tf, &tr);
    Fit ft = FitAll(cam, tr, tobs, mask, static_cast<int>(tf.size()), o.outlier_sigmas);
    std::vector<double> ss_before, ss_after;
    std::vector<int> nb, na;
    CamMask none{};
    for (int i = 0; i < nf; ++i) {
      if (!test[i]) continue;
      std::vector<char> one(nf, 0);
      one[i] = 1;
      std::vector<int> of;
      std::vector<Mat3> orot;
      const std::vector<Obs> oobs = Observations(frames, s, o, one, &of, &orot);
      for (int which = 0; which < 2; ++which) {
        const Fit fo = FitAll(which ? ft.cam : out.guess, orot, oobs, none, 1, o.outlier_sigmas);
        // RMS over all the frame's matches (no outlier rejection: a bad camera is not excused).
        double ss = 0;
        int m = 0;
        for (const auto& ob : oobs) {
          Vec2 r;
          if (Residual(fo.cam, fo.rot[0], ob, &r)) ss += r.squaredNorm(), ++m;
        }
        (which ? ss_after : ss_before).push_back(ss);
        (which ? na : nb).push_back(m);
      }
      ++out.held_out_frames;
    }
    out.held_out_rms_before_px = RmsOf(ss_before, nb);
    out.held_out_rms_after_px = RmsOf(ss_after, na);
  }

  // Every frame solved with the fitted camera as `ssiu solve` would (no focal tolerance).
  const SolvedSet fin = SolveAll(id, frames, cam, o, 0.0);
  std::set<int> held;
  if (o.holdout_every >= 2 && out.held_out_frames > 0)
    for (size_t k = 0; k < fit_frame.size(); ++k)
      if (k % o.holdout_every == static_cast<size_t>(o.holdout_every - 1)) held.insert(fit_frame[k]);
  for (int i = 0; i < nf; ++i) {
    CalibratedFrame cf;
    cf.name = frames[i].name;
    cf.status = fin.results[i].status;
    cf.held_out = held.count(i) > 0;
    if (cf.status == SolveStatus::kSolved) {
      cf.q_inertial_from_sensor = fin.results[i].attitude.q_inertial_from_sensor;
      cf.covariance_rad2 = fin.results[i].attitude.covariance_rad2;
      cf.matches = static_cast<int>(fin.results[i].identification.matches.size());
      double ss = 0;
      for (const auto& m : fin.results[i].identification.matches) {
        const auto p = cam.Project(cf.q_inertial_from_sensor.conjugate() * m.r_inertial);
        if (p) ss += (*p - Vec2(m.x_px, m.y_px)).squaredNorm();
      }
      cf.rms_px = cf.matches ? std::sqrt(ss / (2 * cf.matches)) : 0;
      ++out.frames_solved;
    }
    out.frames.push_back(cf);
  }
  char buf[200];
  std::snprintf(buf, sizeof buf, "%d of %d frames solved with the fitted camera; %d stars, RMS %.3f px",
                out.frames_solved, nf, out.stars_used, out.rms_px);
  out.message = buf;
  return out;
}

Json CameraCalibrationToJson(const CameraCalibration& c) {
  Json j;
  j["status"] = CalibrationStatusName(c.status);
  j["message"] = c.message;
  j["camera"] = CameraToJson(c.camera);
  j["guess"] = CameraToJson(c.guess);
  Json p = Json::object();
  for (const auto& [k, v] : c.value) {
    const bool fitted = std::find(c.parameters.begin(), c.parameters.end(), k) != c.parameters.end();
    p[k] = {{"value", v}, {"sigma", fitted ? Json(c.sigma.at(k)) : Json(nullptr)}, {"fitted", fitted}};
  }
  j["parameters"] = p;
  j["covariance_order"] = c.parameters;
  Json cov = Json::array();
  for (int r = 0; r < c.covariance.rows(); ++r) {
    Json row = Json::array();
    for (int k = 0; k < c.covariance.cols(); ++k) row.push_back(c.covariance(r, k));
    cov.push_back(row);
  }
  j["covariance"] = cov;
  j["unobservable"] = c.unobservable;
  j["dropped_not_significant"] = c.dropped;
  j["frames_solved"] = c.frames_solved;
  j["stars_used"] = c.stars_used;
  j["rms_px"] = c.rms_px;
  j["reduced_chi2"] = c.reduced_chi2;
  j["held_out"] = {{"frames", c.held_out_frames},
                   {"rms_before_px", c.held_out_rms_before_px},
                   {"rms_after_px", c.held_out_rms_after_px}};
  Json fr = Json::array();
  for (const auto& f : c.frames) {
    Json e = {{"name", f.name}, {"status", SolveStatusName(f.status)}, {"held_out", f.held_out}};
    if (f.status == SolveStatus::kSolved) {
      const auto q = ToWxyz(f.q_inertial_from_sensor);
      const RaDecRoll a = RaDecRollFromQuat(f.q_inertial_from_sensor);
      e["q"] = {q[0], q[1], q[2], q[3]};
      e["ra_deg"] = a.ra_rad * kRadToDeg;
      e["dec_deg"] = a.dec_rad * kRadToDeg;
      e["roll_deg"] = a.roll_rad * kRadToDeg;
      e["sigma_cross_arcsec"] = std::sqrt(0.5 * (f.covariance_rad2(0, 0) + f.covariance_rad2(1, 1))) * kRadToArcsec;
      e["matches"] = f.matches;
      e["rms_px"] = f.rms_px;
    }
    fr.push_back(e);
  }
  j["frames"] = fr;
  return j;
}

HeadAlignment AlignHeads(const std::vector<std::vector<AttitudeSolution>>& att, const std::vector<Quat>& mounts) {
  const int nh = static_cast<int>(mounts.size());
  HeadAlignment out;
  out.q_body_sensor = mounts;
  out.covariance_rad2.assign(nh, Mat3::Zero());
  out.epochs_used.assign(nh, 0);
  out.chi2_per_dof.assign(nh, 0.0);
  const Mat3 m1 = mounts[0].normalized().toRotationMatrix();
  for (int h = 1; h < nh; ++h) {
    // Per epoch: M_h = M_1 R_1^T R_h, error dtheta_h - A dtheta_1 with A = R_h^T R_1.
    std::vector<Mat3> est;
    std::vector<Mat3> cov;
    for (const auto& e : att) {
      if (static_cast<int>(e.size()) != nh || e[0].status != SolveStatus::kSolved ||
          e[h].status != SolveStatus::kSolved)
        continue;
      const Mat3 r1 = e[0].q_inertial_from_sensor.toRotationMatrix(),
                 rh = e[h].q_inertial_from_sensor.toRotationMatrix();
      const Mat3 a = rh.transpose() * r1;
      est.push_back(m1 * r1.transpose() * rh);
      cov.push_back(e[h].covariance_rad2 + a * e[0].covariance_rad2 * a.transpose());
    }
    if (est.empty()) continue;
    Mat3 m = est[0];
    Mat3 info = Mat3::Zero();
    for (int it = 0; it < 3; ++it) {
      Vec3 num = Vec3::Zero();
      info.setZero();
      for (size_t k = 0; k < est.size(); ++k) {
        const Eigen::AngleAxisd d(m.transpose() * est[k]);
        const Mat3 w = cov[k].inverse();
        num += w * (d.angle() * d.axis());
        info += w;
      }
      m = m * Exp(info.ldlt().solve(num));
    }
    double chi2 = 0;
    for (size_t k = 0; k < est.size(); ++k) {
      const Eigen::AngleAxisd d(m.transpose() * est[k]);
      const Vec3 dv = d.angle() * d.axis();
      chi2 += dv.dot(cov[k].ldlt().solve(dv));
    }
    out.q_body_sensor[h] = Quat(m).normalized();
    out.covariance_rad2[h] = info.inverse();
    out.epochs_used[h] = static_cast<int>(est.size());
    out.chi2_per_dof[h] = est.size() > 1 ? chi2 / (3.0 * (est.size() - 1)) : 0.0;
  }
  return out;
}

}  // namespace ssiu
