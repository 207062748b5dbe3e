// psf_shape and hot_pixels causes of `ssiu discover frames` (method in discover_frames.h).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "core/stats.h"
#include "core/types.h"
#include "discover/discover_frames_internal.h"

namespace ssiu {

using Eigen::Matrix2d;
using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::VectorXd;

SpotFit FitSpot(const std::vector<float>& stamp, int half, double x_guess, double y_guess, double sigma_guess_px,
                const double* fixed_c) {
  SpotFit out;
  const int w = 2 * half + 1;
  if (static_cast<int>(stamp.size()) != w * w || half < 2) return out;
  // Background guess: median of the border pixels; flux guess: the sum above it.
  std::vector<double> border;
  double sum = 0;
  int nvalid = 0;
  for (int y = 0; y < w; ++y) {
    for (int x = 0; x < w; ++x) {
      const float v = stamp[y * w + x];
      if (!std::isfinite(v)) continue;
      ++nvalid;
      sum += v;
      if (x == 0 || y == 0 || x == w - 1 || y == w - 1) border.push_back(v);
    }
  }
  const int np_free = fixed_c ? 4 : 7;
  if (border.size() < 4 || nvalid < np_free + 5) return out;
  const double b0 = Median(std::move(border));
  // Parameters: flux F, x0, y0, background B, precision matrix P = [[a, b], [b, c]] = C^-1.
  double p[7];
  p[0] = std::max(1.0, sum - b0 * nvalid);
  p[1] = x_guess, p[2] = y_guess, p[3] = b0;
  // Pixel integration by kSub x kSub midpoint sub-samples: they spread a pixel's light with variance
  // (1 - 1/kSub^2) / 12 instead of the box's 1/12, so the fitted covariance carries the missing
  // 1 / (12 kSub^2) px^2 (variances of convolved profiles add), removed from the output below.
  constexpr int kSub = 4;
  constexpr double kSubVar = 1.0 / (12.0 * kSub * kSub);
  if (fixed_c) {
    const double cxx = fixed_c[0] + kSubVar, cyy = fixed_c[1] + kSubVar, cxy = fixed_c[2];
    const double det = cxx * cyy - cxy * cxy;
    if (!(det > 0)) return out;
    p[4] = cyy / det, p[5] = -cxy / det, p[6] = cxx / det;
  } else {
    const double s2 = std::max(0.09, sigma_guess_px * sigma_guess_px);
    p[4] = 1 / s2, p[5] = 0, p[6] = 1 / s2;
  }
  auto eval = [&](const double* q, VectorXd* r, MatrixXd* jac) {
    const double a = q[4], b = q[5], c = q[6], det = a * c - b * b;
    if (!(det > 0) || !(a > 0)) return false;
    const double norm = std::sqrt(det) / (2 * M_PI) / (kSub * kSub);
    r->resize(nvalid);
    if (jac) jac->setZero(nvalid, 7);
    int k = 0;
    for (int y = 0; y < w; ++y) {
      for (int x = 0; x < w; ++x) {
        const float v = stamp[y * w + x];
        if (!std::isfinite(v)) continue;
        double g = 0, gx = 0, gy = 0, ga = 0, gb = 0, gc = 0;
        for (int sy = 0; sy < kSub; ++sy) {
          const double dy = y + (sy + 0.5) / kSub - 0.5 - q[2];
          for (int sx = 0; sx < kSub; ++sx) {
            const double dx = x + (sx + 0.5) / kSub - 0.5 - q[1];
            const double e = norm * std::exp(-0.5 * (a * dx * dx + 2 * b * dx * dy + c * dy * dy));
            g += e;
            if (jac) {
              gx += e * (a * dx + b * dy);
              gy += e * (b * dx + c * dy);
              ga += e * (c / (2 * det) - 0.5 * dx * dx);
              gb += e * (-b / det - dx * dy);
              gc += e * (a / (2 * det) - 0.5 * dy * dy);
            }
          }
        }
        (*r)(k) = v - (q[3] + q[0] * g);
        if (jac) {
          (*jac)(k, 0) = g, (*jac)(k, 1) = q[0] * gx, (*jac)(k, 2) = q[0] * gy, (*jac)(k, 3) = 1;
          (*jac)(k, 4) = q[0] * ga, (*jac)(k, 5) = q[0] * gb, (*jac)(k, 6) = q[0] * gc;
        }
        ++k;
      }
    }
    return true;
  };
  // Levenberg-Marquardt on the model (r = data - model, J = d model / d p).
  VectorXd r;
  MatrixXd jac;
  if (!eval(p, &r, &jac)) return out;
  double rss = r.squaredNorm(), lambda = 1e-3;
  for (int it = 0; it < 30; ++it) {
    const MatrixXd j = jac.leftCols(np_free);
    MatrixXd a = j.transpose() * j;
    const VectorXd g = j.transpose() * r;
    bool improved = false;
    for (int tries = 0; tries < 8 && !improved; ++tries) {
      MatrixXd ad = a;
      for (int i = 0; i < np_free; ++i) ad(i, i) *= 1 + lambda;
      const VectorXd step = ad.ldlt().solve(g);
      double q[7];
      std::copy(p, p + 7, q);
      for (int i = 0; i < np_free; ++i) q[i] += step(i);
      VectorXd r2;
      if (step.allFinite() && std::abs(q[1] - x_guess) < half && std::abs(q[2] - y_guess) < half &&
          eval(q, &r2, nullptr) && r2.squaredNorm() <= rss) {
        const double drop = rss - r2.squaredNorm();
        std::copy(q, q + 7, p);
        eval(p, &r, &jac);
        improved = true;
        lambda = std::max(1e-6, lambda / 4);
        if (drop < 1e-9 * rss) it = 1000;
        rss = r.squaredNorm();
      } else {
        lambda *= 8;
      }
    }
    if (!improved) break;
  }
  const double a = p[4], b = p[5], c = p[6], det = a * c - b * b;
  if (!(det > 0) || !(p[0] > 0)) return out;
  out.x_px = p[1], out.y_px = p[2], out.flux_adu = p[0], out.background_adu = p[3];
  out.cxx = c / det - kSubVar, out.cyy = a / det - kSubVar, out.cxy = -b / det;
  out.t_px2 = (out.cxx + out.cyy) / 2;
  if (!(out.t_px2 > 1e-4)) return out;  // narrower than the sub-sampling can tell
  out.e1 = (out.cxx - out.cyy) / (2 * out.t_px2);
  out.e2 = out.cxy / out.t_px2;
  out.rss_adu2 = rss;
  out.n = nvalid;
  if (!fixed_c) {
    const MatrixXd j = jac.leftCols(7);
    const MatrixXd cov = (j.transpose() * j).ldlt().solve(MatrixXd::Identity(7, 7)) * (rss / std::max(1, nvalid - 7));
    // Gradients of T, e1, e2 with respect to (a, b, c).
    const double s = a + c, d2 = det * det;
    const Eigen::Vector3d gt(-(b * b + c * c) / (2 * d2), b * s / d2, -(b * b + a * a) / (2 * d2));
    // e1, e2 of the raw fit, rescaled by T_raw / T for the sub-sample correction (first order).
    const double k = (a + c) / (2 * det) / out.t_px2;
    const Eigen::Vector3d g1 = k * Eigen::Vector3d(-2 * c / (s * s), 0, 2 * a / (s * s));
    const Eigen::Vector3d g2 = k * Eigen::Vector3d(2 * b / (s * s), -2 / s, 2 * b / (s * s));
    const Eigen::Matrix3d cp = cov.bottomRightCorner(3, 3);
    out.t_var = gt.dot(cp * gt), out.e1_var = g1.dot(cp * g1), out.e2_var = g2.dot(cp * g2);
    if (!(out.t_var > 0) || !std::isfinite(out.t_var) || !(out.e1_var > 0) || !(out.e2_var > 0)) return out;
  }
  out.ok = std::isfinite(rss);
  return out;
}

namespace discover_internal {
namespace {

struct ShapeStar {
  int frame = 0, index = 0;
  double u = 0, t = 0, t_var = 0, e1 = 0, e2 = 0, e1_var = 0, e2_var = 0;
};

// Weighted least squares y = X beta with weights w, outliers beyond 5 robust sigmas left out
// (cosmic-ray hits, blends); covariance scaled by the reduced chi^2 when above 1.
struct Wls {
  VectorXd beta;
  MatrixXd cov;
  bool ok = false;
};
Wls FitWls(const MatrixXd& x, const VectorXd& y, const VectorXd& w) {
  Wls out;
  const int n = static_cast<int>(y.size()), k = static_cast<int>(x.cols());
  std::vector<bool> keep(n, true);
  for (int pass = 0; pass < 3; ++pass) {
    MatrixXd a = MatrixXd::Zero(k, k);
    VectorXd g = VectorXd::Zero(k);
    int m = 0;
    for (int i = 0; i < n; ++i) {
      if (!keep[i]) continue;
      a += w(i) * x.row(i).transpose() * x.row(i);
      g += w(i) * x.row(i).transpose() * y(i);
      ++m;
    }
    if (m <= k + 2) return out;
    const MatrixXd inv = a.ldlt().solve(MatrixXd::Identity(k, k));
    out.beta = inv * g;
    std::vector<double> z(n);
    double chi2 = 0;
    std::vector<double> az;
    for (int i = 0; i < n; ++i) {
      z[i] = (y(i) - x.row(i).dot(out.beta)) * std::sqrt(w(i));
      if (keep[i]) chi2 += z[i] * z[i], az.push_back(std::abs(z[i]));
    }
    out.cov = inv * std::max(1.0, chi2 / (m - k));
    out.ok = out.beta.allFinite();
    const double scale = 1.4826 * Median(az);
    for (int i = 0; i < n; ++i) keep[i] = std::abs(z[i]) <= 5 * std::max(scale, 1e-12);
  }
  return out;
}

struct ShapeModel {
  bool ok = false;
  double alpha = 0, beta = 0, e1 = 0, e2 = 0;  // T = s0^2 + alpha + beta u; mean ellipticity
  Matrix2d cov_ab = Matrix2d::Zero();
  double e1_var = 0, e2_var = 0;
};

ShapeModel FitShape(const std::vector<ShapeStar>& stars, const std::vector<bool>& use_frame, double s0) {
  ShapeModel m;
  std::vector<const ShapeStar*> sel;
  for (const auto& s : stars) {
    if (use_frame[s.frame]) sel.push_back(&s);
  }
  const int n = static_cast<int>(sel.size());
  if (n < 8) return m;
  // Field dependence only when the stars span the field (else the slope is not determined).
  double umin = 1e9, umax = -1e9;
  for (const auto* s : sel) umin = std::min(umin, s->u), umax = std::max(umax, s->u);
  const bool slope = umax - umin > 0.2;
  MatrixXd x(n, slope ? 2 : 1), ones = MatrixXd::Ones(n, 1);
  VectorXd yt(n), wt(n), y1(n), w1(n), y2(n), w2(n);
  for (int i = 0; i < n; ++i) {
    x(i, 0) = 1;
    if (slope) x(i, 1) = sel[i]->u;
    yt(i) = sel[i]->t - s0 * s0, wt(i) = 1 / sel[i]->t_var;
    y1(i) = sel[i]->e1, w1(i) = 1 / sel[i]->e1_var;
    y2(i) = sel[i]->e2, w2(i) = 1 / sel[i]->e2_var;
  }
  const Wls ft = FitWls(x, yt, wt), f1 = FitWls(ones, y1, w1), f2 = FitWls(ones, y2, w2);
  if (!ft.ok || !f1.ok || !f2.ok) return m;
  m.alpha = ft.beta(0);
  m.cov_ab(0, 0) = ft.cov(0, 0);
  if (slope) {
    m.beta = ft.beta(1);
    m.cov_ab = ft.cov;
  } else {
    m.cov_ab(1, 1) = 1;  // no slope fitted: beta = 0 contributes nothing to the chi^2
  }
  m.e1 = f1.beta(0), m.e2 = f2.beta(0);
  m.e1_var = f1.cov(0, 0), m.e2_var = f2.cov(0, 0);
  m.ok = true;
  return m;
}

// The covariance of the PSF at field position u under a shape model.
void ShapeCov(const ShapeModel& m, double s0, double u, double* c) {
  const double t = std::max(0.01, s0 * s0 + m.alpha + m.beta * u);
  c[0] = t * (1 + m.e1), c[1] = t * (1 - m.e1), c[2] = t * m.e2;
}

// The model's (e1, e2) from its ellipticity 1 - b/a and angle: |e| = (a^2 - b^2) / (a^2 + b^2).
void ModelE(const FrameDiscoverOptions& o, double* e1, double* e2) {
  const double r2 = std::pow(1 - o.psf_ellipticity, 2), e = (1 - r2) / (1 + r2), th = 2 * o.psf_angle_deg * kDegToRad;
  *e1 = e * std::cos(th), *e2 = e * std::sin(th);
}

// Chi^2 (4 dof, survival exp(-w/2)(1 + w/2)) of the shape model against the model PSF.
double ShapeChi2(const ShapeModel& m, const FrameDiscoverOptions& o, double s0) {
  double e1m, e2m;
  ModelE(o, &e1m, &e2m);
  Matrix2d cab = m.cov_ab;
  const double ft = 2 * s0 * s0 * o.psf_width_floor_pct / 100;  // T = sigma^2: dT = 2 sigma^2 (dsigma / sigma)
  cab(0, 0) += ft * ft, cab(1, 1) += ft * ft;
  const Vector2d ab(m.alpha, m.beta);
  const double fe = o.psf_ellipticity_floor * o.psf_ellipticity_floor;
  return ab.dot(cab.ldlt().solve(ab)) + std::pow(m.e1 - e1m, 2) / (m.e1_var + fe) +
         std::pow(m.e2 - e2m, 2) / (m.e2_var + fe);
}

}  // namespace

CauseResult AnalysePsfShape(const SolvedFrameSet& set, const Camera& camera, const FrameDiscoverOptions& o,
                            FrameDiscovery* d) {
  CauseResult res;
  res.candidate.cause = "psf_shape";
  res.candidate.dof = 4;
  const double rc2 = std::pow(std::max(camera.cx_px, camera.width - 1 - camera.cx_px), 2) +
                     std::pow(std::max(camera.cy_px, camera.height - 1 - camera.cy_px), 2);
  std::vector<ShapeStar> stars;
  for (int i = 0; i < static_cast<int>(set.stars.size()); ++i) {
    const FrameStar& s = set.stars[i];
    if (s.stamp.empty()) continue;
    const double guess = s.psf_sigma_px > 0 ? s.psf_sigma_px : (o.psf_sigma_px > 0 ? o.psf_sigma_px : 1.0);
    const SpotFit f = FitSpot(s.stamp, s.stamp_half, s.x_px - s.stamp_x0, s.y_px - s.stamp_y0, guess);
    // Keep the fits that say something about the shape (T to better than 30 %).
    if (!f.ok || !(f.t_px2 > 0.02) || std::sqrt(f.t_var) > 0.3 * f.t_px2 || std::abs(f.e1) > 0.95 ||
        std::abs(f.e2) > 0.95)
      continue;
    ShapeStar st;
    st.frame = s.frame, st.index = i;
    st.u = (std::pow(s.x_px - camera.cx_px, 2) + std::pow(s.y_px - camera.cy_px, 2)) / rc2;
    st.t = f.t_px2, st.t_var = f.t_var, st.e1 = f.e1, st.e2 = f.e2, st.e1_var = f.e1_var, st.e2_var = f.e2_var;
    stars.push_back(st);
  }
  const int nf = static_cast<int>(set.q.size());
  const std::vector<bool> all(nf, true);
  d->psf_stars = static_cast<int>(stars.size());
  {  // measured, model-free: the same fit against s0 = 0
    const ShapeModel m = FitShape(stars, all, 0.0);
    if (m.ok) {
      double umean = 0;
      for (const auto& s : stars) umean += s.u / stars.size();
      d->psf_sigma_fit_px = std::sqrt(std::max(0.0, m.alpha + m.beta * umean));
      d->psf_e1 = m.e1, d->psf_e2 = m.e2;
    }
  }
  const double s0 = o.psf_sigma_px;
  if (!(s0 > 0)) return res;
  const ShapeModel m = FitShape(stars, all, s0);
  if (!m.ok) return res;
  res.tested = true;
  auto& c = res.candidate;
  c.statistic = ShapeChi2(m, o, s0);
  c.p_value = std::exp(-c.statistic / 2) * (1 + c.statistic / 2);
  c.delta_bic = c.statistic - c.dof * std::log(static_cast<double>(stars.size()));
  // Parameters: sigma at the centre and at the corner, ellipticity (1 - minor/major) and its
  // position angle (from +x towards +y), with first-order sigmas.
  const double tc = std::max(1e-6, s0 * s0 + m.alpha), tk = std::max(1e-6, s0 * s0 + m.alpha + m.beta);
  res.parameters["psf_sigma_px"] = std::sqrt(tc);
  res.sigmas["psf_sigma_px"] = std::sqrt(m.cov_ab(0, 0)) / (2 * std::sqrt(tc));
  const Eigen::Vector2d gk(1, 1);
  res.parameters["psf_sigma_corner_px"] = std::sqrt(tk);
  res.sigmas["psf_sigma_corner_px"] = std::sqrt(std::max(0.0, gk.dot(m.cov_ab * gk))) / (2 * std::sqrt(tk));
  res.parameters["psf_e1"] = m.e1, res.sigmas["psf_e1"] = std::sqrt(m.e1_var);
  res.parameters["psf_e2"] = m.e2, res.sigmas["psf_e2"] = std::sqrt(m.e2_var);
  const double e = std::hypot(m.e1, m.e2), se = std::sqrt((m.e1_var + m.e2_var) / 2);
  const double ratio = std::sqrt((1 - std::min(e, 0.99)) / (1 + std::min(e, 0.99)));
  res.parameters["psf_ellipticity"] = 1 - ratio;
  res.sigmas["psf_ellipticity"] = se * ratio / ((1 - std::min(e, 0.99)) * (1 + std::min(e, 0.99)));  // d(1-ratio)/de
  res.parameters["psf_angle_deg"] = 0.5 * std::atan2(m.e2, m.e1) * kRadToDeg;
  res.sigmas["psf_angle_deg"] = e > 0 ? 0.5 * se / e * kRadToDeg : 90.0;
  // Held-out gain: shape from the even frames scored on the odd ones and vice versa.
  double e1m, e2m;
  ModelE(o, &e1m, &e2m);
  const double nominal[3] = {s0 * s0 * (1 + e1m), s0 * s0 * (1 - e1m), s0 * s0 * e2m};
  double ss_before = 0, ss_after = 0;
  long n = 0;
  for (int fold = 0; fold < 2; ++fold) {
    std::vector<bool> train(nf), test(nf);
    for (int f = 0; f < nf; ++f) train[f] = nf < 2 || f % 2 == fold, test[f] = nf < 2 || f % 2 != fold;
    const ShapeModel mt = FitShape(stars, train, s0);
    if (!mt.ok) continue;
    for (const auto& st : stars) {
      if (!test[st.frame]) continue;
      const FrameStar& s = set.stars[st.index];
      double fitted[3];
      ShapeCov(mt, s0, st.u, fitted);
      const double xg = s.x_px - s.stamp_x0, yg = s.y_px - s.stamp_y0;
      const SpotFit b = FitSpot(s.stamp, s.stamp_half, xg, yg, s0, nominal);
      const SpotFit a = FitSpot(s.stamp, s.stamp_half, xg, yg, s0, fitted);
      if (!b.ok || !a.ok || !(s.noise_adu > 0)) continue;
      ss_before += b.rss_adu2 / (s.noise_adu * s.noise_adu);
      ss_after += a.rss_adu2 / (s.noise_adu * s.noise_adu);
      n += b.n;
    }
    if (nf < 2) break;
  }
  if (n > 0) {
    res.before = std::sqrt(ss_before / n), res.after = std::sqrt(ss_after / n);
    res.gain = res.after > 0 ? res.before / res.after : 1.0;
  }
  return res;
}

namespace {

// ln P(X >= k) for X ~ Poisson(lambda).
double LogPoissonSurvival(int k, double lambda) {
  if (k <= 0) return 0.0;
  lambda = std::max(lambda, 1e-300);
  if (lambda > k) {  // not in the tail: sum the complement directly
    double p = 0, term = std::exp(-lambda);
    for (int i = 0; i < k; ++i) p += term, term *= lambda / (i + 1);
    return std::log(std::max(1e-300, 1 - p));
  }
  const double leading = -lambda + k * std::log(lambda) - std::lgamma(k + 1.0);
  double s = 1, term = 1;
  for (int i = 1; i < 200; ++i) {
    term *= lambda / (k + i);
    s += term;
    if (term < 1e-16 * s) break;
  }
  return leading + std::log(s);
}

// P(a given pixel is flagged in >= m of the frames) when frame f flags each pixel with probability p[f].
double AtLeastM(const std::vector<double>& p, int m) {
  std::vector<double> dist(p.size() + 1, 0.0);  // Poisson-binomial by dynamic programming
  dist[0] = 1;
  for (size_t f = 0; f < p.size(); ++f) {
    for (size_t k = f + 1; k > 0; --k) dist[k] = dist[k] * (1 - p[f]) + dist[k - 1] * p[f];
    dist[0] *= 1 - p[f];
  }
  double s = 0;
  for (size_t k = static_cast<size_t>(m); k < dist.size(); ++k) s += dist[k];
  return s;
}

using PixelKey = std::pair<int, int>;

// Pixels flagged in >= m of the frames `use`, with their hit count and median excess.
std::map<PixelKey, std::pair<int, double>> Persistent(const SolvedFrameSet& set, const std::vector<bool>& use, int m) {
  std::map<PixelKey, std::vector<double>> hits;
  for (size_t f = 0; f < set.spikes.size(); ++f) {
    if (!use[f]) continue;
    std::map<PixelKey, double> once;  // one hit per pixel and frame
    for (const auto& s : set.spikes[f]) once[{s.x, s.y}] = std::max(once[{s.x, s.y}], s.excess_adu);
    for (const auto& [k, v] : once) hits[k].push_back(v);
  }
  std::map<PixelKey, std::pair<int, double>> out;
  for (auto& [k, v] : hits) {
    if (static_cast<int>(v.size()) >= m) out[k] = {static_cast<int>(v.size()), Median(v)};
  }
  return out;
}

int MinHits(int frames) { return std::max(2, (frames + 1) / 2); }

}  // namespace

CauseResult AnalyseHotPixels(const SolvedFrameSet& set, const FrameDiscoverOptions& o, FrameDiscovery* d) {
  (void)o;
  CauseResult res;
  res.candidate.cause = "hot_pixels";
  res.candidate.dof = 1;
  const int nfr = static_cast<int>(set.spikes.size());
  const double npix = static_cast<double>(set.width) * set.height;
  if (nfr < 2 || !(npix > 0)) return res;
  res.tested = true;
  const int m = MinHits(nfr);
  const std::vector<bool> all(nfr, true);
  const auto pers = Persistent(set, all, m);
  // Null: every frame's spikes at independent uniform positions (cosmic rays, transient hot pixels).
  std::vector<double> rate(nfr);
  for (int f = 0; f < nfr; ++f) rate[f] = std::min(1.0, set.spikes[f].size() / npix);
  const double lambda = npix * AtLeastM(rate, m);
  const int k = static_cast<int>(pers.size());
  const double lp = LogPoissonSurvival(k, lambda);
  auto& c = res.candidate;
  c.p_value = std::exp(lp);
  c.statistic = -2 * lp;
  c.delta_bic = c.statistic - std::log(npix);
  std::vector<double> excess;
  for (const auto& [key, v] : pers) {
    d->hot_pixels.push_back({key.first, key.second, v.second});
    d->hot_pixel_frames.push_back(v.first);
    excess.push_back(v.second);
  }
  res.parameters["hot_pixel_count"] = k;
  res.sigmas["hot_pixel_count"] = std::sqrt(std::max(1.0, static_cast<double>(k)));
  res.parameters["hot_pixel_expected_by_chance"] = lambda;
  res.sigmas["hot_pixel_expected_by_chance"] = std::sqrt(lambda);
  if (!excess.empty()) {
    std::vector<double> dev;
    const double med = Median(excess);
    for (double v : excess) dev.push_back(std::abs(v - med));
    res.parameters["excess_median_adu"] = med;
    res.sigmas["excess_median_adu"] = 1.2533 * 1.4826 * Median(dev) / std::sqrt(static_cast<double>(excess.size()));
    res.parameters["excess_min_adu"] = *std::min_element(excess.begin(), excess.end());
    res.sigmas["excess_min_adu"] = 0;
    res.parameters["excess_max_adu"] = *std::max_element(excess.begin(), excess.end());
    res.sigmas["excess_max_adu"] = 0;
  }
  // Held-out gain: persistent pixels of the even frames masked in the odd frames and vice versa;
  // spikes per held-out frame before and after (the false sources a detector must reject).
  double before = 0, after = 0;
  int ntest = 0;
  for (int fold = 0; fold < 2; ++fold) {
    std::vector<bool> train(nfr), test(nfr);
    int ntrain = 0;
    for (int f = 0; f < nfr; ++f) train[f] = f % 2 == fold, test[f] = !train[f], ntrain += train[f];
    if (ntrain < 2) continue;
    const auto mask = Persistent(set, train, MinHits(ntrain));
    for (int f = 0; f < nfr; ++f) {
      if (!test[f]) continue;
      ++ntest;
      for (const auto& s : set.spikes[f]) {
        before += 1;
        after += mask.count({s.x, s.y}) ? 0 : 1;
      }
    }
  }
  if (ntest > 0) {
    res.before = before / ntest, res.after = after / ntest;
    res.gain = (before + 1) / (after + 1);  // +1: a perfect mask gives a finite gain
  }
  return res;
}

}  // namespace discover_internal
}  // namespace ssiu
