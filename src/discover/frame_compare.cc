#include "discover/frame_compare.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/attitude.h"
#include "core/error.h"
#include "core/stats.h"
#include "core/types.h"
#include "identify/star_catalog.h"
#include "plot/plot.h"

namespace ssiu {

void FrameCompareOptions::Check() const {
  sim.Check();
  if (tile_px < 8) throw InputError("options", "tile_px must be >= 8");
  if (!(match_radius_px > 0)) throw InputError("options", "match_radius_px must be > 0");
}

StarCatalog SkyForCamera(const Camera& camera, double fov_tolerance_pct, double mag_max) {
  const double fov_deg = camera.FovMaxRad() * kRadToDeg * (1 + fov_tolerance_pct / 100);
  const SourceCatalog src = LoadSourceCatalog(DefaultSourceFor(fov_deg));
  StarCatalog sky;
  sky.source = src.source;
  for (const auto& s : src.stars) {
    if (s.star.mag <= mag_max) sky.stars.push_back(s.star);
  }
  std::stable_sort(sky.stars.begin(), sky.stars.end(),
                   [](const CatalogStar& a, const CatalogStar& b) { return a.mag < b.mag; });
  return sky;
}

namespace {

// Median of each whole tile_px x tile_px tile, with the tile centre relative to the image centre.
struct TileMedians {
  std::vector<double> median_adu, dx_px, dy_px;
};
TileMedians MeasureTileMedians(const ImageView& image, int tile_px) {
  TileMedians t;
  std::vector<double> px;
  const double xc = 0.5 * (image.width - 1), yc = 0.5 * (image.height - 1);
  for (int y0 = 0; y0 + tile_px <= image.height; y0 += tile_px) {
    for (int x0 = 0; x0 + tile_px <= image.width; x0 += tile_px) {
      px.clear();
      for (int y = y0; y < y0 + tile_px; ++y) {
        for (int x = x0; x < x0 + tile_px; ++x) px.push_back(image.at(x, y));
      }
      t.median_adu.push_back(Median(px));
      t.dx_px.push_back(x0 + 0.5 * (tile_px - 1) - xc), t.dy_px.push_back(y0 + 0.5 * (tile_px - 1) - yc);
    }
  }
  return t;
}

double StructureOf(const TileMedians& t) {
  const std::vector<double>& medians = t.median_adu;
  if (medians.size() < 2) return 0.0;
  const double m = Median(medians);
  double ss = 0;
  for (double v : medians) ss += (v - m) * (v - m);
  return std::sqrt(ss / medians.size());
}

BackgroundPlane PlaneOf(const TileMedians& t, int width, int height) {
  BackgroundPlane p;
  const std::vector<double>&med = t.median_adu, &dx = t.dx_px, &dy = t.dy_px;
  const double xc = 0.5 * (width - 1), yc = 0.5 * (height - 1);
  const double r_corner2 = 0.25 * (double(width) * width + double(height) * height);
  const int n = static_cast<int>(med.size());
  // (L + gx dx + gy dy)(1 - v u) = L + gx dx + gy dy + c u + (gx' dx + gy' dy) u: linear in the six
  // coefficients, the last two absorbing the vignetted gradient's cubic part.
  if (n < 7) return p;
  Eigen::MatrixXd a(n, 6);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) {
    const double u = (dx[i] * dx[i] + dy[i] * dy[i]) / r_corner2;
    a(i, 0) = 1, a(i, 1) = dx[i], a(i, 2) = dy[i], a(i, 3) = u, a(i, 4) = dx[i] * u, a(i, 5) = dy[i] * u;
    b(i) = med[i];
  }
  const Eigen::VectorXd c = a.colPivHouseholderQr().solve(b);
  if (!c.allFinite()) return p;
  p.ok = true;
  p.level_adu = c(0), p.gx_adu_per_px = c(1), p.gy_adu_per_px = c(2), p.radial_adu = c(3);
  p.amplitude_adu = std::abs(c(1)) * xc + std::abs(c(2)) * yc;
  p.angle_deg = std::atan2(c(2), c(1)) * kRadToDeg;
  p.residual_rms_adu = std::sqrt((a * c - b).squaredNorm() / n);
  return p;
}

}  // namespace

double BackgroundStructureAdu(const ImageView& image, int tile_px) {
  return StructureOf(MeasureTileMedians(image, tile_px));
}

BackgroundPlane FitBackgroundPlane(const ImageView& image, int tile_px) {
  return PlaneOf(MeasureTileMedians(image, tile_px), image.width, image.height);
}

