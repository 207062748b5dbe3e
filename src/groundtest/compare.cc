#include "groundtest/compare.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "ccsds/adm.h"
#include "core/attitude.h"
#include "core/csv.h"
#include "core/error.h"
#include "groundtest/stand.h"
#include "plot/plot.h"

namespace ssiu {

std::vector<AttitudeSample> ReadAttitudeSeries(const std::string& path, std::string* epoch_utc) {
  if (LooksLikeAdm(path)) {  // a CCSDS AEM/ACM: t_s from its epoch, sigmas from an ACM's ANGLE covariance
    const AttitudeHistory h = ReadAdmFile(path, epoch_utc ? *epoch_utc : "");
    if (epoch_utc && epoch_utc->empty()) *epoch_utc = h.epoch_utc;
    const bool sig = h.covariances.size() == h.states.size();
    std::vector<AttitudeSample> out;
    for (size_t i = 0; i < h.states.size(); ++i) {
      AttitudeSample s;
      s.t_s = h.states[i].t_s;
      s.q = h.states[i].q_inertial_from_body;
      if (sig) {
        const std::vector<double>& d = h.covariances[i].diagonal;
        s.sigma_cross_rad = std::sqrt((d[0] + d[1]) / 2);
        s.sigma_roll_rad = std::sqrt(d[2]);
      }
      out.push_back(s);
    }
    return out;
  }
  const CsvTable t = ReadCsv(path);
  if (t.rows() < 1) throw InputError(path, "no data rows");
  t.CheckIncreasing("t_s");
  const auto& ts = t.Column("t_s");
  const auto &qw = t.Column("qw"), &qx = t.Column("qx"), &qy = t.Column("qy"), &qz = t.Column("qz");
  const bool sig = t.Has("sigma_cross_arcsec") && t.Has("sigma_roll_arcsec");
  std::vector<AttitudeSample> out;
  for (size_t i = 0; i < t.rows(); ++i) {
    AttitudeSample s;
    s.t_s = ts[i];
    const std::string what = path + ": row " + std::to_string(i + 1) + " quaternion";
    s.q = FromWxyz(qw[i], qx[i], qy[i], qz[i], what.c_str());
    if (sig) {
      s.sigma_cross_rad = t.Column("sigma_cross_arcsec")[i] * kArcsecToRad;
      s.sigma_roll_rad = t.Column("sigma_roll_arcsec")[i] * kArcsecToRad;
      // Above half a turn a 1-sigma is meaningless, and 1e300 arcsec turned the weights into 0/0.
      if (!(s.sigma_cross_rad >= 0 && s.sigma_cross_rad <= kPi) || !(s.sigma_roll_rad >= 0 && s.sigma_roll_rad <= kPi))
        throw InputError(path,
                         "sigma columns: negative or above 648000 arcsec (180 deg) at row " + std::to_string(i + 1));
    }
    if (t.Has("common_sigma_cross_arcsec") && t.Has("common_sigma_roll_arcsec")) {
      s.common_sigma_cross_rad = t.Column("common_sigma_cross_arcsec")[i] * kArcsecToRad;
      s.common_sigma_roll_rad = t.Column("common_sigma_roll_arcsec")[i] * kArcsecToRad;
    }
    out.push_back(s);
  }
  return out;
}

void CompareOptions::Check() const {
  if (!(requirement_arcsec > 0)) throw InputError("--requirement-arcsec", "must be > 0");
  if (!(roll_requirement_arcsec >= 0)) throw InputError("--roll-requirement-arcsec", "must be >= 0");
  if (!(time_tolerance_s >= 0)) throw InputError("--time-tolerance-s", "must be >= 0");
}

namespace {

// Weighted least-squares line r = a + b (t - t0); returns b and its formal sigma.
void FitLine(const std::vector<double>& t, const std::vector<double>& r, const std::vector<double>& w, double* b,
             double* sb) {
  double sw = 0, st = 0;
  for (size_t i = 0; i < t.size(); ++i) sw += w[i], st += w[i] * t[i];
  const double t0 = st / sw;
  double stt = 0, str = 0;
  for (size_t i = 0; i < t.size(); ++i) stt += w[i] * (t[i] - t0) * (t[i] - t0), str += w[i] * (t[i] - t0) * r[i];
  if (stt <= 0) {
    *b = 0, *sb = 0;
    return;
  }
  *b = str / stt;
  *sb = std::sqrt(1 / stt);
}

}  // namespace

CompareResult CompareAttitudes(const std::vector<AttitudeSample>& ref, const std::vector<AttitudeSample>& est,
                               const CompareOptions& o, const std::string& name) {
  o.Check();
  CompareResult r;
  std::vector<Vec3> sig;        // per-axis 1-sigma of each error, 0 = unknown
  Vec3 common2 = Vec3::Zero();  // sum of the common-mode variances
  bool have_sigmas = true;
  for (const auto& e : est) {
    // Nearest reference in time.
    auto it =
        std::lower_bound(ref.begin(), ref.end(), e.t_s, [](const AttitudeSample& a, double t) { return a.t_s < t; });
    const AttitudeSample* best = nullptr;
    for (auto c : {it, it == ref.begin() ? it : it - 1})
      if (c != ref.end() && std::abs(c->t_s - e.t_s) <= o.time_tolerance_s &&
          (!best || std::abs(c->t_s - e.t_s) < std::abs(best->t_s - e.t_s)))
        best = &*c;
    if (!best) {
      ++r.unmatched;
      continue;
    }
    r.t_s.push_back(e.t_s);
    r.error_rad.push_back(RotationVector(best->q.conjugate() * e.q));
    const double sc = std::hypot(best->sigma_cross_rad, e.sigma_cross_rad);
    const double sr = std::hypot(best->sigma_roll_rad, e.sigma_roll_rad);
    if (!(sc > 0 && sr > 0)) have_sigmas = false;
    sig.emplace_back(sc, sc, sr);
    const double cc = std::hypot(best->common_sigma_cross_rad, e.common_sigma_cross_rad);
    const double cr = std::hypot(best->common_sigma_roll_rad, e.common_sigma_roll_rad);
    common2 += Vec3(cc * cc, cc * cc, cr * cr);
  }
  r.pictures = static_cast<int>(r.t_s.size());
  if (r.pictures < 2)
    throw InputError(name, std::to_string(r.pictures) + " picture(s) matched a reference time within " +
                               std::to_string(o.time_tolerance_s) + " s (need 2)");
  const int n = r.pictures;
  std::vector<Vec3> w(n, Vec3::Ones());
  if (have_sigmas)
    for (int i = 0; i < n; ++i) w[i] = sig[i].cwiseInverse().cwiseAbs2();
  // Weighted mean = misalignment estimate.
  Vec3 sw = Vec3::Zero(), swe = Vec3::Zero();
  for (int i = 0; i < n; ++i) sw += w[i], swe += w[i].cwiseProduct(r.error_rad[i]);
  const Vec3 mean = swe.cwiseQuotient(sw);
  double chi2 = 0;
  Vec3 ss = Vec3::Zero();
  for (int i = 0; i < n; ++i) {
    const Vec3 d = r.error_rad[i] - mean;
    chi2 += d.cwiseAbs2().dot(w[i]);
    ss += d.cwiseAbs2();
  }
  const int dof = 3 * (n - 1);
  if (have_sigmas) {
    r.chi2_per_dof = chi2 / dof;
    r.birge_ratio = std::max(1.0, std::sqrt(r.chi2_per_dof));
    r.misalignment_sigma_rad = sw.cwiseInverse().cwiseSqrt() * r.birge_ratio;
  } else {
    r.misalignment_sigma_rad = (ss / (n - 1) / n).cwiseSqrt();  // standard error of the mean
  }
  r.misalignment_sigma_rad = (r.misalignment_sigma_rad.cwiseAbs2() + common2 / n).cwiseSqrt();
  r.misalignment_rad = o.remove_misalignment ? mean : Vec3::Zero();
  if (!o.remove_misalignment) r.misalignment_sigma_rad.setZero();
  // Residuals and their statistics.
  std::vector<double> rx, ry, rz, wx, wy, wz;
  double s_cross = 0, s_tot = 0, raw_c = 0, raw_r = 0, sig_c = 0, sig_r = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3 e = r.error_rad[i] - r.misalignment_rad;
    r.residual_rad.push_back(e);
    rx.push_back(e.x()), ry.push_back(e.y()), rz.push_back(e.z());
    wx.push_back(w[i].x()), wy.push_back(w[i].y()), wz.push_back(w[i].z());
    const double c = std::hypot(e.x(), e.y());
    s_cross += c * c, s_tot += e.squaredNorm();
    r.max_cross_rad = std::max(r.max_cross_rad, c);
    r.max_total_rad = std::max(r.max_total_rad, e.norm());
    raw_c += r.error_rad[i].head<2>().squaredNorm(), raw_r += r.error_rad[i].z() * r.error_rad[i].z();
    sig_c += sig[i].x() * sig[i].x(), sig_r += sig[i].z() * sig[i].z();
  }
  // Cross-boresight RMS as the RMS per axis (sqrt of the mean of (x^2 + y^2)/2), comparable with a
  // per-axis 1-sigma such as the tracker's sigma_cross.
  r.rms_cross_rad = std::sqrt(s_cross / (2.0 * n));
  r.rms_total_rad = std::sqrt(s_tot / n);
  r.raw_rms_cross_rad = std::sqrt(raw_c / (2.0 * n));
  r.raw_rms_roll_rad = std::sqrt(raw_r / n);
  r.mean_sigma_cross_rad = std::sqrt(sig_c / n);
  r.mean_sigma_roll_rad = std::sqrt(sig_r / n);
  auto stats = [&](const std::vector<double>& v, const std::vector<double>& wv, AxisStats* a) {
    double s = 0, s2 = 0;
    for (double x : v) s += x, s2 += x * x, a->max_abs = std::max(a->max_abs, std::abs(x));
    a->mean = s / n, a->rms = std::sqrt(s2 / n);
    FitLine(r.t_s, v, wv, &a->drift_per_h, &a->drift_sigma_per_h);
    a->drift_per_h *= 3600, a->drift_sigma_per_h *= 3600 * (have_sigmas ? r.birge_ratio : 0);
    if (!have_sigmas) {  // unweighted: sigma from the scatter about the line
      double sr = 0, st = 0, t0 = 0;
      for (double t : r.t_s) t0 += t / n;
      for (int i = 0; i < n; ++i) st += (r.t_s[i] - t0) * (r.t_s[i] - t0);
      for (int i = 0; i < n; ++i) {
        const double d = v[i] - a->mean - a->drift_per_h / 3600 * (r.t_s[i] - t0);
        sr += d * d;
      }
      a->drift_sigma_per_h = n > 2 && st > 0 ? std::sqrt(sr / (n - 2) / st) * 3600 : 0;
    }
  };
  stats(rx, wx, &r.x), stats(ry, wy, &r.y), stats(rz, wz, &r.roll);
  r.requirement_cross_rad = o.requirement_arcsec * kArcsecToRad;
  r.requirement_roll_rad =
      (o.roll_requirement_arcsec > 0 ? o.roll_requirement_arcsec : 8 * o.requirement_arcsec) * kArcsecToRad;
  r.pass = r.rms_cross_rad <= r.requirement_cross_rad && r.roll.rms <= r.requirement_roll_rad;
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s: residual RMS cross %.2f arcsec (req %.2f), roll %.2f arcsec (req %.2f)",
                r.pass ? "pass" : "fail", r.rms_cross_rad * kRadToArcsec, o.requirement_arcsec,
                r.roll.rms * kRadToArcsec, r.requirement_roll_rad * kRadToArcsec);
  r.verdict = buf;
  return r;
}

