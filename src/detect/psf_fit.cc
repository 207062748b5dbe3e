#include "detect/psf_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

#include "detect/smear.h"

namespace ssiu {
namespace {

// Normal equations J'WJ and J'Wr of the five-parameter fit (x, y, A, B, sigma) from 15 + 5 scalar
// sums, shared by the still and the smeared model (scalars rather than an Eigen matrix: they vectorise).
struct NormalSums {
  double h00 = 0, h01 = 0, h02 = 0, h03 = 0, h04 = 0, h11 = 0, h12 = 0, h13 = 0, h14 = 0, h22 = 0, h23 = 0, h24 = 0,
         h33 = 0, h34 = 0, h44 = 0;
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

}  // namespace

// Pixel-integrated 1-D Gaussian: f(i) = 1/2 [erf((i + 1/2 - c) k) - erf((i - 1/2 - c) k)], k = 1/(sqrt2 s),
// with derivatives with respect to the centre c and to s.
void PsfProfile::Compute(int i0, int n, double c, double s) {
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

// The Gaussian averaged along a straight segment (motion smear) for every window pixel: unit-flux model
// f and its derivatives with respect to the centre (dx, dy) and sigma (ds), as the mean over n
// sub-positions h <= sigma apart. The segment is n boxes of width h; each box blurred by the PSF is
// taken as a Gaussian of variance sigma^2 + h^2 / 12 (the box's variance), so that the model's second
// moments are exact; by Poisson summation the sampling adds ripples of relative size
// ~exp(-2 pi^2 sigma^2 / h^2) < 3e-9.
void PsfSmearModel::Compute(int x0, int nx, int y0, int ny, double cx, double cy, double s, double sdx, double sdy) {
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

void PsfFitScratch::Reserve(int side_px) {
  const size_t n = static_cast<size_t>(side_px), npix = n * n;
  for (ScratchVec<double>* b : {&v, &w_cur, &w_new, &sm.f, &sm.dx, &sm.dy, &sm.ds}) b->reserve(npix);
  use.reserve(npix);
  for (PsfProfile* p : {&fx, &fy, &sm.px, &sm.py}) {
    p->f.reserve(n);
    p->dc.reserve(n);
    p->ds.reserve(n);
  }
}

namespace {

using Mat5 = Eigen::Matrix<double, 5, 5>;
using Vec5 = Eigen::Matrix<double, 5, 1>;

// Eigenvalues of a 2x2 second-moment matrix in closed form: elongation sqrt(l1 / l0) and
// major-axis sigma sqrt(l1).
void ShapeFromSecondMoments(double mxx, double myy, double mxy, PsfFit* out) {
  const double tr = 0.5 * (mxx + myy), disc = std::sqrt(std::max(0.25 * (mxx - myy) * (mxx - myy) + mxy * mxy, 0.0));
  const double l0 = std::max(tr - disc, 1e-3), l1 = std::max(tr + disc, 1e-3);
  out->elongation = std::sqrt(l1 / l0);
  out->major_sigma_px = std::sqrt(l1);
}

// One source's fit window and the steps of its fit: start from moments, Levenberg-Marquardt,
// shape, covariance. Parameters (x, y, flux A, background B, sigma) in that order throughout.
class PsfFitter {
 public:
  PsfFitter(const ImageView& img, int px, int py, int r, double level, double sigma_n, const PsfFitOptions& o,
            PixelTest is_bad, PsfFitScratch* sc)
      : o_(o),
        px_(px),
        py_(py),
        r_(r),
        level_(level),
        sigma_n_(sigma_n),
        var_n_(sigma_n * sigma_n),
        v_(sc->v),
        use_(sc->use),
        w_cur_(sc->w_cur),
        w_new_(sc->w_new),
        fx_(sc->fx),
        fy_(sc->fy),
        sm_(sc->sm) {
    // A smeared star's window grows by its smear on both sides: the brightest pixel may sit at either end.
    smeared_ = o.smear_dx_px != 0 || o.smear_dy_px != 0;
    smear_len_ = std::hypot(o.smear_dx_px, o.smear_dy_px);
    rx_ = r + (smeared_ ? static_cast<int>(std::ceil(std::abs(o.smear_dx_px))) : 0);
    ry_ = r + (smeared_ ? static_cast<int>(std::ceil(std::abs(o.smear_dy_px))) : 0);
    if (o.max_half_px > 0 && (rx_ > o.max_half_px || ry_ > o.max_half_px)) {
      rx_ = std::min(rx_, o.max_half_px);
      ry_ = std::min(ry_, o.max_half_px);
      out_.window_clamped = true;
    }
    x0_ = std::max(0, px - rx_), x1_ = std::min(img.width - 1, px + rx_);
    y0_ = std::max(0, py - ry_), y1_ = std::min(img.height - 1, py + ry_);
    nx_ = x1_ - x0_ + 1, ny_ = y1_ - y0_ + 1;
    v_.resize(static_cast<size_t>(nx_) * ny_);
    use_.assign(v_.size(), 1);
    for (int y = y0_; y <= y1_; ++y) {
      for (int x = x0_; x <= x1_; ++x) {
        const size_t i = Index(x, y);
        v_[i] = img.at(x, y);
        if (v_[i] >= o.saturation_adu || is_bad(x, y)) use_[i] = 0;
      }
    }
    inv_gain_ = o.gain_e_per_adu > 0 ? 1.0 / o.gain_e_per_adu : 0.0;  // shot-noise variance = model * inv_gain (ADU^2)
    w_cur_.assign(v_.size(), 0.0);
    w_new_.assign(v_.size(), 0.0);
  }

  PsfFit Run() {
    if (!StartFromMoments()) return out_;
    ShapeFromMoments(cx_, cy_, 1e9);
    s_ = std::clamp(o_.sigma_guess_px, 0.4, 10.0);
    amp_ = sw_, bkg_ = level_;
    info_ = Mat5::Identity();
    if (o_.fit) {
      LevenbergMarquardt();
    } else {
      Residual(cx_, cy_, amp_, bkg_, s_, &info_, nullptr);
    }
    out_.ok = amp_ > 0 && std::isfinite(cx_) && std::isfinite(cy_);
    // With the fitted centre and width known, the shape is measured again within 2.5 fitted sigma:
    // for a sharp PSF (sigma ~0.5 px) the whole window's moments are dominated by noise pixels a few
    // pixels out and make a round star look elongated. A cosmic-ray track or a blend keeps its
    // elongation, being elongated on the scale of its own fitted width.
    if (out_.ok && o_.fit && !smeared_) ShapeFromMoments(cx_, cy_, std::max(1.5, 2.5 * s_));
    if (out_.ok && o_.fit && smeared_) SmearedShape();
    out_.x_px = cx_;
    out_.y_px = cy_;
    out_.flux_adu = amp_;
    out_.background_adu = bkg_;
    out_.sigma_px = s_;
    CentroidCovariance();
    // SNR of the flux in a PSF-matched aperture (noise-equivalent area 4 pi s^2).
    const double nea = 4 * 3.14159265358979 * s_ * s_ * (smeared_ ? SmearNeaFactor(smear_len_, s_) : 1.0);
    out_.snr = amp_ / std::sqrt((o_.gain_e_per_adu > 0 ? std::max(amp_, 0.0) / o_.gain_e_per_adu : 0.0) + nea * var_n_);
    return out_;
  }

 private:
  size_t Index(int x, int y) const { return static_cast<size_t>(y - y0_) * nx_ + (x - x0_); }

  // Start: weighted moments of the positive part above the local background (false: no signal).
  bool StartFromMoments() {
    double sx = 0, sy = 0;
    for (int y = y0_; y <= y1_; ++y) {
      for (int x = x0_; x <= x1_; ++x) {
        const size_t i = Index(x, y);
        const double a = v_[i] - level_;
        if (!use_[i] || a <= 2 * sigma_n_) continue;
        sw_ += a;
        sx += a * x;
        sy += a * y;
      }
    }
    if (sw_ <= 0) return false;
    cx_ = sx / sw_, cy_ = sy / sw_;
    if (smeared_) SmearedStart();
    start_x_ = cx_, start_y_ = cy_;  // the fallback of a failed fit
    return true;
  }

  // The smeared window is large and its noise pixels pull the whole-window moments off the star:
  // start from the moments within reach of the smear segment around the brightest pixel, recentred a
  // few times (the segment's centre is the star's).
  void SmearedStart() {
    const double hx = 0.5 * o_.smear_dx_px, hy = 0.5 * o_.smear_dy_px, len2 = hx * hx + hy * hy;
    const double reach = std::max(2.0, 2.5 * o_.sigma_guess_px);
    cx_ = px_;
    cy_ = py_;
    for (int pass = 0; pass < 4; ++pass) {
      double w = 0, mx = 0, my = 0;
      for (int y = y0_; y <= y1_; ++y) {
        for (int x = x0_; x <= x1_; ++x) {
          const size_t i = Index(x, y);
          const double a = v_[i] - level_, dx = x - cx_, dy = y - cy_;
          if (!use_[i] || a <= 2 * sigma_n_) continue;
          const double t = std::clamp((dx * hx + dy * hy) / len2, -1.0, 1.0);
          if (std::hypot(dx - t * hx, dy - t * hy) > reach) continue;
          w += a;
          mx += a * x;
          my += a * y;
        }
      }
      if (w <= 0) break;
      cx_ = mx / w;
      cy_ = my / w;
    }
  }

  // Elongation and major-axis sigma from the second moments of the pixels above 2 sigma_n within
  // `radius` of (mx, my).
  void ShapeFromMoments(double mx, double my, double radius) {
    double w = 0, mxx = 0, myy = 0, mxy = 0;
    for (int y = y0_; y <= y1_; ++y) {
      for (int x = x0_; x <= x1_; ++x) {
        const size_t i = Index(x, y);
        const double a = v_[i] - level_, dx = x - mx, dy = y - my;
        if (!use_[i] || a <= 2 * sigma_n_ || dx * dx + dy * dy > radius * radius) continue;
        w += a;
        mxx += a * dx * dx;
        myy += a * dy * dy;
        mxy += a * dx * dy;
      }
    }
    if (w <= 0) return;
    ShapeFromSecondMoments(mxx / w, myy / w, mxy / w, &out_);
  }

  // chi2 and, on request, the normal equations J^T W J and J^T W r of the five parameters. The
  // still model is separable, A fx(a) fy(b), so each pixel's Jacobian row is a few products of the
  // per-axis profiles; only the 15 distinct entries of the symmetric J^T W J are summed (scalar
  // accumulators: about a quarter of the work of a 5x5 outer product per pixel). Each pixel's weight
  // goes to w_new; with chi2_frozen, the chi2 under the weights w_cur of the current iterate is
  // summed there too.
  double Residual(double xc, double yc, double A, double B, double ss, Mat5* jtj, Vec5* jtr,
                  double* chi2_frozen = nullptr) {
    return smeared_ ? ResidualSmeared(xc, yc, A, B, ss, jtj, jtr, chi2_frozen)
                    : ResidualStill(xc, yc, A, B, ss, jtj, jtr, chi2_frozen);
  }

  double ResidualStill(double xc, double yc, double A, double B, double ss, Mat5* jtj, Vec5* jtr, double* chi2_frozen) {
    fx_.Compute(x0_, nx_, xc, ss);
    fy_.Compute(y0_, ny_, yc, ss);
    double chi2 = 0;
    NormalSums ns;
    for (int b = 0; b < ny_; ++b) {
      const double fyb = fy_.f[b], dyb = A * fy_.dc[b], syb = A * fy_.ds[b];
      const size_t row = static_cast<size_t>(b) * nx_;
      for (int a = 0; a < nx_; ++a) {
        if (!use_[row + a]) continue;
        const double fxa = fx_.f[a];
        const double j2 = fxa * fyb;
        const double m = A * j2;
        const double wgt = 1.0 / (var_n_ + std::max(m, 0.0) * inv_gain_), res = v_[row + a] - (B + m);
        const double wr = wgt * res;
        chi2 += wr * res;
        w_new_[row + a] = wgt;
        if (chi2_frozen) *chi2_frozen += w_cur_[row + a] * res * res;
        if (!jtj) continue;
        const double j0 = A * fx_.dc[a] * fyb, j1 = fxa * dyb, j4 = A * fx_.ds[a] * fyb + fxa * syb;
        ns.Add(wgt, wr, j0, j1, j2, j4);
      }
    }
    ns.Fill(jtj, jtr);
    return chi2;
  }

  // The same sums for the smeared model (SmearModel), kept apart so that the still path is untouched.
  double ResidualSmeared(double xc, double yc, double A, double B, double ss, Mat5* jtj, Vec5* jtr,
                         double* chi2_frozen) {
    sm_.Compute(x0_, nx_, y0_, ny_, xc, yc, ss, o_.smear_dx_px, o_.smear_dy_px);
    double chi2 = 0;
    NormalSums ns;
    for (size_t i = 0; i < v_.size(); ++i) {
      if (!use_[i]) continue;
      const double j2 = sm_.f[i], m = A * j2;
      const double wgt = 1.0 / (var_n_ + std::max(m, 0.0) * inv_gain_), res = v_[i] - (B + m);
      const double wr = wgt * res;
      chi2 += wr * res;
      w_new_[i] = wgt;
      if (chi2_frozen) *chi2_frozen += w_cur_[i] * res * res;
      if (!jtj) continue;
      const double j0 = A * sm_.dx[i], j1 = A * sm_.dy[i], j4 = A * sm_.ds[i];
      ns.Add(wgt, wr, j0, j1, j2, j4);
    }
    ns.Fill(jtj, jtr);
    return chi2;
  }

  // Levenberg-Marquardt on (x, y, flux, background, sigma); info_ and fit_chi2_ at the solution. A
  // fit that runs off the window or loses its signal falls back to the moments.
  void LevenbergMarquardt() {
    double lambda = 1e-4;
    Mat5 jtj;
    Vec5 jtr;
    double chi2 = Residual(cx_, cy_, amp_, bkg_, s_, &jtj, &jtr);
    std::swap(w_cur_, w_new_);
    for (int it = 0; it < o_.max_iterations; ++it) {
      out_.iterations = it + 1;
      Mat5 a = jtj;
      for (int k = 0; k < 5; ++k) a(k, k) *= 1.0 + lambda;
      const Vec5 d = a.ldlt().solve(jtr);
      if (!d.allFinite()) break;
      // 2e-3 px is far below any centroid's noise (0.01 px at SNR 500): a small, nearly undamped
      // step ends the fit without evaluating it.
      const bool small_step = std::abs(d(0)) < 2e-3 && std::abs(d(1)) < 2e-3 && std::abs(d(4)) < 5e-3;
      if (small_step && lambda <= 1e-2) {
        cx_ += d(0);
        cy_ += d(1);
        amp_ += d(2);
        bkg_ += d(3);
        s_ = std::clamp(s_ + d(4), 0.3, 3.0 * r_);
        break;
      }
      const double nxc = cx_ + d(0), nyc = cy_ + d(1), na = amp_ + d(2), nb = bkg_ + d(3);
      const double ns = std::clamp(s_ + d(4), 0.3, 3.0 * r_);
      Mat5 jtj2;
      Vec5 jtr2;
      // The step is judged with the weights held at the current iterate (iteratively reweighted
      // least squares): with shot-noise weights, the chi2 under the trial's own weights is not
      // what the Gauss-Newton step lowers, and near the solution it would refuse good steps.
      double chi2_frozen = 0;
      const double chi2n = Residual(nxc, nyc, na, nb, ns, &jtj2, &jtr2, &chi2_frozen);
      if (chi2_frozen <= chi2) {
        cx_ = nxc;
        cy_ = nyc;
        amp_ = na;
        bkg_ = nb;
        s_ = ns;
        chi2 = chi2n;
        jtj = jtj2;
        jtr = jtr2;
        std::swap(w_cur_, w_new_);
        lambda = std::max(lambda * 0.1, 1e-8);
        if (small_step) break;
      } else {
        lambda *= 10;
        if (lambda > 1e8) break;
      }
    }
    info_ = jtj;
    fit_chi2_ = chi2;
    if (!(amp_ > 0) || std::abs(cx_ - px_) > rx_ || std::abs(cy_ - py_) > ry_ || !std::isfinite(cx_ + cy_)) {
      cx_ = start_x_;
      cy_ = start_y_;
      amp_ = sw_;
      bkg_ = level_;
      s_ = o_.sigma_guess_px;
      Residual(cx_, cy_, amp_, bkg_, s_, &info_, nullptr);
      fit_chi2_ = -1;
    }
  }

  // Smeared: the second moments of the data (less the fitted background) against those of the
  // fitted smeared model, over the same pixels: where the model is above 2 sigma_n, within 2.5 sigma
  // of the smear segment. E = M_data - M_model + s^2 I is round (elongation 1) when the image is the
  // predicted smear; a track of another direction or length keeps its elongation.
  void SmearedShape() {
    sm_.Compute(x0_, nx_, y0_, ny_, cx_, cy_, s_, o_.smear_dx_px, o_.smear_dy_px);
    const double hx = 0.5 * o_.smear_dx_px, hy = 0.5 * o_.smear_dy_px, len2 = hx * hx + hy * hy;
    const double reach = std::max(1.5, 2.5 * s_);
    Eigen::Matrix2d md = Eigen::Matrix2d::Zero(), mm = Eigen::Matrix2d::Zero();
    double wd = 0, wm = 0;
    for (int y = y0_; y <= y1_; ++y) {
      for (int x = x0_; x <= x1_; ++x) {
        const size_t i = Index(x, y);
        if (!use_[i]) continue;
        const double dx = x - cx_, dy = y - cy_;
        const double t = std::clamp((dx * hx + dy * hy) / len2, -1.0, 1.0);  // nearest point of the segment
        if (std::hypot(dx - t * hx, dy - t * hy) > reach) continue;
        const Eigen::Vector2d d(dx, dy);
        const double a = v_[i] - bkg_, m = amp_ * sm_.f[i];
        if (m > 2 * sigma_n_) {
          md += a * d * d.transpose();
          wd += a;
          mm += m * d * d.transpose();
          wm += m;
        }
      }
    }
    if (!(wd > 0 && wm > 0)) return;
    Eigen::Matrix2d e = md / wd - mm / wm + s_ * s_ * Eigen::Matrix2d::Identity();
    // The data's along-smear moment is noisy (relative error of order sqrt(2) / SNR of its variance
    // s^2 + L^2 / 12), so along the smear a difference of 7 / SNR of that variance, and never more
    // than half the smear's own variance, is forgiven before the rest enters the elongation; a smear
    // across the predicted one or 1.5x as long exceeds it. Across the smear the test is the still
    // one.
    const double gain = o_.gain_e_per_adu;
    const double var_along = s_ * s_ + smear_len_ * smear_len_ / 12;
    const double nea_s = 4 * kPi * s_ * s_ * SmearNeaFactor(smear_len_, s_);
    const double snr_s = amp_ / std::sqrt((gain > 0 ? amp_ / gain : 0.0) + nea_s * var_n_);
    const Eigen::Vector2d u = Eigen::Vector2d(hx, hy).normalized();
    const double tol = std::min(0.5 * smear_len_ * smear_len_ / 12, 7.0 * var_along / std::max(snr_s, 1.0));
    const double e_uu = u.dot(e * u);
    const double e_uu_kept = s_ * s_ + std::copysign(std::max(0.0, std::abs(e_uu - s_ * s_) - tol), e_uu - s_ * s_);
    e += (e_uu_kept - e_uu) * u * u.transpose();
    ShapeFromSecondMoments(e(0, 0), e(1, 1), e(0, 1), &out_);
  }

  // The model value and Jacobian row of window pixel i at the solution (after PrepareModel).
  void PrepareModel() {
    if (smeared_) {
      sm_.Compute(x0_, nx_, y0_, ny_, cx_, cy_, s_, o_.smear_dx_px, o_.smear_dy_px);
    } else {
      fx_.Compute(x0_, nx_, cx_, s_);
      fy_.Compute(y0_, ny_, cy_, s_);
    }
  }
  double ModelAt(size_t i) const {
    if (smeared_) return amp_ * sm_.f[i];
    const size_t a = i % nx_, b = i / nx_;
    return amp_ * fx_.f[a] * fy_.f[b];
  }
  Vec5 JacobianAt(size_t i) const {
    Vec5 j;
    if (smeared_) {
      j << amp_ * sm_.dx[i], amp_ * sm_.dy[i], sm_.f[i], 1.0, amp_ * sm_.ds[i];
    } else {
      const size_t a = i % nx_, b = i / nx_;
      j << amp_ * fx_.dc[a] * fy_.f[b], amp_ * fx_.f[a] * fy_.dc[b], fx_.f[a] * fy_.f[b], 1.0,
          amp_ * (fx_.ds[a] * fy_.f[b] + fx_.f[a] * fy_.ds[b]);
    }
    return j;
  }

  // x and y sigmas from the inverse normal matrix. Without the gain the weights hold the background
  // noise only and the star's shot noise is missing from them: the inverse normal matrix then
  // understates the scatter of bright stars (simulated frames: normalised centroid errors 1.34 rms,
  // 2.0 at SNR > 200). The residuals carry the missing variance: var_i = var_n + m_i / g gives
  // 1/g = sum(r_i^2 - var_n) / sum(m_i) over the window (r_i^2 scaled by N / (N - 5) for the five
  // fitted parameters). The centroid was fitted with weights W = 1 / var_n, so its covariance is the
  // sandwich H^-1 (J' W S W J) H^-1 with H = J' W J and S = diag(var_i) (e.g. Huber-White; Seber &
  // Wild, Nonlinear Regression, sec. 2.1.4), not H^-1.
  void CentroidCovariance() {
    Eigen::Matrix<double, 5, 2> cov;
    const Eigen::LDLT<Mat5> ldlt(info_);
    // Only the x and y variances are needed: two solves instead of a general 5x5 inverse.
    cov.col(0) = ldlt.solve(Vec5::Unit(0));
    cov.col(1) = ldlt.solve(Vec5::Unit(1));
    if (o_.gain_e_per_adu <= 0 && fit_chi2_ > 0) {
      PrepareModel();
      double excess = 0, model = 0;
      int n_used = 0;
      for (size_t i = 0; i < v_.size(); ++i) {
        if (!use_[i]) continue;
        const double m = ModelAt(i), res = v_[i] - (bkg_ + m);
        excess += res * res - var_n_;
        model += std::max(m, 0.0);
        ++n_used;
      }
      if (n_used > 10 && model > 0 && excess > 0) {
        const double inv_g = excess * n_used / (n_used - 5.0) / model;
        Mat5 meat = Mat5::Zero();
        for (size_t i = 0; i < v_.size(); ++i) {
          if (!use_[i]) continue;
          const double var_i = var_n_ + std::max(ModelAt(i), 0.0) * inv_g;
          const Vec5 j = JacobianAt(i);
          meat.noalias() += (var_i / (var_n_ * var_n_)) * j * j.transpose();
        }
        const Eigen::Matrix<double, 5, 2> hx = cov;  // H^-1 columns 0 and 1
        cov.col(0) = meat * hx.col(0);
        cov.col(1) = meat * hx.col(1);
        cov(0, 0) = hx.col(0).dot(cov.col(0));
        cov(1, 1) = hx.col(1).dot(cov.col(1));
      }
    }
    out_.x_sigma_px = std::sqrt(std::max(cov(0, 0), 0.0));
    out_.y_sigma_px = std::sqrt(std::max(cov(1, 1), 0.0));
  }

  const PsfFitOptions& o_;
  int px_, py_, r_;
  double level_, sigma_n_, var_n_;
  bool smeared_ = false;
  double smear_len_ = 0;
  int rx_ = 0, ry_ = 0, x0_ = 0, x1_ = 0, y0_ = 0, y1_ = 0, nx_ = 0, ny_ = 0;
  // Window pixels, their use and weights, and the model: the scratch's buffers.
  ScratchVec<double>& v_;
  ScratchVec<uint8_t>& use_;
  ScratchVec<double>&w_cur_, &w_new_;  // pixel weights at the current iterate and the trial
  PsfProfile &fx_, &fy_;
  PsfSmearModel& sm_;
  double inv_gain_ = 0;
  double sw_ = 0;                     // moment sum of the start
  double start_x_ = 0, start_y_ = 0;  // the moments' centre (the fallback of a failed fit)
  double cx_ = 0, cy_ = 0, s_ = 0, amp_ = 0, bkg_ = 0;
  Mat5 info_;
  double fit_chi2_ = -1;  // chi2 at the solution; < 0 when there is none (moments only)
  PsfFit out_;
};

}  // namespace

PsfFit FitPsf(const ImageView& img, int px, int py, int r, double level, double sigma_n, const PsfFitOptions& o,
              PixelTest is_bad, PsfFitScratch* scratch) {
  return PsfFitter(img, px, py, r, level, sigma_n, o, is_bad, scratch).Run();
}

PsfFit FitPsf(const ImageView& img, int px, int py, int r, double level, double sigma_n, const PsfFitOptions& o,
              const std::function<bool(int, int)>& is_bad) {
  PsfFitScratch scratch;
  return FitPsf(img, px, py, r, level, sigma_n, o, PixelTest(is_bad), &scratch);
}

}  // namespace ssiu
