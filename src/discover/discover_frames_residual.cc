// `unexplained` for `ssiu discover frames` (docs/discrepancy.md): after every geometric cause of the
// vocabulary is fitted (the fullest model) and the vignetting law is fitted to the photometry, what is
// left of the star positions (a map over the focal plane) and of the fluxes is tested for structure.
// Each test is an F test of extra columns against the fitted model (the noise being the scatter the
// extra columns leave): a cubic field over the focal plane, the means of a grid of cells (a local
// pattern) and a dependence on the star's magnitude.
#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/fisher_f.hpp>
#include <cmath>

#include "core/types.h"
#include "discover/discover_frames_internal.h"

namespace ssiu::discover_internal {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

struct ExtraFit {
  FrameResidualTest test;
  VectorXd fitted;    // the part of y the extra columns explain (rows of y)
  double scale2 = 0;  // residual variance of the full fit
};

// Residual of y on the columns of x (each scaled to unit norm first, so that the rank threshold is
// relative), and the rank of x.
VectorXd ResidualOn(const MatrixXd& x, const VectorXd& y, int* rank) {
  MatrixXd xs = x;
  for (int k = 0; k < xs.cols(); ++k) {
    const double nrm = xs.col(k).norm();
    if (nrm > 0) xs.col(k) /= nrm;
  }
  Eigen::CompleteOrthogonalDecomposition<MatrixXd> qr;
  qr.setThreshold(1e-8);
  qr.compute(xs);
  *rank = static_cast<int>(qr.rank());
  if (*rank == 0) return y;
  return y - xs * qr.solve(y);
}

// F test of `extra` against `nuisance` (Fisher; degrees of freedom from the ranks, so that extra
// columns inside the fitted model's span count for nothing).
ExtraFit FTestExtra(const std::string& name, const MatrixXd& nuisance, const MatrixXd& extra, const VectorXd& y) {
  ExtraFit out;
  out.test.name = name;
  const int n = static_cast<int>(y.size());
  MatrixXd full(n, nuisance.cols() + extra.cols());
  full << nuisance, extra;
  int r0 = 0, r1 = 0;
  const VectorXd e0 = ResidualOn(nuisance, y, &r0);
  const VectorXd e1 = ResidualOn(full, y, &r1);
  const int q = r1 - r0, dof = n - r1;
  if (q < 1 || dof < 5) return out;
  const double ss1 = e1.squaredNorm(), ss0 = e0.squaredNorm();
  if (!(ss1 > 1e-12 * y.squaredNorm())) return out;  // noise-free (synthetic) data: no scale to test against
  out.test.tested = true;
  out.test.dof = q;
  out.test.dof_resid = dof;
  out.test.f = std::max(0.0, (ss0 - ss1) / q / (ss1 / dof));
  if (!std::isfinite(out.test.f)) return ExtraFit{};  // boost's distributions throw on a non-finite statistic
  out.test.p_value = boost::math::cdf(boost::math::complement(boost::math::fisher_f(q, dof), out.test.f));
  out.fitted = e0 - e1;
  out.scale2 = ss1 / dof;
  return out;
}

// Per-row weights 1 / sd of the residual e within the row's magnitude quartile: the noise's dependence
// on brightness estimated from the data (centroid sigmas and flux errors need not be honest, and an
// F test with faint stars noisier than bright ones would find "structure" in the magnitude columns).
VectorXd MagnitudeWeights(const std::vector<double>& row_mag, const VectorXd& e) {
  const int n = static_cast<int>(row_mag.size());
  std::vector<double> sorted = row_mag;
  std::sort(sorted.begin(), sorted.end());
  double cut[3];
  for (int k = 0; k < 3; ++k) cut[k] = sorted[static_cast<size_t>((k + 1) * n / 4)];
  auto group = [&](double m) { return (m >= cut[0]) + (m >= cut[1]) + (m >= cut[2]); };
  double ss[4] = {0, 0, 0, 0};
  int cnt[4] = {0, 0, 0, 0};
  for (int i = 0; i < n; ++i) ss[group(row_mag[i])] += e(i) * e(i), ++cnt[group(row_mag[i])];
  double all = e.squaredNorm() / std::max(1, n);
  VectorXd w(n);
  for (int i = 0; i < n; ++i) {
    const int g = group(row_mag[i]);
    const double var = cnt[g] >= 5 && ss[g] > 0 ? ss[g] / cnt[g] : all;
    w(i) = var > 0 ? 1 / std::sqrt(var) : 1.0;
  }
  return w;
}

// Monomials a^i b^j, lo <= i + j <= 3, of the normalised field position.
std::vector<double> Monomials(double a, double b, int lo) {
  std::vector<double> m;
  for (int deg = lo; deg <= 3; ++deg) {
    for (int i = deg; i >= 0; --i) m.push_back(std::pow(a, i) * std::pow(b, deg - i));
  }
  return m;
}

// The steps of TestFrameResidual: F tests of extra columns on the position and photometry
// residuals, descriptions of the strongest structure, and the combined (Bonferroni) verdict.
class FrameResidualTester {
 public:
  FrameResidualTester(const SolvedFrameSet& set, const Camera& camera, const MatrixXd& jac, const VectorXd& res_w,
                      const FrameDiscoverOptions& o)
      : set_(set),
        camera_(camera),
        jac_(jac),
        res_w_(res_w),
        o_(o),
        ns_(static_cast<int>(set.stars.size())),
        nf_(static_cast<int>(set.q.size())) {}