Json CompareResultToJson(const CompareResult& r) {
  auto as = [](double rad) { return rad * kRadToArcsec; };
  auto axis = [&](const AxisStats& a) {
    return Json{{"mean_arcsec", as(a.mean)},
                {"rms_arcsec", as(a.rms)},
                {"max_abs_arcsec", as(a.max_abs)},
                {"drift_arcsec_per_h", as(a.drift_per_h)},
                {"drift_sigma_arcsec_per_h", as(a.drift_sigma_per_h)}};
  };
  Json j;
  j["pictures"] = r.pictures;
  j["unmatched"] = r.unmatched;
  j["misalignment_arcsec"] = {as(r.misalignment_rad.x()), as(r.misalignment_rad.y()), as(r.misalignment_rad.z())};
  j["misalignment_sigma_arcsec"] = {as(r.misalignment_sigma_rad.x()), as(r.misalignment_sigma_rad.y()),
                                    as(r.misalignment_sigma_rad.z())};
  j["misalignment_frame"] = "tracker sensor axes: rotation vector of conj(q_ref) * q_est (bias)";
  j["bias_arcsec"] = {{"cross", as(r.misalignment_rad.head<2>().norm())}, {"roll", as(r.misalignment_rad.z())}};
  j["raw"] = {{"rms_cross_arcsec", as(r.raw_rms_cross_rad)}, {"rms_roll_arcsec", as(r.raw_rms_roll_rad)}};
  j["residual"] = {{"x", axis(r.x)},
                   {"y", axis(r.y)},
                   {"roll", axis(r.roll)},
                   {"rms_cross_arcsec", as(r.rms_cross_rad)},
                   {"max_cross_arcsec", as(r.max_cross_rad)},
                   {"rms_total_arcsec", as(r.rms_total_rad)},
                   {"max_total_arcsec", as(r.max_total_rad)}};
  j["stated_sigma_arcsec"] = {{"cross", as(r.mean_sigma_cross_rad)}, {"roll", as(r.mean_sigma_roll_rad)}};
  j["chi2_per_dof"] = r.chi2_per_dof;
  j["birge_ratio"] = r.birge_ratio;
  j["requirement_arcsec"] = {{"cross", as(r.requirement_cross_rad)}, {"roll", as(r.requirement_roll_rad)}};
  j["pass"] = r.pass;
  j["verdict"] = r.verdict;
  Json pics = Json::array();
  for (int i = 0; i < r.pictures; ++i) {
    const Vec3& e = r.error_rad[i];
    const Vec3& d = r.residual_rad[i];
    pics.push_back({{"t_s", r.t_s[i]},
                    {"cross_arcsec", as(e.head<2>().norm())},
                    {"roll_arcsec", as(e.z())},
                    {"error_arcsec", {as(e.x()), as(e.y()), as(e.z())}},
                    {"residual_cross_arcsec", as(d.head<2>().norm())},
                    {"residual_roll_arcsec", as(d.z())}});
  }
  j["per_picture"] = pics;
  return j;
}

