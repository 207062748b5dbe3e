#include "attitude/star_solver.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/attitude.h"
#include "core/csv.h"
#include "core/error.h"

namespace ssiu {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

Json NumOrNull(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

// `lost_in_space`: the camera and options r was identified with (null when tracking): with sky
// corrections, a focal length refined on catalog directions is tested again on the apparent ones.
void Finish(const StarIdentifier& id, const SkyCorrections& sky, SolveResult* r, const Camera* camera = nullptr,
            const IdentifyOptions* lost_in_space = nullptr) {
  r->sky = sky;
  r->catalog_epoch_year = id.catalog().epoch_year;
  ApplySkyCorrections(id, sky, &r->identification);
  if (sky.active() && camera && lost_in_space) RetestFocalLength(*camera, *lost_in_space, &r->identification);
  if (camera && lost_in_space) RetestPrincipalPoint(*camera, *lost_in_space, &r->identification);
  r->status = r->identification.status;
  r->message = r->identification.message;
  for (const auto& [k, v] : r->identification.timing_ms) r->timing_ms[k] = v;
  if (r->status == SolveStatus::kSolved) {
    const auto t0 = Clock::now();
    r->attitude = SolveAttitude(r->identification);
    r->timing_ms["attitude"] = MsSince(t0);
  }
}

}  // namespace

void SolveOptions::Check() const {
  identify.Check();
  sky.Check();
  detect.Check();
  if (!(detector_sigma_scale > 0 && detector_sigma_scale < 100))
    throw InputError("solve options", "detector_sigma_scale must be in (0, 100)");
  if (!(track_search_radius_px > 0 && track_search_radius_px < 1000))
    throw InputError("solve options", "track_search_radius_px must be in (0, 1000)");
  if (!(vignetting >= 0 && vignetting < 1)) throw InputError("solve options", "vignetting must be in [0, 1)");
}

void ApplySkyCorrections(const StarIdentifier& id, const SkyCorrections& sky, Identification* identification) {
  if (!sky.active()) return;
  const Vec3 v = sky.ObserverVelocityMS();
  const auto& stars = id.catalog().stars;
  for (auto& m : identification->matches) {
    if (m.star >= 0 && m.star < static_cast<int>(stars.size()))
      m.r_inertial = sky.Apparent(stars[m.star], id.catalog().epoch_year, v);
  }
}

StarIdentifier MakeIdentifierForCamera(const std::string& dir, const Camera& cam, double fov_tolerance_pct,
                                       double mag_max, const std::string& source) {
  CatalogBuildOptions b;
  b.fov_deg = std::round(cam.FovMaxRad() * kRadToDeg * (1 + fov_tolerance_pct / 100.0) * 10) / 10;
  b.mag_max = mag_max;
  const std::string src = source.empty() ? DefaultSourceFor(b.fov_deg) : source;
  if (dir.empty()) return StarIdentifier(LoadOrBuildCatalog(src, b));
  return StarIdentifier(LoadOrBuildCatalogIn(dir, src, b, /*rebuild_damaged=*/false));
}

StarIdentifier MakeIdentifierForFovRange(const std::string& dir, const Camera& cam, double fov_min_deg,
                                         double fov_max_deg, double mag_max, const std::string& source) {
  CatalogBuildOptions b;
  // Horizontal FOVs; a sensor taller than wide needs the vertical one (square pixels assumed here).
  b.fov_deg = std::ceil(fov_max_deg * std::max(1.0, static_cast<double>(cam.height) / cam.width) * 10) / 10;
  b.fov_min_deg = std::min(b.fov_deg, std::floor(fov_min_deg * 10) / 10);
  b.mag_max = mag_max;
  const std::string src = source.empty() ? DefaultSourceFor(b.fov_min_deg) : source;
  if (dir.empty()) return StarIdentifier(LoadOrBuildCatalog(src, b));
  return StarIdentifier(LoadOrBuildCatalogIn(dir, src, b, /*rebuild_damaged=*/false));
}

StarIdentifier MakeIdentifierFor(const std::string& dir, const Camera& camera, const IdentifyOptions& o, double mag_max,
                                 const std::string& source) {
  if (o.FovRange()) return MakeIdentifierForFovRange(dir, camera, o.fov_min_deg, o.fov_max_deg, mag_max, source);
  return MakeIdentifierForCamera(dir, camera, o.fov_tolerance_pct, mag_max, source);
}

void CentroidsFromDetections(const Detections& d, double sigma_scale, std::vector<Centroid>* out) {
  out->clear();
  out->reserve(d.stars.size());
  for (const auto& s : d.stars) {
    Centroid c;
    c.x_px = s.x_px;
    c.y_px = s.y_px;
    c.flux = s.flux_adu;
    const double v = 0.5 * (s.x_sigma_px * s.x_sigma_px + s.y_sigma_px * s.y_sigma_px);
    c.sigma_px = std::isfinite(v) && v > 0 ? sigma_scale * std::sqrt(v) : 0.0;
    out->push_back(c);
  }
}

std::vector<Centroid> CentroidsFromDetections(const Detections& d, double sigma_scale) {
  std::vector<Centroid> out;
  CentroidsFromDetections(d, sigma_scale, &out);
  return out;
}

void UseCameraExtras(const CameraExtras& e, DetectOptions* o) {
  if (o->psf_sigma_px == 0) o->psf_sigma_px = e.psf_sigma_px;
}

void UseCameraExtras(const CameraExtras& e, SolveOptions* o) {
  UseCameraExtras(e, &o->detect);
  o->vignetting = e.vignetting;
}

void TakeOutVignetting(const Camera& camera, double v, std::vector<Centroid>* centroids) {
  if (!(v > 0)) return;
  for (auto& c : *centroids) c.flux /= std::max(0.05, 1 - v * VignettingRadius2(camera, c.x_px, c.y_px));
}

std::vector<Centroid> ReadCentroidsCsv(const std::string& path) {
  const CsvTable t = ReadCsv(path);
  const auto& x = t.Column("x_px");
  const auto& y = t.Column("y_px");
  std::vector<Centroid> out(t.rows());
  for (size_t i = 0; i < t.rows(); ++i) {
    out[i].x_px = x[i];
    out[i].y_px = y[i];
  }
  if (t.Has("flux")) {
    const auto& f = t.Column("flux");
    for (size_t i = 0; i < t.rows(); ++i) out[i].flux = f[i];
  }
  if (t.Has("sigma_px")) {
    const auto& s = t.Column("sigma_px");
    for (size_t i = 0; i < t.rows(); ++i) {
      if (s[i] < 0) throw InputError(path, "column sigma_px, row " + std::to_string(i + 1) + ": negative");
      out[i].sigma_px = s[i];
    }
  }
  return out;
}

namespace {

// What identification sees (SolveOptions::vignetting): `centroids` themselves, or with v > 0 a copy in
// *kept with the vignetting taken out of the fluxes.
const std::vector<Centroid>& WithoutVignetting(const std::vector<Centroid>& centroids, const Camera& camera, double v,
                                               std::vector<Centroid>* kept) {
  if (!(v > 0)) return centroids;
  *kept = centroids;
  TakeOutVignetting(camera, v, kept);
  return *kept;
}

}  // namespace

SolveResult SolveCentroids(const StarIdentifier& id, const std::vector<Centroid>& centroids, const Camera& camera,
                           const SolveOptions& options) {
  options.Check();
  SolveResult r;
  r.centroids = centroids;  // as measured; identification sees the fluxes with the vignetting taken out
  std::vector<Centroid> kept;
  r.identification =
      id.Identify(WithoutVignetting(centroids, camera, options.vignetting, &kept), camera, options.identify);
  Finish(id, options.sky, &r, &camera, &options.identify);
  return r;
}

SolveResult SolveFrame(const StarIdentifier& id, const ImageView& image, const Camera& camera,
                       const SolveOptions& options, const DefectMap* defects) {
  options.Check();
  if (image.width != camera.width || image.height != camera.height) {
    throw InputError("camera", "image is " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                                   " but the camera is " + std::to_string(camera.width) + "x" +
                                   std::to_string(camera.height));
  }
  const auto t0 = Clock::now();
  DetectOptions dopt = options.detect;
  if (dopt.gain_e_per_adu == 0) dopt.gain_e_per_adu = camera.gain_e_per_adu;
  Detections det = Detect(image, dopt, defects);
  const double detect_ms = MsSince(t0);
  SolveResult r = SolveCentroids(id, CentroidsFromDetections(det, options.detector_sigma_scale), camera, options);
  r.detections = std::move(det);
  r.timing_ms["detect"] = detect_ms;
  return r;
}

Json SolveResultToJson(const SolveResult& r) {
  Json j;
  j["status"] = SolveStatusName(r.status);
  j["mode"] = SolveModeName(r.mode);
  j["message"] = r.message;
  const bool ok = r.status == SolveStatus::kSolved;
  const double nan = std::nan("");
  if (ok) {
    const auto q = ToWxyz(r.attitude.q_inertial_from_sensor);
    j["q"] = {q[0], q[1], q[2], q[3]};
  } else {
    j["q"] = nullptr;
  }
  const RaDecRoll rdr = RaDecRollFromQuat(r.attitude.q_inertial_from_sensor);
  j["ra_deg"] = NumOrNull(ok ? rdr.ra_rad * kRadToDeg : nan);
  j["dec_deg"] = NumOrNull(ok ? rdr.dec_rad * kRadToDeg : nan);
  j["roll_deg"] = NumOrNull(ok ? rdr.roll_rad * kRadToDeg : nan);
  j["sigma_cross_arcsec"] = NumOrNull(ok ? r.attitude.sigma_cross_rad * kRadToArcsec : nan);
  j["sigma_roll_arcsec"] = NumOrNull(ok ? r.attitude.sigma_roll_rad * kRadToArcsec : nan);
  j["focal_length_px"] = NumOrNull(r.identification.focal_length_px);
  j["focal_length_y_px"] = NumOrNull(r.identification.focal_length_y_px);
  j["focal_length_sigma_px"] =
      NumOrNull(ok && r.identification.focal_length_fitted ? r.identification.focal_length_sigma_px : nan);
  // A fixed focal length the stars rejected and that was refitted (docs/identify.md, "Focal length").
  j["focal_length_refined"] = ok && r.identification.focal_length_refined;
  j["focal_length_p_value"] = NumOrNull(ok ? r.identification.focal_length_p_value : nan);
  const bool pp = ok && r.identification.principal_point_refined;
  j["principal_point_refined"] = pp;
  j["principal_point_p_value"] = NumOrNull(ok ? r.identification.principal_point_p_value : nan);
  j["cx_px"] = NumOrNull(pp ? r.identification.cx_px : nan);
  j["cy_px"] = NumOrNull(pp ? r.identification.cy_px : nan);
  j["principal_point_sigma_px"] = NumOrNull(pp ? r.identification.principal_point_sigma_px : nan);
  j["outliers_rejected"] = r.identification.outliers_rejected;
  j["false_match_probability"] = r.identification.false_match_probability;
  j["photometric_factor"] = r.identification.photometric_factor;
  Json m = Json::array();
  if (ok) {
    for (const auto& s : r.identification.matches) {
      const Vec3 pred = r.attitude.q_inertial_from_sensor.conjugate() * s.r_inertial;
      const double res = std::atan2(pred.cross(s.b_sensor).norm(), pred.dot(s.b_sensor));
      m.push_back({{"x_px", s.x_px},
                   {"y_px", s.y_px},
                   {"star_id", s.star_id},
                   {"mag", s.mag},
                   {"residual_arcsec", res * kRadToArcsec}});
    }
  }
  j["matches"] = m;
  j["num_centroids"] = r.centroids.size();
  j["hypotheses"] = r.identification.hypotheses;
  // The work budget (docs/identify.md, "Work budget"): triangles looked up and why the search ended.
  j["patterns"] = r.identification.patterns;
  j["search_stop"] = SearchStopName(r.identification.stop);
  Json t = Json::object();
  for (const auto& [k, v] : r.timing_ms) t[k] = v;
  j["timing_ms"] = t;
  AddCorrectionsToJson(r.sky, r.catalog_epoch_year, ok ? &r.attitude.q_inertial_from_sensor : nullptr, &j);
  return j;
}

void AddCorrectionsToJson(const SkyCorrections& sky, double catalog_epoch_year, const Quat* q, Json* j) {
  const bool on = sky.active();
  (*j)["time_utc"] = on ? Json(FormatUtcIso8601(sky.time)) : Json(nullptr);
  Json c;
  c["proper_motion_epoch"] = on && sky.proper_motion ? Json(JulianYearTt(sky.time)) : Json(nullptr);
  c["catalog_epoch"] = catalog_epoch_year;
  c["annual_aberration"] = on && sky.annual_aberration;
  if (on && sky.have_velocity) {
    const Vec3 v = sky.velocity_m_s / 1000.0;
    c["velocity_kms"] = {v.x(), v.y(), v.z()};
  } else {
    c["velocity_kms"] = nullptr;
  }
  // Size of the correction at the boresight: (v/c) sin(angle to the apex), to first order.
  const Vec3 v = on ? sky.ObserverVelocityMS() : Vec3::Zero();
  c["aberration_arcsec"] =
      q ? Json(v.cross(q->normalized() * Vec3::UnitZ()).norm() / kSpeedOfLightMS * kRadToArcsec) : Json(nullptr);
  (*j)["corrections"] = c;
}

namespace {

// SIP polynomial (Shupe et al. 2005) of a camera's distortion, fitted by least squares on a grid over
// the image: forward (A, B) maps pixel offsets (u, v) from CRPIX to the pinhole offsets the CD matrix
// takes, u' = u + A(u, v), with 2 <= p + q <= order; inverse (AP, BP) maps back, u = u' + AP(u', v'),
// with 1 <= p + q <= order. The lowest order (2..9) whose worst grid error is below 0.002 px is kept.
struct SipFit {
  int order = 0;
  std::vector<std::array<double, 4>> a, b;  // {p, q, coefficient, unused}
  double max_err_px = 0;
};

SipFit FitSip(const std::vector<Vec2>& from, const std::vector<Vec2>& to, int min_total, double scale) {
  SipFit best;
  for (int order = 2; order <= 9; ++order) {
    std::vector<std::pair<int, int>> terms;
    for (int p = 0; p <= order; ++p)
      for (int q = 0; p + q <= order; ++q)
        if (p + q >= min_total) terms.push_back({p, q});
    Eigen::MatrixXd m(from.size(), terms.size());
    Eigen::VectorXd du(from.size()), dv(from.size());
    for (size_t i = 0; i < from.size(); ++i) {
      const double x = from[i].x() / scale, y = from[i].y() / scale;  // normalised for conditioning
      for (size_t t = 0; t < terms.size(); ++t) m(i, t) = std::pow(x, terms[t].first) * std::pow(y, terms[t].second);
      du[i] = to[i].x() - from[i].x();
      dv[i] = to[i].y() - from[i].y();
    }
    const auto qr = m.colPivHouseholderQr();
    const Eigen::VectorXd ca = qr.solve(du), cb = qr.solve(dv);
    const double err = std::max((m * ca - du).cwiseAbs().maxCoeff(), (m * cb - dv).cwiseAbs().maxCoeff());
    if (best.order == 0 || err < best.max_err_px) {
      best.order = order;
      best.max_err_px = err;
      best.a.clear(), best.b.clear();
      for (size_t t = 0; t < terms.size(); ++t) {
        const double k = std::pow(scale, terms[t].first + terms[t].second);
        best.a.push_back({double(terms[t].first), double(terms[t].second), ca[t] / k, 0});
        best.b.push_back({double(terms[t].first), double(terms[t].second), cb[t] / k, 0});
      }
    }
    if (err < 0.002) break;
  }
  return best;
}

}  // namespace

std::string TanWcsHeader(const Quat& q, const Camera& cam) {
  const Mat3 r = q.normalized().toRotationMatrix();
  // Pixel direction at the principal point is the boresight; standard coordinates (xi east, eta north)
  // of a pixel offset (dx, dy) are (R^T e_east . (dx/fx, dy/fy, 0), R^T e_north . (dx/fx, dy/fy, 0))
  // (Calabretta & Greisen 2002, TAN: x = xi, y = eta in degrees).
  const Vec3 bore = r.col(2);
  double ra, dec;
  RaDecFromUnit(bore, &ra, &dec);
  const Vec3 east(-std::sin(ra), std::cos(ra), 0);
  const Vec3 north(-std::sin(dec) * std::cos(ra), -std::sin(dec) * std::sin(ra), std::cos(dec));
  const Vec3 e_s = r.transpose() * east, n_s = r.transpose() * north;
  const double sx = kRadToDeg / cam.focal_length_px, sy = kRadToDeg / cam.FocalYPx();
  std::vector<std::string> cards;
  auto card = [&](const std::string& key, const std::string& value, const std::string& comment) {
    char buf[81];
    std::snprintf(buf, sizeof buf, "%-8.8s= %20s / %-47.47s", key.c_str(), value.c_str(), comment.c_str());
    cards.push_back(buf);
  };
  auto num = [](double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.12G", v);
    return std::string(b);
  };
  card("WCSAXES", "2", "ssiu solve");
  const bool sip = !cam.distortion.IsZero();
  card("CTYPE1", sip ? "'RA---TAN-SIP'" : "'RA---TAN'", sip ? "TAN with SIP distortion" : "TAN (gnomonic) projection");
  card("CTYPE2", sip ? "'DEC--TAN-SIP'" : "'DEC--TAN'", sip ? "TAN with SIP distortion" : "TAN (gnomonic) projection");
  card("EQUINOX", "2000.0", "ICRS/J2000");
  card("CRVAL1", num(ra * kRadToDeg), "RA of the reference pixel (deg)");
  card("CRVAL2", num(dec * kRadToDeg), "Dec of the reference pixel (deg)");
  card("CRPIX1", num(cam.cx_px + 1), "principal point x (FITS 1-based)");
  card("CRPIX2", num(cam.cy_px + 1), "principal point y (FITS 1-based)");
  card("CUNIT1", "'deg'", "");
  card("CUNIT2", "'deg'", "");
  card("CD1_1", num(e_s.x() * sx), "deg/px");
  card("CD1_2", num(e_s.y() * sy), "deg/px");
  card("CD2_1", num(n_s.x() * sx), "deg/px");
  card("CD2_2", num(n_s.y() * sy), "deg/px");
  card("IMAGEW", std::to_string(cam.width), "image width (px)");
  card("IMAGEH", std::to_string(cam.height), "image height (px)");
  if (sip) {
    // Grid over the image (and 2 % beyond): distorted pixel offsets (u, v) <-> pinhole offsets (u', v').
    std::vector<Vec2> dist, pin;
    const int n = 40;
    for (int i = 0; i <= n; ++i) {
      for (int k = 0; k <= n; ++k) {
        const double x = -0.5 + (cam.width * 1.04) * (i / double(n) - 0.02),
                     y = -0.5 + (cam.height * 1.04) * (k / double(n) - 0.02);
        const Vec3 d = cam.Unproject(Vec2(x, y));
        dist.push_back(Vec2(x - cam.cx_px, y - cam.cy_px));
        pin.push_back(Vec2(cam.focal_length_px * d.x() / d.z(), cam.FocalYPx() * d.y() / d.z()));
      }
    }
    const double scale = 0.5 * std::max(cam.width, cam.height);
    auto write = [&](const SipFit& f, const std::string& a, const std::string& b, const char* what) {
      card(a + "_ORDER", std::to_string(f.order), what);
      for (const auto& t : f.a)
        card(a + "_" + std::to_string(int(t[0])) + "_" + std::to_string(int(t[1])), num(t[2]), "");
      card(b + "_ORDER", std::to_string(f.order), what);
      for (const auto& t : f.b)
        card(b + "_" + std::to_string(int(t[0])) + "_" + std::to_string(int(t[1])), num(t[2]), "");
    };
    write(FitSip(dist, pin, 2, scale), "A", "B", "SIP: distorted -> pinhole pixel offsets");
    write(FitSip(pin, dist, 1, scale), "AP", "BP", "SIP inverse: pinhole -> distorted");
  }
  std::string out;
  for (auto& c : cards) out += c.substr(0, 80) + std::string(80 - std::min<size_t>(80, c.size()), ' ');
  out += "END" + std::string(77, ' ');
  out += std::string((2880 - out.size() % 2880) % 2880, ' ');
  return out;
}

SolveResult Tracker::Update(const std::vector<Centroid>& centroids, double t_s) {
  options_.Check();
  const auto t0 = Clock::now();
  SolveResult r;
  r.centroids = centroids;
  std::vector<Centroid> kept;
  const std::vector<Centroid>& seen = WithoutVignetting(centroids, camera_, options_.vignetting, &kept);
  if (locked_) {
    const double dt = t_s - t_last_;
    Quat q_pred = q_last_;
    if (have_rate_) {
      const Vec3 th = w_sensor_rad_s_ * dt;
      if (th.norm() > 0) q_pred = q_last_ * Quat(Eigen::AngleAxisd(th.norm(), th.normalized()));
    }
    r.identification = id_.MatchWithAttitude(seen, camera_, q_pred, options_.track_search_radius_px, options_.identify);
    r.mode = SolveMode::kTracking;
  }
  const Camera camera_before = camera_;
  if (!locked_ || r.identification.status != SolveStatus::kSolved) {
    r.identification = id_.Identify(seen, camera_, options_.identify);
    r.mode = SolveMode::kLostInSpace;
    have_rate_ = false;
  }
  SkyCorrections sky = options_.sky;
  if (sky.active()) sky.time = AddSeconds(sky.time, t_s);
  Finish(id_, sky, &r, &camera_before, r.mode == SolveMode::kLostInSpace ? &options_.identify : nullptr);
  if (r.mode == SolveMode::kLostInSpace && r.identification.status == SolveStatus::kSolved)
    camera_ = FittedCamera(camera_before, r.identification);
  if (r.status == SolveStatus::kSolved) {
    const Quat q = r.attitude.q_inertial_from_sensor;
    if (locked_ && r.mode == SolveMode::kTracking) {  // a rate only from two attitudes of one lock
      const double dt = t_s - t_last_;
      if (dt > 0) {
        Quat d = q_last_.conjugate() * q;  // sensor-frame rotation over dt
        if (d.w() < 0) d.coeffs() = -d.coeffs();
        const Eigen::AngleAxisd aa(d);
        w_sensor_rad_s_ = aa.axis() * aa.angle() / dt;
        have_rate_ = true;
      }
    }
    q_last_ = q;
    t_last_ = t_s;
    locked_ = true;
  } else {
    locked_ = false;
    have_rate_ = false;
  }
  r.timing_ms["total"] = MsSince(t0);
  return r;
}

}  // namespace ssiu