  FrameResidual Run() {
    if (ns_ < 10 || nf_ == 0) return out_;
    half_diag_ = 0.5 * std::hypot(camera_.width, camera_.height);
    // Grid of the cell tests: as many cells as the stars fill with residual_min_stars_per_cell each.
    grid_ = std::clamp(static_cast<int>(std::sqrt(ns_ / static_cast<double>(o_.residual_min_stars_per_cell))), 2, 4);
    for (const auto& s : set_.stars) mean_mag_ += s.mag / ns_;
    // Positions: rows 2i (x) and 2i + 1 (y), whitened as res_w.
    const bool positions = res_w_.size() == 2 * ns_ && jac_.rows() == 2 * ns_;
    sig_.resize(ns_);
    for (int i = 0; i < ns_; ++i) sig_[i] = std::max(set_.stars[i].sigma_px, o_.min_sigma_px);
    // Where the fitted model puts each star: the extra columns are functions of these, not of the
    // measured positions (whose noise is the residual itself: a field linear in the measured x would
    // contain it).
    px_.resize(ns_), py_.resize(ns_);
    for (int i = 0; i < ns_; ++i) {
      px_[i] = set_.stars[i].x_px - (positions ? res_w_(2 * i) * sig_[i] : 0.0);
      py_[i] = set_.stars[i].y_px - (positions ? res_w_(2 * i + 1) * sig_[i] : 0.0);
    }
    if (positions) PositionTests();
    PhotometryTests();
    DescribePositions();
    int ntests = 0;
    double pmin = 1;
    for (const auto& f : fits_) {
      if (!f.test.tested) continue;
      out_.tests.push_back(f.test);
      ++ntests;
      if (f.test.p_value < pmin) pmin = f.test.p_value, out_.finding = f.test.name;
    }
    out_.p_value = std::min(1.0, ntests * pmin);
    out_.structured = ntests > 0 && out_.p_value < o_.residual_alpha;
    return out_;
  }

 private:
  int CellOf(double x, double y) const {
    // (clamped as doubles: a star the model puts far outside must not overflow the cast)
    auto index = [&](double t, int size) {
      const double u = (t + 0.5) / size * grid_;
      return std::isfinite(u) ? static_cast<int>(std::clamp(u, 0.0, grid_ - 1.0)) : 0;
    };
    const int cx = index(x, camera_.width), cy = index(y, camera_.height);
    return cy * grid_ + cx;
  }

  // The strongest tested structure whose name starts with `prefix` (nullptr: none).
  const ExtraFit* Strongest(const char* prefix) const {
    const ExtraFit* best = nullptr;
    for (const auto& f : fits_) {
      if (f.test.tested && f.test.name.rfind(prefix, 0) == 0 && (!best || f.test.p_value < best->test.p_value))
        best = &f;
    }
    return best;
  }