void WriteComparePlots(const CompareResult& r, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(dir, "cannot create the plot directory");
  const double to_min = 1.0 / 60.0;
  std::vector<double> t;
  for (double x : r.t_s) t.push_back(x * to_min);
  auto series = [&](const std::string& label, const std::vector<Vec3>& v, int axis, PlotColor c, bool line) {
    PlotSeries s;
    s.label = label, s.x = t, s.color = c, s.markers = true, s.line = line;
    for (const auto& e : v) s.y.push_back(e(axis) * kRadToArcsec);
    return s;
  };
  auto hline = [&](const std::string& label, double y, PlotColor c) {
    PlotSeries s;
    s.label = label, s.x = {t.front(), t.back()}, s.y = {y * kRadToArcsec, y * kRadToArcsec}, s.color = c,
    s.dashed = true;
    return s;
  };
  const PlotColor red{200, 40, 40}, blue{40, 70, 200}, green{30, 150, 60};
  PlotOptions po;
  po.x_label = "time (min)";
  po.y_label = "error (arcsec), tracker axes";
  po.title = "Tracker - reference per picture, with the estimated misalignment";
  WritePlotPng(dir + "/errors.png",
               {series("x", r.error_rad, 0, red, false), series("y", r.error_rad, 1, blue, false),
                series("roll", r.error_rad, 2, green, false), hline("misalignment x", r.misalignment_rad.x(), red),
                hline("misalignment y", r.misalignment_rad.y(), blue),
                hline("misalignment roll", r.misalignment_rad.z(), green)},
               po);
  po.title = "Residuals after removing the misalignment";
  po.y_label = "residual (arcsec)";
  WritePlotPng(dir + "/residuals.png",
               {series("x", r.residual_rad, 0, red, true), series("y", r.residual_rad, 1, blue, true),
                series("roll", r.residual_rad, 2, green, true), hline("+req cross", r.requirement_cross_rad, {0, 0, 0}),
                hline("-req cross", -r.requirement_cross_rad, {0, 0, 0})},
               po);
}

}  // namespace ssiu