FieldFigures MeasureFieldFigures(const SolvedFrameSet& set, const std::vector<ImageView>& images, const Camera& camera,
                                 int tile_px) {
  FieldFigures f;
  f.frames = static_cast<int>(set.status.size());
  f.frames_solved = static_cast<int>(set.q.size());
  f.stars = static_cast<int>(set.stars.size());
  // ln(flux) = c + b V, one 4-sigma clipping pass.
  std::vector<double> m, y;
  double usum = 0;
  for (const auto& s : set.stars) {
    if (s.flux > 0) {
      m.push_back(s.mag), y.push_back(std::log(s.flux));
      usum += VignettingRadius2(camera, s.x_px, s.y_px);
    }
  }
  if (!m.empty()) f.star_u_mean = usum / m.size();
  std::vector<bool> keep(m.size(), true);
  const double to_mag = 2.5 / std::log(10.0);
  for (int pass = 0; pass < 2 && m.size() >= 5; ++pass) {
    double n = 0, mm = 0, my = 0;
    for (size_t i = 0; i < m.size(); ++i) {
      if (keep[i]) n += 1, mm += m[i], my += y[i];
    }
    mm /= n, my /= n;
    double smm = 0, smy = 0;
    for (size_t i = 0; i < m.size(); ++i) {
      if (keep[i]) smm += (m[i] - mm) * (m[i] - mm), smy += (m[i] - mm) * (y[i] - my);
    }
    if (!(smm > 0)) break;
    const double b = smy / smm, c = my - b * mm;
    double ss = 0;
    for (size_t i = 0; i < m.size(); ++i) {
      if (keep[i]) ss += std::pow(y[i] - c - b * m[i], 2);
    }
    const double s = std::sqrt(ss / std::max(1.0, n - 2));
    f.zero_point_adu = std::exp(c);
    f.flux_slope = -b / (0.4 * std::log(10.0));
    f.flux_scatter_mag = s * to_mag;
    for (size_t i = 0; i < m.size(); ++i) keep[i] = std::abs(y[i] - c - b * m[i]) <= 4 * s;
  }
  {
    double sum = 0;
    int n = 0;
    for (size_t i = 0; i < m.size(); ++i) {
      if (keep[i]) sum += y[i] + 0.4 * std::log(10.0) * m[i], ++n;
    }
    if (n > 0) f.zero_point_slope1_adu = std::exp(sum / n);
  }
  // PSF: medians of the stamp fits.
  std::vector<double> sig, e1, e2, u;
  for (const auto& s : set.stars) {
    if (s.stamp.empty()) continue;
    const SpotFit fit = FitSpot(s.stamp, s.stamp_half, s.x_px - s.stamp_x0, s.y_px - s.stamp_y0,
                                s.psf_sigma_px > 0 ? s.psf_sigma_px : 1.0);
    if (!fit.ok || !(fit.t_px2 > 0.02) || std::sqrt(fit.t_var) > 0.3 * fit.t_px2) continue;
    sig.push_back(std::sqrt(fit.t_px2)), e1.push_back(fit.e1), e2.push_back(fit.e2);
    u.push_back(VignettingRadius2(camera, s.x_px, s.y_px));
  }
  f.psf_stars = static_cast<int>(sig.size());
  f.psf_sigma_px = Median(sig), f.psf_e1 = Median(e1), f.psf_e2 = Median(e2);
  {  // ellipticity 1 - b/a from |e| = (a^2 - b^2) / (a^2 + b^2): b/a = sqrt((1 - |e|) / (1 + |e|))
    const double e = std::min(0.99, std::hypot(f.psf_e1, f.psf_e2));
    f.psf_ellipticity = 1 - std::sqrt((1 - e) / (1 + e));
    f.psf_angle_deg = 0.5 * std::atan2(f.psf_e2, f.psf_e1) * kRadToDeg;
  }
  if (sig.size() >= 8 && *std::max_element(u.begin(), u.end()) - *std::min_element(u.begin(), u.end()) > 0.2) {
    // sigma = c0 + c1 u, least squares, then once more without the points beyond 3.5 robust sigmas.
    std::vector<bool> keep(sig.size(), true);
    double c0 = 0, c1 = 0, se1 = 0;
    for (int pass = 0; pass < 2; ++pass) {
      double n = 0, su = 0, ss = 0, suu = 0, sus = 0;
      for (size_t i = 0; i < sig.size(); ++i) {
        if (keep[i]) n += 1, su += u[i], ss += sig[i], suu += u[i] * u[i], sus += u[i] * sig[i];
      }
      const double det = n * suu - su * su;
      if (!(det > 0)) break;
      c1 = (n * sus - su * ss) / det, c0 = (ss - c1 * su) / n;
      std::vector<double> res;
      for (size_t i = 0; i < sig.size(); ++i) res.push_back(sig[i] - c0 - c1 * u[i]);
      // Slope's standard error (OLS, residual RMS of the points fitted / sqrt(sum (u - mean u)^2)).
      double rss = 0;
      for (size_t i = 0; i < sig.size(); ++i) rss += keep[i] ? res[i] * res[i] : 0.0;
      se1 = std::sqrt(rss / std::max(1.0, n - 2) * n / det);
      const double rs = RobustSigma(res);
      for (size_t i = 0; i < sig.size(); ++i) keep[i] = std::abs(res[i]) <= 3.5 * rs;
    }
    f.psf_sigma_centre_px = c0, f.psf_sigma_corner_px = c0 + c1, f.psf_sigma_change_se_px = se1;
  }
  f.background_adu = Median(set.background_adu);
  f.noise_adu = Median(set.noise_adu);
  std::vector<double> st, amp, resid, radial, vig, centre;
  double ux = 0, uy = 0;
  int planes = 0;
  for (int idx : set.solved_index) {
    const TileMedians tiles = MeasureTileMedians(images[idx], tile_px);  // once for both figures
    st.push_back(StructureOf(tiles));
    const BackgroundPlane p = PlaneOf(tiles, images[idx].width, images[idx].height);
    if (!p.ok) continue;
    amp.push_back(p.amplitude_adu), resid.push_back(p.residual_rms_adu), radial.push_back(p.radial_adu);
    centre.push_back(p.level_adu);
    if (p.level_adu > 0) vig.push_back(-p.radial_adu / p.level_adu);
    ux += std::cos(p.angle_deg * kDegToRad), uy += std::sin(p.angle_deg * kDegToRad);
    ++planes;
  }
  f.background_structure_adu = Median(st);
  if (planes > 0) {
    f.background_gradient_adu = Median(amp);
    f.background_gradient_angle_deg = std::atan2(uy, ux) * kRadToDeg;
    f.background_gradient_coherence = std::hypot(ux, uy) / planes;
    f.background_plane_residual_adu = Median(resid);
    f.background_radial_adu = Median(radial);
    f.background_vignetting = Median(vig);
    f.background_centre_adu = Median(centre);
  }
  return f;
}