  // Position residual against a cubic polynomial field, per-cell offsets and magnitude terms.
  void PositionTests() {
    const int ns = ns_, grid = grid_;
    const int nm = static_cast<int>(Monomials(0, 0, 0).size());
    MatrixXd poly = MatrixXd::Zero(2 * ns, 2 * nm), cells = MatrixXd::Zero(2 * ns, 2 * grid * grid),
             mag = MatrixXd::Zero(2 * ns, 6);
    for (int i = 0; i < ns; ++i) {
      const auto& s = set_.stars[i];
      const double w = 1 / sig_[i], a = (px_[i] - camera_.cx_px) / half_diag_,
                   b = (py_[i] - camera_.cy_px) / half_diag_;
      const auto m = Monomials(a, b, 0);
      const int c = CellOf(px_[i], py_[i]);
      // Saturated stars are left out of the magnitude columns: their clipped centroids are noise here.
      const double dm = s.saturated ? 0.0 : s.mag - mean_mag_, mm[3] = {dm, dm * a, dm * b};
      for (int comp = 0; comp < 2; ++comp) {
        for (int k = 0; k < nm; ++k) poly(2 * i + comp, comp * nm + k) = m[k] * w;
        cells(2 * i + comp, comp * grid * grid + c) = w;
        for (int k = 0; k < 3; ++k) mag(2 * i + comp, comp * 3 + k) = mm[k] * w;
      }
    }
    std::vector<double> row_mag(2 * ns);
    for (int i = 0; i < 2 * ns; ++i) row_mag[i] = set_.stars[i / 2].mag;
    int r0 = 0;
    const VectorXd wq = MagnitudeWeights(row_mag, ResidualOn(jac_, res_w_, &r0));
    const MatrixXd jq = wq.asDiagonal() * jac_;
    const VectorXd yq = wq.asDiagonal() * res_w_;
    fits_.push_back(FTestExtra("position_polynomial", jq, wq.asDiagonal() * poly, yq));
    if (ns >= 4 * o_.residual_min_stars_per_cell)
      fits_.push_back(FTestExtra("position_cells", jq, wq.asDiagonal() * cells, yq));
    fits_.push_back(FTestExtra("position_magnitude", jq, wq.asDiagonal() * mag, yq));
    for (auto& f : fits_) {
      if (f.test.tested) f.fitted = f.fitted.cwiseQuotient(wq);  // back to res_w's units
    }
  }

  // Photometry: y = ln(flux) + 0.4 ln(10) V about the fitted vignetting law, per-frame zero points
  // and the law's derivative in v as the fitted model; saturated stars left out. The strongest
  // photometric structure is described (mag).
  void PhotometryTests() {
    std::vector<int> phot;
    for (int i = 0; i < ns_; ++i) {
      if (set_.stars[i].flux > 0 && !set_.stars[i].saturated) phot.push_back(i);
    }
    const int np = static_cast<int>(phot.size());
    if (np < 10) return;
    std::vector<double> u(np), y(np);
    for (int k = 0; k < np; ++k) {
      const auto& s = set_.stars[phot[k]];
      u[k] = VignettingRadius2(camera_, s.x_px, s.y_px);
      y[k] = std::log(s.flux) + 0.4 * std::log(10.0) * s.mag;
    }
    const double v = FitVignettingLaw(u, y, nullptr);
    const int nm = static_cast<int>(Monomials(0, 0, 1).size());
    VectorXd yv(np);
    MatrixXd nuis = MatrixXd::Zero(np, nf_ + 1), poly(np, nm), cells = MatrixXd::Zero(np, grid_ * grid_), mag(np, 2);
    for (int k = 0; k < np; ++k) {
      const auto& s = set_.stars[phot[k]];
      yv(k) = y[k] - std::log(1 - v * u[k]);
      nuis(k, s.frame) = 1;
      nuis(k, nf_) = -u[k] / (1 - v * u[k]);
      const auto m = Monomials((s.x_px - camera_.cx_px) / half_diag_, (s.y_px - camera_.cy_px) / half_diag_, 1);
      for (int j = 0; j < nm; ++j) poly(k, j) = m[j];
      cells(k, CellOf(s.x_px, s.y_px)) = 1;
      mag(k, 0) = s.mag - mean_mag_;
      mag(k, 1) = std::pow(s.mag - mean_mag_, 2);
    }
    std::vector<double> row_mag(np);
    for (int k = 0; k < np; ++k) row_mag[k] = set_.stars[phot[k]].mag;
    int r0 = 0;
    const VectorXd wq = MagnitudeWeights(row_mag, ResidualOn(nuis, yv, &r0));
    nuis = wq.asDiagonal() * nuis;
    yv = wq.asDiagonal() * yv;
    const size_t first = fits_.size();
    fits_.push_back(FTestExtra("photometry_polynomial", nuis, wq.asDiagonal() * poly, yv));
    if (np >= 4 * o_.residual_min_stars_per_cell)
      fits_.push_back(FTestExtra("photometry_cells", nuis, wq.asDiagonal() * cells, yv));
    fits_.push_back(FTestExtra("photometry_magnitude", nuis, wq.asDiagonal() * mag, yv));
    for (size_t k = first; k < fits_.size(); ++k) {
      if (fits_[k].test.tested) fits_[k].fitted = fits_[k].fitted.cwiseQuotient(wq);
    }
    const ExtraFit* best = Strongest("photometry");
    if (!best) return;
    const double to_mag = 2.5 / std::log(10.0);
    double ss = 0;
    for (int k = 0; k < np; ++k) {
      const double a = std::abs(best->fitted(k)) * to_mag;
      ss += a * a;
      if (a > out_.photometry_max_mag) {
        out_.photometry_max_mag = a;
        out_.photometry_max_x_px = set_.stars[phot[k]].x_px;
        out_.photometry_max_y_px = set_.stars[phot[k]].y_px;
      }
    }
    out_.photometry_rms_mag = std::sqrt(ss / np);
    // Slope of the flux residual against V (mag per mag; > 0: faint stars measured too faint).
    const ExtraFit m = FTestExtra("", nuis, wq.asDiagonal() * mag.leftCols(1), yv);
    if (m.test.tested) {
      const VectorXd col = mag.col(0), fitted = m.fitted.cwiseQuotient(wq);
      out_.photometry_per_mag = -fitted.dot(col) / col.squaredNorm() * to_mag;
    }
  }

