#include "groundtest/performance.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <filesystem>
#include <limits>
#include <unsupported/Eigen/FFT>

#include "attitude/quest.h"
#include "core/csv.h"
#include "core/error.h"
#include "core/rng.h"
#include "groundtest/stand.h"
#include "inertial/propagate.h"
#include "plot/plot.h"

namespace ssiu {
namespace {

double Interpolate(const std::vector<double>& t, const std::vector<double>& v, double x) {
  const auto it = std::upper_bound(t.begin(), t.end(), x);
  if (it == t.begin()) return v.front();
  if (it == t.end()) return v.back();
  const size_t k = it - t.begin();
  const double a = (x - t[k - 1]) / (t[k] - t[k - 1]);
  return v[k - 1] + a * (v[k] - v[k - 1]);
}

double Alias(double f, double fs) { return std::abs(f - fs * std::round(f / fs)); }

enum class Band { kFov, kPixel, kNoise };

}  // namespace

void PerformanceOptions::Check() const {
  if (!(fov_band_crossings > 0) || !std::isfinite(fov_band_crossings))
    throw InputError("performance options", "fov_band_crossings must be a finite number > 0");
  if (pixel_harmonics < 1 || pixel_harmonics > 10)
    throw InputError("performance options", "pixel_harmonics must be 1-10");
  if (!(time_tolerance_s >= 0)) throw InputError("performance options", "time_tolerance_s must be >= 0");
}

TemperatureLog ReadTemperatureLog(const std::string& path) {
  const CsvTable t = ReadCsv(path);
  if (t.rows() < 2) throw InputError(path, "needs at least 2 rows (t_s, temp_c)");
  t.CheckIncreasing("t_s");
  return {path, t.Column("t_s"), t.Column("temp_c")};
}

PerformanceReport AnalysePerformance(const std::vector<AttitudeSample>& measured,
                                     const std::vector<AttitudeSample>& reference, const Camera& camera,
                                     const TemperatureLog& temperature, const PerformanceOptions& options) {
  options.Check();
  camera.Check();
  PerformanceReport r;
  // Pairs by time: the reference sample nearest each measured one.
  std::vector<Quat> q_ref, q_meas;
  for (const AttitudeSample& m : measured) {
    const auto it = std::lower_bound(reference.begin(), reference.end(), m.t_s,
                                     [](const AttitudeSample& a, double t) { return a.t_s < t; });
    const AttitudeSample* best = nullptr;
    if (it != reference.end()) best = &*it;
    if (it != reference.begin() && (!best || m.t_s - (it - 1)->t_s < best->t_s - m.t_s)) best = &*(it - 1);
    if (!best || std::abs(best->t_s - m.t_s) > options.time_tolerance_s) continue;
    r.t_s.push_back(m.t_s);
    q_ref.push_back(best->q);
    q_meas.push_back(m.q);
  }
  const size_t n = r.t_s.size();
  r.samples = static_cast<int>(n);
  if (n < 64) throw InputError("--measured", std::to_string(n) + " attitudes pair with the reference (need 64)");
  std::vector<double> dt(n - 1);
  for (size_t k = 1; k < n; ++k) dt[k - 1] = r.t_s[k] - r.t_s[k - 1];
  std::vector<double> sorted = dt;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double dt_med = sorted[sorted.size() / 2];
  for (size_t k = 0; k < dt.size(); ++k)
    if (dt[k] > 1.5 * dt_med)
      throw InputError("--measured", "a gap of " + std::to_string(dt[k]) + " s at t_s = " + std::to_string(r.t_s[k]) +
                                         ": the spectral split needs evenly spaced samples");
  r.sample_rate_hz = 1.0 / dt_med;
  r.span_s = r.t_s.back() - r.t_s.front();

  // The reference's mean rate (sensor axes) and the star image motion it causes near the boresight.
  Vec3 w = Vec3::Zero();
  for (size_t k = 1; k < n; ++k) w += RotationVector(q_ref[k - 1].conjugate() * q_ref[k]);
  r.rate_rad_s = w / (r.t_s.back() - r.t_s.front());
  r.star_velocity_px_s = Vec2(-r.rate_rad_s.y() * camera.FocalXPx(), r.rate_rad_s.x() * camera.FocalYPx());
  const double v = r.star_velocity_px_s.norm();
  if (!(v * r.span_s > 1.0))
    throw InputError("--reference",
                     "the stars move less than a pixel over the test: no crossing frequencies "
                     "(a slow slew across the field is needed)");
  const Vec2 u = r.star_velocity_px_s / v;
  const double inf = std::numeric_limits<double>::infinity();
  const double length_px =
      std::min(u.x() != 0 ? camera.width / std::abs(u.x()) : inf, u.y() != 0 ? camera.height / std::abs(u.y()) : inf);
  r.field_crossing_hz = v / length_px;
  r.pixel_crossing_hz = r.star_velocity_px_s.cwiseAbs();
  r.fov_band_hz = options.fov_band_crossings * r.field_crossing_hz;
  const double nyquist = r.sample_rate_hz / 2;
  if (r.fov_band_hz >= nyquist) r.warnings.push_back("the FOV band reaches the Nyquist frequency: no noise bins");
  if (std::abs(r.rate_rad_s.z()) * length_px / 2 > 0.2 * v)
    r.warnings.push_back(
        "the roll rate moves stars at the field's edge by more than 20% of the slew's image "
        "velocity: crossing frequencies are spread");
  for (int m = 1; m <= options.pixel_harmonics; ++m) {
    for (int a = 0; a < 2; ++a) {
      const double f = m * r.pixel_crossing_hz[a];
      if (f <= r.fov_band_hz) continue;  // a slow axis: its pixel pattern is a FOV-like error
      const double c = Alias(f, r.sample_rate_hz);
      if (c <= r.fov_band_hz) {
        r.warnings.push_back("pixel-crossing harmonic " + std::to_string(m) + " (" + std::to_string(f) +
                             " Hz) aliases into the FOV band at this sample rate: counted as FOV error");
        continue;
      }
      const bool known = std::any_of(r.pixel_band_centres_hz.begin(), r.pixel_band_centres_hz.end(),
                                     [&](double x) { return std::abs(x - c) < 1e-6 * r.sample_rate_hz; });
      if (!known) r.pixel_band_centres_hz.push_back(c);  // x and y cross pixels at one rate on a diagonal slew
    }
  }

  // Errors, temperature, thermo-elastic regression.
  for (size_t k = 0; k < n; ++k) r.error_rad.push_back(RotationVector(q_ref[k].conjugate() * q_meas[k]));
  Vec3 mean = Vec3::Zero();
  for (const Vec3& e : r.error_rad) mean += e;
  mean /= n;
  r.bias_rad = mean;
  r.thermal_rad.assign(n, Vec3::Zero());
  if (!temperature.t_s.empty()) {
    if (temperature.t_s.front() > r.t_s.front() + dt_med || temperature.t_s.back() < r.t_s.back() - dt_med)
      throw InputError(temperature.file, "does not cover the test (t_s " + std::to_string(r.t_s.front()) + " to " +
                                             std::to_string(r.t_s.back()) + ")");
    for (double t : r.t_s) r.temp_c.push_back(Interpolate(temperature.t_s, temperature.temp_c, t));
    double t_mean = 0;
    for (double x : r.temp_c) t_mean += x;
    t_mean /= n;
    double var_t = 0;
    Vec3 cov = Vec3::Zero();
    for (size_t k = 0; k < n; ++k) {
      var_t += (r.temp_c[k] - t_mean) * (r.temp_c[k] - t_mean);
      cov += (r.temp_c[k] - t_mean) * (r.error_rad[k] - mean);
    }
    r.temperature_sigma_c = std::sqrt(var_t / n);
    if (var_t > 0) {
      r.thermoelastic_rad_per_c = cov / var_t;  // least squares e = a + k (T - mean T)
      r.thermoelastic_rad = r.thermoelastic_rad_per_c.cwiseAbs() * r.temperature_sigma_c;
      for (size_t k = 0; k < n; ++k) r.thermal_rad[k] = r.thermoelastic_rad_per_c * (r.temp_c[k] - t_mean);
    } else {
      r.warnings.push_back(temperature.file + ": the temperature does not change: no thermo-elastic figure");
    }
  }

  // Band powers per axis.
  Eigen::FFT<double> fft;
  const size_t bins = n / 2 + 1;
  for (size_t k = 0; k < bins; ++k) r.freq_hz.push_back(k * r.sample_rate_hz / n);
  std::vector<Band> band(bins, Band::kNoise);
  size_t n_fov = 0, n_pix = 0, n_noise = 0;  // one-sided bins per band
  for (size_t k = 0; k < bins; ++k) {
    const double f = r.freq_hz[k];
    if (f <= r.fov_band_hz)
      band[k] = Band::kFov;
    else
      for (double c : r.pixel_band_centres_hz)
        if (std::abs(f - c) <= r.fov_band_hz) band[k] = Band::kPixel;
    (band[k] == Band::kFov ? n_fov : band[k] == Band::kPixel ? n_pix : n_noise)++;
  }
  if (n_noise == 0) r.warnings.push_back("no frequency bin outside the FOV and pixel bands: temporal noise unknown");
  r.power_rad2.assign(bins, Vec3::Zero());
  r.fov_rad.assign(n, Vec3::Zero());
  r.pixel_rad.assign(n, Vec3::Zero());
  r.noise_rad.assign(n, Vec3::Zero());
  for (int a = 0; a < 3; ++a) {
    // No taper: a window weights the middle of the test more than its ends, which biases every figure
    // when the noise or the spatial errors change along the test (the number of stars in view does);
    // the bands are wide enough that the plain periodogram's sidelobes (1/f^2) stay in them.
    std::vector<double> x(n);
    for (size_t k = 0; k < n; ++k) x[k] = r.error_rad[k][a] - mean[a] - r.thermal_rad[k][a];
    std::vector<std::complex<double>> spec;
    fft.fwd(spec, x);
    double fov = 0, pix = 0;
    std::vector<double> noise_bins, upper_noise_bins;
    for (size_t k = 0; k < bins; ++k) {
      double p = std::norm(spec[k]) / (static_cast<double>(n) * n);  // two-sided bins sum to the variance
      if (k != 0 && 2 * k != n) p *= 2;                              // one-sided
      r.power_rad2[k][a] = p;
      if (band[k] == Band::kFov)
        fov += p;
      else if (band[k] == Band::kPixel)
        pix += p;
      else
        (r.freq_hz[k] > nyquist / 2 ? upper_noise_bins : noise_bins).push_back(p);
    }
    if (upper_noise_bins.size() >= 100)
      noise_bins.swap(upper_noise_bins);
    else
      noise_bins.insert(noise_bins.end(), upper_noise_bins.begin(), upper_noise_bins.end());
    // The white floor: the median of the noise bins over ln 2 (a periodogram bin of white noise is
    // exponentially distributed, median = ln 2 x mean), from the bins above half the Nyquist frequency
    // when there are 100 of them: the spatial errors change in steps (stars enter and leave the field)
    // whose 1/f^2 tails are lowest there, and the median is not moved by the few bins they still lift.
    double floor = 0;
    if (!noise_bins.empty()) {
      std::nth_element(noise_bins.begin(), noise_bins.begin() + noise_bins.size() / 2, noise_bins.end());
      floor = noise_bins[noise_bins.size() / 2] / std::log(2.0);
    }
    r.temporal_noise_rad[a] = std::sqrt(floor * bins);
    // A band's power above the floor counts when it exceeds 3 sigma of what white noise alone puts in
    // that many bins: a sum of n independent (exponential) periodogram bins has a standard deviation of
    // floor sqrt(n).
    auto above_floor = [&](double power, size_t n_bins, double* limit) {
      const double three_sigma = 3 * floor * std::sqrt(static_cast<double>(n_bins));
      *limit = std::sqrt(three_sigma);
      const double excess = power - floor * n_bins;
      return excess > three_sigma ? std::sqrt(excess) : 0.0;
    };
    r.fov_spatial_rad[a] = above_floor(fov, n_fov, &r.fov_limit_rad[a]);
    r.pixel_spatial_rad[a] = above_floor(pix, n_pix, &r.pixel_limit_rad[a]);
    // The parts over time for the plots: the spectrum masked to each band.
    const std::vector<std::complex<double>>& full = spec;
    for (Band b : {Band::kFov, Band::kPixel, Band::kNoise}) {
      std::vector<std::complex<double>> masked(full.size(), 0.0);
      for (size_t k = 0; k < full.size(); ++k) {
        const size_t kk = k < bins ? k : n - k;
        if (band[kk] == b) masked[k] = full[k];
      }
      std::vector<double> part;
      fft.inv(part, masked);
      std::vector<Vec3>& out = b == Band::kFov ? r.fov_rad : b == Band::kPixel ? r.pixel_rad : r.noise_rad;
      for (size_t k = 0; k < n; ++k) out[k][a] = part[k];
    }
    double var = 0;
    for (size_t k = 0; k < n; ++k) var += std::pow(r.error_rad[k][a] - mean[a], 2);
    r.total_rad[a] = std::sqrt(var / n);
  }
  return r;
}

Json PerformanceReportToJson(const PerformanceReport& r) {
  auto arcsec = [](const Vec3& v) {
    return Json::array({v.x() * kRadToArcsec, v.y() * kRadToArcsec, v.z() * kRadToArcsec});
  };
  Json j;
  j["standard"] = "ECSS-E-ST-60-20C";
  j["axes"] = Json::array({"x", "y", "roll"});
  j["bias_arcsec"] = arcsec(r.bias_rad);
  j["temporal_noise_arcsec"] = arcsec(r.temporal_noise_rad);
  j["fov_spatial_arcsec"] = arcsec(r.fov_spatial_rad);
  j["pixel_spatial_arcsec"] = arcsec(r.pixel_spatial_rad);
  j["thermoelastic_arcsec"] = arcsec(r.thermoelastic_rad);
  j["fov_spatial_limit_arcsec"] = arcsec(r.fov_limit_rad);
  j["pixel_spatial_limit_arcsec"] = arcsec(r.pixel_limit_rad);
  j["thermoelastic_arcsec_per_c"] = arcsec(r.thermoelastic_rad_per_c);
  j["temperature_sigma_c"] = r.temperature_sigma_c;
  j["total_sigma_arcsec"] = arcsec(r.total_rad);
  j["samples"] = r.samples;
  j["sample_rate_hz"] = r.sample_rate_hz;
  j["span_s"] = r.span_s;
  j["rate_deg_s"] =
      Json::array({r.rate_rad_s.x() * kRadToDeg, r.rate_rad_s.y() * kRadToDeg, r.rate_rad_s.z() * kRadToDeg});
  j["star_velocity_px_s"] = Json::array({r.star_velocity_px_s.x(), r.star_velocity_px_s.y()});
  j["field_crossing_hz"] = r.field_crossing_hz;
  j["pixel_crossing_hz"] = Json::array({r.pixel_crossing_hz.x(), r.pixel_crossing_hz.y()});
  j["fov_band_hz"] = r.fov_band_hz;
  j["pixel_band_centres_hz"] = r.pixel_band_centres_hz;
  j["warnings"] = r.warnings;
  return j;
}

void WritePerformancePlots(const PerformanceReport& r, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (!std::filesystem::is_directory(dir, ec)) throw InputError(dir, "cannot create the plot directory");
  const PlotColor black{0, 0, 0}, red{200, 40, 40}, blue{40, 70, 200}, green{30, 150, 60}, grey{150, 150, 150},
      orange{230, 130, 20};
  const char* axis_name[] = {"x", "y", "roll"};
  for (int a = 0; a < 3; ++a) {
    auto series = [&](const std::string& label, const std::vector<Vec3>& v, PlotColor c, double offset) {
      PlotSeries s;
      s.label = label, s.x = r.t_s, s.color = c, s.thickness_px = 1;
      for (const Vec3& e : v) s.y.push_back((e[a] + offset) * kRadToArcsec);
      return s;
    };
    PlotOptions po;
    po.x_label = "time (s)";
    po.y_label = std::string("error about ") + axis_name[a] + " (arcsec)";
    po.title = std::string("Attitude error and its ECSS parts, ") + axis_name[a];
    PlotSeries bias;
    bias.label = "bias", bias.x = {r.t_s.front(), r.t_s.back()},
    bias.y = {r.bias_rad[a] * kRadToArcsec, r.bias_rad[a] * kRadToArcsec}, bias.color = black, bias.dashed = true;
    WritePlotPng(
        dir + "/error_parts_" + axis_name[a] + ".png",
        {series("error", r.error_rad, grey, 0), bias, series("thermo-elastic", r.thermal_rad, orange, r.bias_rad[a]),
         series("FOV spatial", r.fov_rad, red, 0), series("pixel spatial", r.pixel_rad, blue, 0),
         series("temporal noise", r.noise_rad, green, 0)},
        po);
  }
  PlotOptions ps;
  ps.log_y = true;
  ps.x_label = "frequency (Hz)";
  ps.y_label = "power per bin (arcsec^2)";
  ps.title = "Periodogram of the residual, FOV band and pixel bands";
  std::vector<PlotSeries> spec;
  const PlotColor colors[] = {red, blue, green};
  double top = 0;
  for (int a = 0; a < 3; ++a) {
    PlotSeries s;
    s.label = axis_name[a], s.color = colors[a], s.thickness_px = 1;
    for (size_t k = 1; k < r.freq_hz.size(); ++k) {
      s.x.push_back(r.freq_hz[k]);
      s.y.push_back(std::max(r.power_rad2[k][a] * kRadToArcsec * kRadToArcsec, 1e-12));
      top = std::max(top, s.y.back());
    }
    spec.push_back(s);
  }
  auto vline = [&](const std::string& label, double f, PlotColor c) {
    PlotSeries s;
    s.label = label, s.x = {f, f}, s.y = {top * 1e-8, top}, s.color = c, s.dashed = true;
    return s;
  };
  spec.push_back(vline("FOV band edge", r.fov_band_hz, black));
  for (size_t i = 0; i < r.pixel_band_centres_hz.size(); ++i)
    spec.push_back(vline(i == 0 ? "pixel crossing" : "", r.pixel_band_centres_hz[i], orange));
  WritePlotPng(dir + "/spectrum.png", spec, ps);
  if (!r.temp_c.empty()) {
    PlotOptions pt;
    pt.x_label = "temperature (C)";
    pt.y_label = "error (arcsec)";
    pt.title = "Error against temperature, with the thermo-elastic fit";
    std::vector<PlotSeries> tv;
    for (int a = 0; a < 3; ++a) {
      PlotSeries s, fit;
      s.label = axis_name[a], s.x = r.temp_c, s.color = colors[a], s.line = false, s.markers = true;
      fit.x = r.temp_c, fit.color = colors[a], fit.line = true;
      for (size_t k = 0; k < r.t_s.size(); ++k) {
        s.y.push_back(r.error_rad[k][a] * kRadToArcsec);
        fit.y.push_back((r.bias_rad[a] + r.thermal_rad[k][a]) * kRadToArcsec);
      }
      tv.push_back(s);
      tv.push_back(fit);
    }
    WritePlotPng(dir + "/error_vs_temperature.png", tv, pt);
  }
}

SimulatedPerformance SimulatePerformance(const PerformanceSimulation& s) {
  Rng rng(s.seed);
  const Camera ideal = [&] {
    Camera c = s.camera;
    c.distortion = Distortion{};
    return c;
  }();
  Camera distorted = ideal;
  distorted.distortion.k1 = s.distortion_k1;
  // Stars near the slew's path only (uniform on the sphere elsewhere, never seen).
  const Quat q0 = Quat(Eigen::AngleAxisd(0.3, Vec3(1, 2, 3).normalized()));
  const Vec3 axis_inertial = q0 * (s.rate_rad_s.norm() > 0 ? s.rate_rad_s.normalized() : Vec3::UnitX());
  // The boresight sweeps a cone about the (inertially fixed) rate axis: stars within the field's half
  // diagonal of that cone can be seen.
  const double cone = std::acos(std::clamp(axis_inertial.dot(q0 * Vec3::UnitZ()), -1.0, 1.0));
  const double reach = ideal.FovDiagRad() / 2 + 0.02;
  const long n_all = std::lround(s.stars_per_deg2 * 41252.96);
  std::vector<Vec3> stars;
  for (long i = 0; i < n_all; ++i) {
    const double z = rng.Uniform(-1, 1), phi = rng.Uniform(0, 2 * kPi), rho = std::sqrt(1 - z * z);
    const Vec3 u(rho * std::cos(phi), rho * std::sin(phi), z);
    if (std::abs(std::acos(std::clamp(u.dot(axis_inertial), -1.0, 1.0)) - cone) < reach) stars.push_back(u);
  }
  SimulatedPerformance out;
  const int n = static_cast<int>(std::lround(s.duration_s * s.rate_hz));
  std::vector<Vec3> e_fov, e_pix, e_noise;
  std::vector<double> temps;
  for (int k = 0; k < n; ++k) {
    const double t = k / s.rate_hz;
    const Quat q_ref = q0 * QuatFromRotationVector(s.rate_rad_s * t);
    const double temp = 20 + (s.temp_period_s > 0 ? s.temp_amplitude_c * std::sin(2 * kPi * t / s.temp_period_s) : 0.0);
    std::vector<WahbaObservation> all, fov, pix, noise;
    for (const Vec3& u : stars) {
      const Vec3 d = q_ref.conjugate() * u;
      if (d.z() <= 0) continue;
      const auto p0 = ideal.Project(d);
      if (!p0 || !ideal.InImage(*p0, 2)) continue;
      const Vec2 pd = *distorted.Project(d);
      const Vec2 dpix(s.intra_pixel_px * std::sin(2 * kPi * p0->x()), s.intra_pixel_px * std::sin(2 * kPi * p0->y()));
      const Vec2 dn(s.noise_px * rng.Normal(), s.noise_px * rng.Normal());
      const double sigma = 1.0 / ideal.FocalMeanPx();
      all.push_back({ideal.Unproject(pd + dpix + dn), u, sigma});
      fov.push_back({ideal.Unproject(pd), u, sigma});
      pix.push_back({ideal.Unproject(*p0 + dpix), u, sigma});
      noise.push_back({ideal.Unproject(*p0 + dn), u, sigma});
    }
    if (all.size() < 3) continue;  // no solution at this sample (the sensor would report none)
    auto err = [&](const std::vector<WahbaObservation>& obs) {
      return RotationVector(q_ref.conjugate() * SolveQuest(obs).q_inertial_from_sensor);
    };
    const Vec3 mount = s.bias_rad + s.drift_rad_per_c * (temp - 20);
    const Quat q_meas = SolveQuest(all).q_inertial_from_sensor * QuatFromRotationVector(mount);
    out.reference.push_back({t, q_ref});
    out.measured.push_back({t, q_meas});
    out.temperature.t_s.push_back(t);
    out.temperature.temp_c.push_back(temp);
    e_fov.push_back(err(fov));
    e_pix.push_back(err(pix));
    e_noise.push_back(err(noise));
    temps.push_back(temp);
  }
  auto mean = [](const std::vector<Vec3>& v) {
    Vec3 m = Vec3::Zero();
    for (const Vec3& e : v) m += e;
    return Vec3(m / v.size());
  };
  auto sigma = [&](const std::vector<Vec3>& v) {
    const Vec3 m = mean(v);
    Vec3 q = Vec3::Zero();
    for (const Vec3& e : v) q += (e - m).cwiseProduct(e - m);
    return Vec3((q / v.size()).cwiseSqrt());
  };
  out.fov_rad = sigma(e_fov);
  out.pixel_rad = sigma(e_pix);
  out.noise_rad = sigma(e_noise);
  double tm = 0, tv = 0;
  for (double x : temps) tm += x;
  tm /= temps.size();
  for (double x : temps) tv += (x - tm) * (x - tm);
  out.thermal_rad = s.drift_rad_per_c.cwiseAbs() * std::sqrt(tv / temps.size());
  out.bias_rad = s.bias_rad + s.drift_rad_per_c * (tm - 20) + mean(e_fov) + mean(e_pix) + mean(e_noise);
  out.temperature.file = "simulated temperature";
  return out;
}

}  // namespace ssiu