FrameComparison CompareWithSimulation(const SolvedFrameSet& measured, const std::vector<ImageView>& measured_images,
                                      const Camera& camera, const StarCatalog& sky, const StarIdentifier& id,
                                      const SolveOptions& solve, const FrameCompareOptions& o) {
  o.Check();
  FrameComparison c;
  c.measured = MeasureFieldFigures(measured, measured_images, camera, o.tile_px);
  std::vector<Image16> imgs;
  std::vector<std::string> names;
  for (size_t k = 0; k < measured.q.size(); ++k) {
    imgs.push_back(SimulateFrame(camera, sky, measured.q[k], o.sim, o.seed + k).image);
    names.push_back("sim" + std::to_string(k));
  }
  std::vector<ImageView> views;
  for (const auto& im : imgs) views.push_back(im.view());
  SolveOptions so = solve;
  so.detect.saturation_adu = (1 << o.sim.bit_depth) - 1;
  const SolvedFrameSet sim = SolveFrameSet(id, views, names, camera, so);
  c.simulated = MeasureFieldFigures(sim, views, camera, o.tile_px);
  c.simulated_solved = static_cast<int>(sim.q.size());
  for (size_t j = 0; j < sim.q.size(); ++j) {
    c.attitude_error_arcsec.push_back(AttitudeErrorRad(sim.q[j], measured.q[sim.solved_index[j]]) * kRadToArcsec);
  }
  c.attitude_error_median_arcsec = Median(c.attitude_error_arcsec);
  // Star pairs: the same catalog direction in the measured frame and its simulation.
  const double cos_tol = std::cos(o.match_radius_px / camera.FocalMinPx());
  std::vector<double> dpos, dmag;
  for (const auto& ms : measured.stars) {
    for (const auto& ss : sim.stars) {
      if (sim.solved_index[ss.frame] != ms.frame || ms.r_inertial.dot(ss.r_inertial) < cos_tol) continue;
      if (std::hypot(ms.x_px - ss.x_px, ms.y_px - ss.y_px) > o.match_radius_px) continue;
      StarPair p;
      p.frame = ms.frame, p.mag = ms.mag;
      p.x_measured_px = ms.x_px, p.y_measured_px = ms.y_px, p.x_simulated_px = ss.x_px, p.y_simulated_px = ss.y_px;
      p.flux_measured_adu = ms.flux, p.flux_simulated_adu = ss.flux;
      p.sigma_measured_px = ms.psf_sigma_px, p.sigma_simulated_px = ss.psf_sigma_px;
      c.pairs.push_back(p);
      dpos.push_back(std::pow(ms.x_px - ss.x_px, 2) + std::pow(ms.y_px - ss.y_px, 2));
      if (ms.flux > 0 && ss.flux > 0) dmag.push_back(-2.5 * std::log10(ms.flux / ss.flux));
      break;
    }
  }
  if (!dpos.empty()) {
    double ss = 0;
    for (double v : dpos) ss += v;
    c.position_rms_px = std::sqrt(ss / (2.0 * dpos.size()));
  }
  if (!dmag.empty()) {
    c.flux_ratio_median = std::pow(10, -0.4 * Median(dmag));
    c.flux_ratio_scatter_mag = RobustSigma(dmag);
  }
  return c;
}

