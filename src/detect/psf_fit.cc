#include "detect/psf_fit.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Dense>

#include "detect/smear.h"

namespace ssiu {
namespace {

// Normal equations J'WJ and J'Wr of the five-parameter fit (x, y, A, B, sigma) from 15 + 5 scalar
// sums, shared by the still and the smeared model (scalars rather than an Eigen matrix: they vectorise).
struct NormalSums {
  double h00 = 0, h01 = 0, h02 = 0, h03 = 0, h04 = 0, h11 = 0, h12 = 0, h13 = 0, h14 = 0, h22 = 0, h23 = 0,
         h24 = 0, h33 = 0, h34 = 0, h44 = 0;
  double g0 = 0, g1 = 0, g2 = 0, g3 = 0, g4 = 0;
  // One pixel: weight, weighted residual and the Jacobian (x, y, A, sigma; B's column is 1).
  void Add(double wgt, double wr, double j0, double j1, double j2, double j4) {
    const double w0 = wgt * j0, w1 = wgt * j1, w2 = wgt * j2, w4 = wgt * j4;
    h00 += w0 * j0;
    h01 += w0 * j1;
    h02 += w0 * j2;
    h03 += w0;
    h04 += w0 * j4;
    h11 += w1 * j1;
    h12 += w1 * j2;
    h13 += w1;
    h14 += w1 * j4;
    h22 += w2 * j2;
    h23 += w2;
    h24 += w2 * j4;
    h33 += wgt;
    h34 += w4;
    h44 += w4 * j4;
    g0 += wr * j0;
    g1 += wr * j1;
    g2 += wr * j2;
    g3 += wr;
    g4 += wr * j4;
  }
  void Fill(Eigen::Matrix<double, 5, 5>* jtj, Eigen::Matrix<double, 5, 1>* jtr) const {
      if (jtj) {
        *jtj << h00, h01, h02, h03, h04,  //
            h01, h11, h12, h13, h14,      //
            h02, h12, h22, h23, h24,      //
            h03, h13, h23, h33, h34,      //
            h04, h14, h24, h34, h44;
      }
      if (jtr) *jtr << g0, g1, g2, g3, g4;
  }
};

constexpr double kSqrt2 = 1.41421356237309504880;
constexpr double kInvSqrtPi = 0.56418958354775628695;

// Pixel-integrated 1-D Gaussian: f(i) = 1/2 [erf((i + 1/2 - c) k) - erf((i - 1/2 - c) k)], k = 1/(sqrt2 s),
// with derivatives with respect to the centre c and to s.
struct Profile {
  std::vector<double> f, dc, ds;
  void Compute(int i0, int n, double c, double s) {
    f.resize(n);
    dc.resize(n);
    ds.resize(n);
    const double k = 1.0 / (kSqrt2 * s);
    double ulo = (i0 - 0.5 - c) * k;
    double elo = std::erf(ulo), glo = std::exp(-ulo * ulo);
    for (int a = 0; a < n; ++a) {
      const double uhi = (i0 + a + 0.5 - c) * k;
      const double ehi = std::erf(uhi), ghi = std::exp(-uhi * uhi);
      f[a] = 0.5 * (ehi - elo);
      dc[a] = -k * kInvSqrtPi * (ghi - glo);
      ds[a] = -kInvSqrtPi / s * (ghi * uhi - glo * ulo);
      ulo = uhi;
      elo = ehi;
      glo = ghi;
    }
  }
};

// The Gaussian averaged along a straight segment (motion smear) for every window pixel: unit-flux model
// f and its derivatives with respect to the centre (dx, dy) and sigma (ds), as the mean over n
// sub-positions h <= sigma apart. The segment is n boxes of width h; each box blurred by the PSF is
// taken as a Gaussian of variance sigma^2 + h^2 / 12 (the box's variance), so that the model's second
// moments are exact; by Poisson summation the sampling adds ripples of relative size
// ~exp(-2 pi^2 sigma^2 / h^2) < 3e-9.
struct SmearModel {
  std::vector<double> f, dx, dy, ds;
  Profile px, py;
  void Compute(int x0, int nx, int y0, int ny, double cx, double cy, double s, double sdx, double sdy) {
    const size_t npix = static_cast<size_t>(nx) * ny;
    f.assign(npix, 0.0);
    dx.assign(npix, 0.0);
    dy.assign(npix, 0.0);
    ds.assign(npix, 0.0);
    const double len = std::hypot(sdx, sdy);
    const int n = std::max(2, static_cast<int>(std::ceil(len / std::max(s, 0.5))));
    const double h = len / n, sub = std::sqrt(s * s + h * h / 12);
    const double wk = 1.0 / n, dsub = s / sub;  // d sub / d s
    for (int k = 0; k < n; ++k) {
      const double t = (k + 0.5) / n - 0.5;
      px.Compute(x0, nx, cx + t * sdx, sub);
      py.Compute(y0, ny, cy + t * sdy, sub);
      for (int b = 0; b < ny; ++b) {
        const double fyb = wk * py.f[b], dyb = wk * py.dc[b], syb = wk * dsub * py.ds[b];
        const size_t row = static_cast<size_t>(b) * nx;
        for (int a = 0; a < nx; ++a) {
          f[row + a] += px.f[a] * fyb;
          dx[row + a] += px.dc[a] * fyb;
          dy[row + a] += px.f[a] * dyb;
          ds[row + a] += dsub * px.ds[a] * fyb + px.f[a] * syb;
        }
      }
    }
  }
};

}  // namespace

PsfFit FitPsf(const ImageView& img, int px, int py, int r, double level, double sigma_n, const PsfFitOptions& o,
              const std::function<bool(int, int)>& is_bad) {
  PsfFit out;
  // A smeared star's window grows by its smear on both sides: the brightest pixel may sit at either end.
  const bool smeared = o.smear_dx_px != 0 || o.smear_dy_px != 0;
  const double smear_len = std::hypot(o.smear_dx_px, o.smear_dy_px);
  const int rx = r + (smeared ? static_cast<int>(std::ceil(std::abs(o.smear_dx_px))) : 0);
  const int ry = r + (smeared ? static_cast<int>(std::ceil(std::abs(o.smear_dy_px))) : 0);
  const int x0 = std::max(0, px - rx), x1 = std::min(img.width - 1, px + rx);
  const int y0 = std::max(0, py - ry), y1 = std::min(img.height - 1, py + ry);
  const int nx = x1 - x0 + 1, ny = y1 - y0 + 1;
  std::vector<double> v(static_cast<size_t>(nx) * ny);
  std::vector<uint8_t> use(v.size(), 1);
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const size_t i = static_cast<size_t>(y - y0) * nx + (x - x0);
      v[i] = img.at(x, y);
      if (v[i] >= o.saturation_adu || is_bad(x, y)) use[i] = 0;
    }
  }
  const double var_n = sigma_n * sigma_n;

  // Start: weighted moments of the positive part above the local background.
  double sw = 0, sx = 0, sy = 0, peak = 0;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const size_t i = static_cast<size_t>(y - y0) * nx + (x - x0);
      const double a = v[i] - level;
      if (!use[i]) continue;
      peak = std::max(peak, a);
      if (a <= 2 * sigma_n) continue;
      sw += a;
      sx += a * x;
      sy += a * y;
    }
  }
  if (sw <= 0) return out;
  double cx = sx / sw, cy = sy / sw;
  if (smeared) {
    // The smeared window is large and its noise pixels pull the whole-window moments off the star:
    // start from the moments within reach of the smear segment around the brightest pixel, recentred
    // a few times (the segment's centre is the star's).
    const double hx = 0.5 * o.smear_dx_px, hy = 0.5 * o.smear_dy_px, len2 = hx * hx + hy * hy;
    const double reach = std::max(2.0, 2.5 * o.sigma_guess_px);
    cx = px;
    cy = py;
    for (int pass = 0; pass < 4; ++pass) {
      double w = 0, mx = 0, my = 0;
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          const size_t i = static_cast<size_t>(y - y0) * nx + (x - x0);
          const double a = v[i] - level, dx = x - cx, dy = y - cy;
          if (!use[i] || a <= 2 * sigma_n) continue;
          const double t = std::clamp((dx * hx + dy * hy) / len2, -1.0, 1.0);
          if (std::hypot(dx - t * hx, dy - t * hy) > reach) continue;
          w += a;
          mx += a * x;
          my += a * y;
        }
      }
      if (w <= 0) break;
      cx = mx / w;
      cy = my / w;
    }
    sx = cx * sw;  // the fallback below starts from here too
    sy = cy * sw;
  }
  // Elongation and major-axis sigma from the second moments of the pixels above 2 sigma_n within
  // `radius` of (mx, my): the eigenvalues of the 2x2 moment matrix in closed form.
  auto shape_from_moments = [&](double mx, double my, double radius) {
    double w = 0, mxx = 0, myy = 0, mxy = 0;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const size_t i = static_cast<size_t>(y - y0) * nx + (x - x0);
        const double a = v[i] - level, dx = x - mx, dy = y - my;
        if (!use[i] || a <= 2 * sigma_n || dx * dx + dy * dy > radius * radius) continue;
        w += a;
        mxx += a * dx * dx;
        myy += a * dy * dy;
        mxy += a * dx * dy;
      }
    }
    if (w <= 0) return;
    mxx /= w;
    myy /= w;
    mxy /= w;
    const double tr = 0.5 * (mxx + myy), disc = std::sqrt(std::max(0.25 * (mxx - myy) * (mxx - myy) + mxy * mxy, 0.0));
    const double l0 = std::max(tr - disc, 1e-3), l1 = std::max(tr + disc, 1e-3);
    out.elongation = std::sqrt(l1 / l0);
    out.major_sigma_px = std::sqrt(l1);
  };
  shape_from_moments(cx, cy, 1e9);
  double s = std::clamp(o.sigma_guess_px, 0.4, 10.0);
  double amp = sw, bkg = level;
  const double gain = o.gain_e_per_adu;
  Profile fx, fy;
  Eigen::Matrix<double, 5, 5> info = Eigen::Matrix<double, 5, 5>::Identity();
  // chi2 and, on request, the normal equations J^T W J and J^T W r of the five parameters
  // (x, y, flux, background, sigma). The model is separable, A fx(a) fy(b), so each pixel's
  // Jacobian row is a few products of the per-axis profiles; only the 15 distinct entries of the
  // symmetric J^T W J are summed (scalar accumulators: about a quarter of the work of a 5x5
  // outer product per pixel). Each pixel's weight goes to w_new; with chi2_frozen, the chi2 under
  // the weights w_cur of the current iterate is summed there too.
  std::vector<double> w_cur(v.size(), 0.0), w_new(v.size(), 0.0);
  const double inv_gain = gain > 0 ? 1.0 / gain : 0.0;  // shot-noise variance = model * inv_gain (ADU^2)
  auto residual_chi2 = [&](double xc, double yc, double A, double B, double ss, Eigen::Matrix<double, 5, 5>* jtj,
                           Eigen::Matrix<double, 5, 1>* jtr, double* chi2_frozen = nullptr) {
    fx.Compute(x0, nx, xc, ss);
    fy.Compute(y0, ny, yc, ss);
    double chi2 = 0;
    NormalSums ns;
    for (int b = 0; b < ny; ++b) {
      const double fyb = fy.f[b], dyb = A * fy.dc[b], syb = A * fy.ds[b];
      const size_t row = static_cast<size_t>(b) * nx;
      for (int a = 0; a < nx; ++a) {
        if (!use[row + a]) continue;
        const double fxa = fx.f[a];
        const double j2 = fxa * fyb;
        const double m = A * j2;
        const double wgt = 1.0 / (var_n + std::max(m, 0.0) * inv_gain), res = v[row + a] - (B + m);
        const double wr = wgt * res;
        chi2 += wr * res;
        w_new[row + a] = wgt;
        if (chi2_frozen) *chi2_frozen += w_cur[row + a] * res * res;
        if (!jtj) continue;
        const double j0 = A * fx.dc[a] * fyb, j1 = fxa * dyb, j4 = A * fx.ds[a] * fyb + fxa * syb;
        ns.Add(wgt, wr, j0, j1, j2, j4);
      }
    }
    ns.Fill(jtj, jtr);
    return chi2;
  };

  // The same sums for the smeared model (SmearModel), kept apart so that the static path is untouched.
  SmearModel sm;
  auto residual_chi2_smeared = [&](double xc, double yc, double A, double B, double ss,
                                   Eigen::Matrix<double, 5, 5>* jtj, Eigen::Matrix<double, 5, 1>* jtr,
                                   double* chi2_frozen) {
    sm.Compute(x0, nx, y0, ny, xc, yc, ss, o.smear_dx_px, o.smear_dy_px);
    double chi2 = 0;
    NormalSums ns;
    for (size_t i = 0; i < v.size(); ++i) {
      if (!use[i]) continue;
      const double j2 = sm.f[i], m = A * j2;
      const double wgt = 1.0 / (var_n + std::max(m, 0.0) * inv_gain), res = v[i] - (B + m);
      const double wr = wgt * res;
      chi2 += wr * res;
      w_new[i] = wgt;
      if (chi2_frozen) *chi2_frozen += w_cur[i] * res * res;
      if (!jtj) continue;
      const double j0 = A * sm.dx[i], j1 = A * sm.dy[i], j4 = A * sm.ds[i];
      ns.Add(wgt, wr, j0, j1, j2, j4);
    }
    ns.Fill(jtj, jtr);
    return chi2;
  };
  auto residual = [&](double xc, double yc, double A, double B, double ss, Eigen::Matrix<double, 5, 5>* jtj,
                      Eigen::Matrix<double, 5, 1>* jtr, double* chi2_frozen = nullptr) {
    return smeared ? residual_chi2_smeared(xc, yc, A, B, ss, jtj, jtr, chi2_frozen)
                   : residual_chi2(xc, yc, A, B, ss, jtj, jtr, chi2_frozen);
  };

  double fit_chi2 = -1;  // chi2 at the solution; < 0 when there is none (moments only)
  if (o.fit) {
    // Levenberg-Marquardt on (x, y, flux, background, sigma).
    double lambda = 1e-4;
    Eigen::Matrix<double, 5, 5> jtj;
    Eigen::Matrix<double, 5, 1> jtr;
    double chi2 = residual(cx, cy, amp, bkg, s, &jtj, &jtr);
    std::swap(w_cur, w_new);
    for (int it = 0; it < o.max_iterations; ++it) {
      out.iterations = it + 1;
      Eigen::Matrix<double, 5, 5> a = jtj;
      for (int k = 0; k < 5; ++k) a(k, k) *= 1.0 + lambda;
      const Eigen::Matrix<double, 5, 1> d = a.ldlt().solve(jtr);
      if (!d.allFinite()) break;
      // 2e-3 px is far below any centroid's noise (0.01 px at SNR 500): a small, nearly undamped
      // step ends the fit without evaluating it.
      const bool small_step = std::abs(d(0)) < 2e-3 && std::abs(d(1)) < 2e-3 && std::abs(d(4)) < 5e-3;
      if (small_step && lambda <= 1e-2) {
        cx += d(0);
        cy += d(1);
        amp += d(2);
        bkg += d(3);
        s = std::clamp(s + d(4), 0.3, 3.0 * r);
        break;
      }
      const double nxc = cx + d(0), nyc = cy + d(1), na = amp + d(2), nb = bkg + d(3);
      const double ns = std::clamp(s + d(4), 0.3, 3.0 * r);
      Eigen::Matrix<double, 5, 5> jtj2;
      Eigen::Matrix<double, 5, 1> jtr2;
      // The step is judged with the weights held at the current iterate (iteratively reweighted
      // least squares): with shot-noise weights, the chi2 under the trial's own weights is not
      // what the Gauss-Newton step lowers, and near the solution it would refuse good steps.
      double chi2_frozen = 0;
      const double chi2n = residual(nxc, nyc, na, nb, ns, &jtj2, &jtr2, &chi2_frozen);
      if (chi2_frozen <= chi2) {
        cx = nxc;
        cy = nyc;
        amp = na;
        bkg = nb;
        s = ns;
        chi2 = chi2n;
        jtj = jtj2;
        jtr = jtr2;
        std::swap(w_cur, w_new);
        lambda = std::max(lambda * 0.1, 1e-8);
        if (small_step) break;
      } else {
        lambda *= 10;
        if (lambda > 1e8) break;
      }
    }
    info = jtj;
    fit_chi2 = chi2;
    // A fit that ran off the window or lost its signal falls back to the moments.
    if (!(amp > 0) || std::abs(cx - px) > rx || std::abs(cy - py) > ry || !std::isfinite(cx + cy)) {
      cx = sx / sw;
      cy = sy / sw;
      amp = sw;
      bkg = level;
      s = o.sigma_guess_px;
      residual(cx, cy, amp, bkg, s, &info, nullptr);
      fit_chi2 = -1;
    }
  } else {
    residual(cx, cy, amp, bkg, s, &info, nullptr);
  }
  out.ok = amp > 0 && std::isfinite(cx) && std::isfinite(cy);
  // With the fitted centre and width known, the shape is measured again within 2.5 fitted sigma:
  // for a sharp PSF (sigma ~0.5 px) the whole window's moments are dominated by noise pixels a few
  // pixels out and make a round star look elongated. A cosmic-ray track or a blend keeps its
  // elongation, being elongated on the scale of its own fitted width.
  if (out.ok && o.fit && !smeared) shape_from_moments(cx, cy, std::max(1.5, 2.5 * s));
  if (out.ok && o.fit && smeared) {
    // Smeared: the second moments of the data (less the fitted background) against those of the
    // fitted smeared model, over the same pixels: where the model is above 2 sigma_n, within 2.5 sigma
    // of the smear segment. E = M_data - M_model + s^2 I is round (elongation 1) when the image is the
    // predicted smear; a track of another direction or length keeps its elongation.
    sm.Compute(x0, nx, y0, ny, cx, cy, s, o.smear_dx_px, o.smear_dy_px);
    const double hx = 0.5 * o.smear_dx_px, hy = 0.5 * o.smear_dy_px, len2 = hx * hx + hy * hy;
    const double reach = std::max(1.5, 2.5 * s);
    Eigen::Matrix2d md = Eigen::Matrix2d::Zero(), mm = Eigen::Matrix2d::Zero();
    double wd = 0, wm = 0;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const size_t i = static_cast<size_t>(y - y0) * nx + (x - x0);
        if (!use[i]) continue;
        const double dx = x - cx, dy = y - cy;
        const double t = std::clamp((dx * hx + dy * hy) / len2, -1.0, 1.0);  // nearest point of the segment
        if (std::hypot(dx - t * hx, dy - t * hy) > reach) continue;
        const Eigen::Vector2d d(dx, dy);
        const double a = v[i] - bkg, m = amp * sm.f[i];
        if (m > 2 * sigma_n) {
          md += a * d * d.transpose();
          wd += a;
          mm += m * d * d.transpose();
          wm += m;
        }
      }
    }
    if (wd > 0 && wm > 0) {
      Eigen::Matrix2d e = md / wd - mm / wm + s * s * Eigen::Matrix2d::Identity();
      // The data's along-smear moment is noisy (relative error of order sqrt(2) / SNR of its variance
      // s^2 + L^2 / 12), so along the smear a difference of 7 / SNR of that variance, and never more
      // than half the smear's own variance, is forgiven before the rest enters the elongation; a smear
      // across the predicted one or 1.5x as long exceeds it. Across the smear the test is the still
      // one.
      const double var_along = s * s + smear_len * smear_len / 12;
      const double nea_s = 4 * kPi * s * s * SmearNeaFactor(smear_len, s);
      const double snr_s = amp / std::sqrt((gain > 0 ? amp / gain : 0.0) + nea_s * var_n);
      const Eigen::Vector2d u = Eigen::Vector2d(hx, hy).normalized();
      const double tol = std::min(0.5 * smear_len * smear_len / 12, 7.0 * var_along / std::max(snr_s, 1.0));
      const double e_uu = u.dot(e * u);
      const double e_uu_kept = s * s + std::copysign(std::max(0.0, std::abs(e_uu - s * s) - tol), e_uu - s * s);
      e += (e_uu_kept - e_uu) * u * u.transpose();
      const double tr = 0.5 * e.trace(), disc = std::sqrt(std::max(0.25 * std::pow(e(0, 0) - e(1, 1), 2) + e(0, 1) * e(0, 1), 0.0));
      const double l0 = std::max(tr - disc, 1e-3), l1 = std::max(tr + disc, 1e-3);
      out.elongation = std::sqrt(l1 / l0);
      out.major_sigma_px = std::sqrt(l1);
    }
  }
  out.x_px = cx;
  out.y_px = cy;
  out.flux_adu = amp;
  out.background_adu = bkg;
  out.sigma_px = s;
  // Without the gain the weights hold the background noise only and the star's shot noise is
  // missing from them: the inverse normal matrix then understates the scatter of bright stars
  // (simulated frames: normalised centroid errors 1.34 rms, 2.0 at SNR > 200). The residuals carry
  // the missing variance: var_i = var_n + m_i / g gives 1/g = sum(r_i^2 - var_n) / sum(m_i) over the
  // window (r_i^2 scaled by N / (N - 5) for the five fitted parameters). The centroid was fitted
  // with weights W = 1 / var_n, so its covariance is the sandwich
  // H^-1 (J' W S W J) H^-1 with H = J' W J and S = diag(var_i) (e.g. Huber-White; Seber & Wild,
  // Nonlinear Regression, sec. 2.1.4), not H^-1.
  Eigen::Matrix<double, 5, 2> cov;
  const Eigen::LDLT<Eigen::Matrix<double, 5, 5>> ldlt(info);
  // Only the x and y variances are needed: two solves instead of a general 5x5 inverse.
  cov.col(0) = ldlt.solve(Eigen::Matrix<double, 5, 1>::Unit(0));
  cov.col(1) = ldlt.solve(Eigen::Matrix<double, 5, 1>::Unit(1));
  if (gain <= 0 && fit_chi2 > 0 && smeared) {
    // As below, for the smeared model.
    sm.Compute(x0, nx, y0, ny, cx, cy, s, o.smear_dx_px, o.smear_dy_px);
    double excess = 0, model = 0;
    int n_used = 0;
    for (size_t i = 0; i < v.size(); ++i) {
      if (!use[i]) continue;
      const double m = amp * sm.f[i], res = v[i] - (bkg + m);
      excess += res * res - var_n;
      model += std::max(m, 0.0);
      ++n_used;
    }
    if (n_used > 10 && model > 0 && excess > 0) {
      const double inv_g = excess * n_used / (n_used - 5.0) / model;
      Eigen::Matrix<double, 5, 5> meat = Eigen::Matrix<double, 5, 5>::Zero();
      for (size_t i = 0; i < v.size(); ++i) {
        if (!use[i]) continue;
        const double var_i = var_n + std::max(amp * sm.f[i], 0.0) * inv_g;
        Eigen::Matrix<double, 5, 1> j;
        j << amp * sm.dx[i], amp * sm.dy[i], sm.f[i], 1.0, amp * sm.ds[i];
        meat.noalias() += (var_i / (var_n * var_n)) * j * j.transpose();
      }
      const Eigen::Matrix<double, 5, 2> hx = cov;
      cov.col(0) = meat * hx.col(0);
      cov.col(1) = meat * hx.col(1);
      cov(0, 0) = hx.col(0).dot(cov.col(0));
      cov(1, 1) = hx.col(1).dot(cov.col(1));
    }
  } else if (gain <= 0 && fit_chi2 > 0) {
    fx.Compute(x0, nx, cx, s);
    fy.Compute(y0, ny, cy, s);
    double excess = 0, model = 0;
    int n_used = 0;
    for (int b = 0; b < ny; ++b) {
      for (int a = 0; a < nx; ++a) {
        const size_t i = static_cast<size_t>(b) * nx + a;
        if (!use[i]) continue;
        const double m = amp * fx.f[a] * fy.f[b], res = v[i] - (bkg + m);
        excess += res * res - var_n;
        model += std::max(m, 0.0);
        ++n_used;
      }
    }
    if (n_used > 10 && model > 0 && excess > 0) {
      const double inv_g = excess * n_used / (n_used - 5.0) / model;
      Eigen::Matrix<double, 5, 5> meat = Eigen::Matrix<double, 5, 5>::Zero();
      for (int b = 0; b < ny; ++b) {
        for (int a = 0; a < nx; ++a) {
          if (!use[static_cast<size_t>(b) * nx + a]) continue;
          const double m = amp * fx.f[a] * fy.f[b];
          const double var_i = var_n + std::max(m, 0.0) * inv_g;
          Eigen::Matrix<double, 5, 1> j;
          j << amp * fx.dc[a] * fy.f[b], amp * fx.f[a] * fy.dc[b], fx.f[a] * fy.f[b], 1.0,
              amp * (fx.ds[a] * fy.f[b] + fx.f[a] * fy.ds[b]);
          meat.noalias() += (var_i / (var_n * var_n)) * j * j.transpose();
        }
      }
      const Eigen::Matrix<double, 5, 2> hx = cov;  // H^-1 columns 0 and 1
      cov.col(0) = meat * hx.col(0);
      cov.col(1) = meat * hx.col(1);
      cov(0, 0) = hx.col(0).dot(cov.col(0));
      cov(1, 1) = hx.col(1).dot(cov.col(1));
    }
  }
  out.x_sigma_px = std::sqrt(std::max(cov(0, 0), 0.0));
  out.y_sigma_px = std::sqrt(std::max(cov(1, 1), 0.0));
  // SNR of the flux in a PSF-matched aperture (noise-equivalent area 4 pi s^2).
  const double nea = 4 * 3.14159265358979 * s * s * (smeared ? SmearNeaFactor(smear_len, s) : 1.0);
  out.snr = amp / std::sqrt((gain > 0 ? std::max(amp, 0.0) / gain : 0.0) + nea * var_n);
  return out;
}

}  // namespace ssiu