  // Description of the strongest position structure (px): its RMS and largest shift, the shift per
  // magnitude, and the cell of the largest mean residual.
  void DescribePositions() {
    const ExtraFit* best = Strongest("position");
    if (!best) return;
    const int ns = ns_, grid = grid_;
    const double arcsec_per_px = kRadToArcsec / camera_.FocalMeanPx();
    double ss = 0;
    for (int i = 0; i < ns; ++i) {
      const double dx = best->fitted(2 * i) * sig_[i], dy = best->fitted(2 * i + 1) * sig_[i];
      const double a = std::hypot(dx, dy);
      ss += a * a;
      if (a > out_.position_max_px) {
        out_.position_max_px = a;
        out_.position_max_x_px = set_.stars[i].x_px;
        out_.position_max_y_px = set_.stars[i].y_px;
        out_.position_max_angle_deg = std::atan2(dy, dx) * kRadToDeg;
      }
    }
    out_.position_rms_px = std::sqrt(ss / ns);
    out_.position_rms_arcsec = out_.position_rms_px * arcsec_per_px;
    out_.position_max_arcsec = out_.position_max_px * arcsec_per_px;
    // Largest shift per magnitude: the magnitude test's columns m' in x and in y.
    for (const auto& f : fits_) {
      if (f.test.name != "position_magnitude" || !f.test.tested) continue;
      double sdd = 0, sdx = 0, sdy = 0;
      for (int i = 0; i < ns; ++i) {
        const double dm = set_.stars[i].mag - mean_mag_;
        sdd += dm * dm, sdx += dm * f.fitted(2 * i) * sig_[i], sdy += dm * f.fitted(2 * i + 1) * sig_[i];
      }
      if (sdd > 0) out_.position_per_mag_px = std::hypot(sdx / sdd, sdy / sdd);
    }
    // The cell of the largest mean residual (weighted means of the px residual, chi^2 against the
    // scatter of the residual).
    out_.grid = grid;
    std::vector<double> sw(grid * grid, 0), sx(grid * grid, 0), sy(grid * grid, 0);
    std::vector<int> cnt(grid * grid, 0);
    for (int i = 0; i < ns; ++i) {
      const int c = CellOf(px_[i], py_[i]);
      const double w2 = 1 / (sig_[i] * sig_[i]);
      sw[c] += w2, sx[c] += w2 * res_w_(2 * i) * sig_[i], sy[c] += w2 * res_w_(2 * i + 1) * sig_[i];
      ++cnt[c];
    }
    const double s2 = std::max(1e-12, res_w_.squaredNorm() / std::max<Eigen::Index>(1, res_w_.size() - jac_.cols()));
    for (int c = 0; c < grid * grid; ++c) {
      if (cnt[c] < 2) continue;
      const double mx = sx[c] / sw[c], my = sy[c] / sw[c], chi2 = (mx * mx + my * my) * sw[c] / s2;
      if (chi2 > out_.cell_chi2) {
        out_.cell_chi2 = chi2;
        out_.cell_dx_px = mx, out_.cell_dy_px = my, out_.cell_stars = cnt[c];
        out_.cell_x_px = ((c % grid) + 0.5) * camera_.width / grid - 0.5;
        out_.cell_y_px = ((c / grid) + 0.5) * camera_.height / grid - 0.5;
      }
    }
  }

  const SolvedFrameSet& set_;
  const Camera& camera_;
  const MatrixXd& jac_;
  const VectorXd& res_w_;
  const FrameDiscoverOptions& o_;
  const int ns_, nf_;
  double half_diag_ = 0, mean_mag_ = 0;
  int grid_ = 2;
  std::vector<double> sig_, px_, py_;  // centroid sigma (px) and the fitted model's star positions
  std::vector<ExtraFit> fits_;
  FrameResidual out_;
};

}  // namespace

FrameResidual TestFrameResidual(const SolvedFrameSet& set, const Camera& camera, const MatrixXd& jac,
                                const VectorXd& res_w, const FrameDiscoverOptions& o) {
  return FrameResidualTester(set, camera, jac, res_w, o).Run();
}

}  // namespace ssiu::discover_internal