FrameSimOptions FitSimOptions(const FieldFigures& m, const FrameSimOptions& base) {
  FrameSimOptions f = base;
  // The field law only when the change is significant (3 standard errors); else the median width.
  if (m.psf_sigma_centre_px > 0.1 && m.psf_sigma_corner_px > 0.1 && m.psf_sigma_centre_px < 50 &&
      m.psf_sigma_corner_px < 50 &&
      std::abs(m.psf_sigma_corner_px - m.psf_sigma_centre_px) > 3 * m.psf_sigma_change_se_px) {
    f.psf_sigma_px = m.psf_sigma_centre_px;
    f.psf_sigma_corner_px = m.psf_sigma_corner_px;
  } else if (m.psf_sigma_px > 0.1) {
    f.psf_sigma_px = m.psf_sigma_px;
    f.psf_sigma_corner_px = 0;
  }
  if (m.psf_stars > 0) {
    f.psf_ellipticity = std::clamp(m.psf_ellipticity, 0.0, 0.95);
    f.psf_angle_deg = m.psf_angle_deg;
  }
  if (m.zero_point_slope1_adu > 0)
    f.mag0_flux_e_per_s = m.zero_point_slope1_adu * base.gain_e_per_adu / base.exposure_s;
  // Level = bias + sky; the sky is the gradient's amplitude (the least that keeps it >= 0 everywhere),
  // or with a vignetted sky the whole level.
  const bool vignetted = m.background_vignetting > 0.02 && m.background_vignetting < 1 && m.background_centre_adu > 0;
  const double level = std::max(0.0, vignetted ? m.background_centre_adu : m.background_adu);
  const double g_adu = std::clamp(m.background_gradient_adu, 0.0, level);
  const double sky_adu = vignetted ? level : g_adu;
  f.bias_adu = level - sky_adu;
  f.background_e_per_s = sky_adu * base.gain_e_per_adu / base.exposure_s;
  f.background_gradient_e_per_s = g_adu * base.gain_e_per_adu / base.exposure_s;
  f.background_gradient_angle_deg = m.background_gradient_angle_deg;
  f.dark_current_e_per_s = 0;
  f.vignetting = vignetted ? m.background_vignetting : 0.0;
  if (vignetted) f.mag0_flux_e_per_s /= std::max(0.05, 1 - f.vignetting * m.star_u_mean);
  if (m.noise_adu > 0) {
    const double sky_shot_e2 = base.shot_noise ? sky_adu * base.gain_e_per_adu : 0.0;
    f.read_noise_e = std::sqrt(std::max(0.0, std::pow(m.noise_adu * base.gain_e_per_adu, 2) - sky_shot_e2));
  }
  return f;
}

Json FieldFiguresToJson(const FieldFigures& f) {
  return Json{{"frames", f.frames},
              {"frames_solved", f.frames_solved},
              {"stars", f.stars},
              {"zero_point_adu_v0", f.zero_point_adu},
              {"flux_slope", f.flux_slope},
              {"zero_point_slope1_adu_v0", f.zero_point_slope1_adu},
              {"flux_scatter_mag", f.flux_scatter_mag},
              {"psf_sigma_px", f.psf_sigma_px},
              {"psf_e1", f.psf_e1},
              {"psf_e2", f.psf_e2},
              {"psf_stars", f.psf_stars},
              {"psf_ellipticity", f.psf_ellipticity},
              {"psf_angle_deg", f.psf_angle_deg},
              {"psf_sigma_centre_px", f.psf_sigma_centre_px},
              {"psf_sigma_corner_px", f.psf_sigma_corner_px},
              {"psf_sigma_change_se_px", f.psf_sigma_change_se_px},
              {"background_adu", f.background_adu},
              {"background_structure_adu", f.background_structure_adu},
              {"background_gradient_adu", f.background_gradient_adu},
              {"background_gradient_angle_deg", f.background_gradient_angle_deg},
              {"background_gradient_coherence", f.background_gradient_coherence},
              {"background_plane_residual_adu", f.background_plane_residual_adu},
              {"background_radial_adu", f.background_radial_adu},
              {"background_vignetting", f.background_vignetting},
              {"background_centre_adu", f.background_centre_adu},
              {"star_u_mean", f.star_u_mean},
              {"noise_adu", f.noise_adu}};
}

Json FrameComparisonToJson(const FrameComparison& c) {
  Json j;
  j["measured"] = FieldFiguresToJson(c.measured);
  j["simulated"] = FieldFiguresToJson(c.simulated);
  j["star_pairs"] = c.pairs.size();
  j["position_rms_px"] = c.position_rms_px;
  j["flux_ratio_median"] = c.flux_ratio_median;
  j["flux_ratio_scatter_mag"] = c.flux_ratio_scatter_mag;
  j["simulated_solved"] = c.simulated_solved;
  j["attitude_error_median_arcsec"] = c.attitude_error_median_arcsec;
  j["pairs"] = Json::array();
  for (const auto& p : c.pairs) {
    j["pairs"].push_back({{"frame", p.frame},
                          {"mag", p.mag},
                          {"measured_px", {p.x_measured_px, p.y_measured_px}},
                          {"simulated_px", {p.x_simulated_px, p.y_simulated_px}},
                          {"flux_measured_adu", p.flux_measured_adu},
                          {"flux_simulated_adu", p.flux_simulated_adu},
                          {"sigma_measured_px", p.sigma_measured_px},
                          {"sigma_simulated_px", p.sigma_simulated_px}});
  }
  return j;
}

Json FrameSimOptionsDiff(const FrameSimOptions& base, const FrameSimOptions& fitted) {
  const Json a = FrameSimOptionsToJson(base), b = FrameSimOptionsToJson(fitted);
  Json d = Json::object();
  for (auto it = b.begin(); it != b.end(); ++it) {
    if (!a.contains(it.key()) || a[it.key()] != it.value()) d[it.key()] = it.value();
  }
  return d;
}

void WriteComparePlots(const std::string& dir, const std::string& prefix, const FrameComparison& c,
                       const Camera& camera, const std::string& title) {
  // One figure of the measured (red) and simulated (blue) values of the same stars against x; a
  // value <= 0 (not measured) is left out.
  using Pick = double (*)(const StarPair&, const Camera&);
  auto scatter = [&](const std::string& file, Pick x_of, Pick measured, Pick simulated, PlotOptions po) {
    PlotSeries ms, ss;
    ms.label = "measured", ss.label = "simulated";
    ms.color = {200, 40, 40}, ss.color = {40, 70, 200};
    ms.line = ss.line = false;
    ms.markers = ss.markers = true;
    for (const auto& p : c.pairs) {
      const double x = x_of(p, camera), m = measured(p, camera), s = simulated(p, camera);
      if (m > 0) ms.x.push_back(x), ms.y.push_back(m);
      if (s > 0) ss.x.push_back(x), ss.y.push_back(s);
    }
    if (!ms.x.empty()) WritePlotPng(dir + "/" + prefix + file, {ms, ss}, po);
  };
  PlotOptions flux;
  flux.log_y = true;
  flux.title = title + ": flux vs catalog V, same stars";
  flux.x_label = "V (mag)";
  flux.y_label = "flux (ADU)";
  scatter(
      "_flux.png", [](const StarPair& p, const Camera&) { return p.mag; },
      [](const StarPair& p, const Camera&) { return p.flux_measured_adu; },
      [](const StarPair& p, const Camera&) { return p.flux_simulated_adu; }, flux);
  PlotOptions sigma;
  sigma.title = title + ": spot sigma (detector fit) vs field radius";
  sigma.x_label = "distance from the principal point (px)";
  sigma.y_label = "sigma (px)";
  scatter(
      "_sigma.png",
      [](const StarPair& p, const Camera& cam) {
        return std::hypot(p.x_measured_px - cam.cx_px, p.y_measured_px - cam.cy_px);
      },
      [](const StarPair& p, const Camera&) { return p.sigma_measured_px; },
      [](const StarPair& p, const Camera&) { return p.sigma_simulated_px; }, sigma);
}

}  // namespace ssiu
