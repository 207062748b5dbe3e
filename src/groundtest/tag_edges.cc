#include "groundtest/tag_edges.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace ssiu::groundtest_internal {

Vec2 UndistortPixel(const Camera& c, const Vec2& px) {
  if (c.distortion.IsZero()) return px;
  const Vec3 d = c.Unproject(px);
  return Vec2(c.cx_px + c.focal_length_px * d.x() / d.z(), c.cy_px + c.FocalYPx() * d.y() / d.z());
}

namespace {

// Band half-width as a fraction of a tag cell, and the number of re-centred passes.
constexpr double kBandFrac = 0.45;
constexpr int kPasses = 1;

struct EdgeFit {
  Vec2 p0;              // fixed reference point (edge midpoint)
  double theta = 0;     // normal direction (cos, sin), pointing out of the tag
  double delta = 0;     // line: n . (p - p0) = delta
  Eigen::Matrix2d cov;  // of (theta, delta), per unit pixel noise
  double rss = 0;
  int n = 0;
};

double Phi(double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); }
double PhiPdf(double z) { return std::exp(-0.5 * z * z) / std::sqrt(2 * kPi); }

// Fits one side from corner a to corner b (undistorted px) of the tag centred at `centre`.
bool FitEdge(const uint8_t* img, int w, int h, const Camera& cam, const Vec2& a, const Vec2& b, const Vec2& centre,
             int border_cells, EdgeFit* f) {
  const double L = (b - a).norm();
  if (!(L > 8)) return false;
  const Vec2 e = (b - a) / L;
  Vec2 n(-e.y(), e.x());
  f->p0 = (a + b) / 2;
  if (n.dot(centre - f->p0) > 0) n = -n;
  // Band half-width: within the black border and the white ring (one cell each); away from the
  // corners, where the adjacent side's blur enters.
  const double cell = L / border_cells;
  const double R = std::clamp(kBandFrac * cell, 1.5, 4.0), margin = R + 2.0;
  if (L / 2 - margin < 3) return false;
  // Candidate pixels: bounding box of the band in the (distorted) photo.
  const Vec2 corners[4] = {a + n * (R + 3), a - n * (R + 3), b + n * (R + 3), b - n * (R + 3)};
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const Vec2& c : corners) {
    const auto d =
        cam.Project(Vec3((c.x() - cam.cx_px) / cam.focal_length_px, (c.y() - cam.cy_px) / cam.FocalYPx(), 1));
    const Vec2 p = d ? *d : c;
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x()), y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  }
  std::vector<Vec2> pts;
  std::vector<double> val;
  for (int y = std::max(0, static_cast<int>(std::floor(y0)) - 2);
       y <= std::min(h - 1, static_cast<int>(std::ceil(y1)) + 2); ++y)
    for (int x = std::max(0, static_cast<int>(std::floor(x0)) - 2);
         x <= std::min(w - 1, static_cast<int>(std::ceil(x1)) + 2); ++x) {
      const Vec2 pu = UndistortPixel(cam, Vec2(x, y));
      const Vec2 r = pu - f->p0;
      if (std::abs(r.dot(e)) > L / 2 - margin || std::abs(r.dot(n)) > R) continue;
      pts.push_back(r);
      val.push_back(img[static_cast<size_t>(y) * w + x]);
    }
  const int N = static_cast<int>(pts.size());
  if (N < 30) return false;
  double in = 0, out = 0;
  int nin = 0, nout = 0;
  for (int i = 0; i < N; ++i) {
    const double d = pts[i].dot(n);
    if (d < -R / 2) in += val[i], ++nin;
    if (d > R / 2) out += val[i], ++nout;
  }
  if (nin == 0 || nout == 0) return false;
  // Parameters: theta, delta, a (dark level), b (contrast), s (edge width).
  Eigen::Matrix<double, 5, 1> p;
  p << std::atan2(n.y(), n.x()), 0.0, in / nin, out / nout - in / nin, 1.5;
  if (!(p(3) > 5)) return false;  // no dark-to-bright step here
  Eigen::Matrix<double, 5, 5> JtJ;
  auto evaluate = [&](const Eigen::Matrix<double, 5, 1>& q, Eigen::Matrix<double, 5, 5>* jtj,
                      Eigen::Matrix<double, 5, 1>* jtr) {
    const Vec2 nn(std::cos(q(0)), std::sin(q(0))), np(-std::sin(q(0)), std::cos(q(0)));
    double rss = 0;
    if (jtj) jtj->setZero(), jtr->setZero();
    for (int i = 0; i < N; ++i) {
      const double z = (nn.dot(pts[i]) - q(1)) / q(4);
      const double m = q(2) + q(3) * Phi(z);
      const double r = val[i] - m;
      rss += r * r;
      if (!jtj) continue;
      const double dz = q(3) * PhiPdf(z);
      Eigen::Matrix<double, 5, 1> J;
      J << dz * np.dot(pts[i]) / q(4), -dz / q(4), 1.0, Phi(z), -dz * z / q(4);
      *jtj += J * J.transpose();
      *jtr += J * r;
    }
    return rss;
  };
  Eigen::Matrix<double, 5, 1> jtr;
  double rss = evaluate(p, &JtJ, &jtr), lambda = 1e-3;
  for (int it = 0; it < 50; ++it) {
    Eigen::Matrix<double, 5, 5> A = JtJ;
    A.diagonal() *= 1 + lambda;
    const Eigen::Matrix<double, 5, 1> step = A.ldlt().solve(jtr);
    Eigen::Matrix<double, 5, 1> q = p + step;
    q(4) = std::max(q(4), 0.2);
    const double rss2 = evaluate(q, nullptr, nullptr);
    if (rss2 <= rss) {
      p = q, lambda = std::max(lambda / 10, 1e-9);
      const bool done = rss - rss2 < 1e-10 * rss || step.head<2>().cwiseAbs().maxCoeff() < 1e-9;
      rss = evaluate(p, &JtJ, &jtr);
      if (done) break;
    } else {
      lambda *= 10;
      if (lambda > 1e8) break;
    }
  }
  if (!(p(3) > 0) || std::abs(p(1)) > R) return false;
  const Eigen::Matrix<double, 5, 5> C = JtJ.inverse();
  if (!C.allFinite()) return false;
  f->theta = p(0), f->delta = p(1), f->cov = C.topLeftCorner<2, 2>(), f->rss = rss, f->n = N;
  return true;
}

// Intersection of two lines n_k . (p - p0_k) = delta_k, from the 4 parameters (theta_a, delta_a,
// theta_b, delta_b).
Vec2 Intersect(const EdgeFit& A, const EdgeFit& B, const Eigen::Vector4d& q) {
  Eigen::Matrix2d M;
  M << std::cos(q(0)), std::sin(q(0)), std::cos(q(2)), std::sin(q(2));
  const Eigen::Vector2d rhs(q(1) + M.row(0).dot(A.p0), q(3) + M.row(1).dot(B.p0));
  return M.lu().solve(rhs);
}

}  // namespace

TagCornerFit FitTagCorners(const uint8_t* img, int w, int h, const Camera& cam, const std::array<Vec2, 4>& corners_px,
                           int border_cells) {
  TagCornerFit out;
  std::array<Vec2, 4> c;
  Vec2 centre = Vec2::Zero();
  for (int k = 0; k < 4; ++k) c[k] = UndistortPixel(cam, corners_px[k]), centre += c[k] / 4;
  std::array<EdgeFit, 4> edges;  // edge k from corner k to corner k+1
  for (int k = 0; k < 4; ++k)
    if (!FitEdge(img, w, h, cam, c[k], c[(k + 1) % 4], centre, border_cells, &edges[k])) return out;
  // Second pass with the band centred on the fitted sides (libapriltag's corners are ~0.1 px off).
  for (int pass = 0; pass < kPasses; ++pass) {
    std::array<Vec2, 4> c2;
    for (int k = 0; k < 4; ++k) {
      const EdgeFit &A = edges[(k + 3) % 4], &B = edges[k];
      c2[k] = Intersect(A, B, Eigen::Vector4d(A.theta, A.delta, B.theta, B.delta));
      if (!c2[k].allFinite() || (c2[k] - c[k]).norm() > 3) return out;  // parallel sides, or not this corner
    }
    for (int k = 0; k < 4; ++k)
      if (!FitEdge(img, w, h, cam, c2[k], c2[(k + 1) % 4], centre, border_cells, &edges[k])) return out;
  }
  // Corner k lies on edges k-1 and k.
  Eigen::Matrix<double, 8, 1> x0;
  auto corners_of = [&](const Eigen::Matrix<double, 8, 1>& q) {
    Eigen::Matrix<double, 8, 1> r;
    for (int k = 0; k < 4; ++k) {
      const int a = (k + 3) % 4, b = k;
      const Vec2 p = Intersect(edges[a], edges[b], Eigen::Vector4d(q(2 * a), q(2 * a + 1), q(2 * b), q(2 * b + 1)));
      r(2 * k) = p.x(), r(2 * k + 1) = p.y();
    }
    return r;
  };
  for (int k = 0; k < 4; ++k) x0(2 * k) = edges[k].theta, x0(2 * k + 1) = edges[k].delta;
  const Eigen::Matrix<double, 8, 1> c0 = corners_of(x0);
  Eigen::Matrix<double, 8, 8> J, Cl = Eigen::Matrix<double, 8, 8>::Zero();
  for (int j = 0; j < 8; ++j) {
    const double hstep = j % 2 == 0 ? 1e-6 : 1e-4;
    Eigen::Matrix<double, 8, 1> xp = x0, xm = x0;
    xp(j) += hstep, xm(j) -= hstep;
    J.col(j) = (corners_of(xp) - corners_of(xm)) / (2 * hstep);
  }
  for (int k = 0; k < 4; ++k) {
    Cl.block<2, 2>(2 * k, 2 * k) = edges[k].cov;
    out.rss_dn2 += edges[k].rss, out.pixels += edges[k].n;
  }
  out.parameters = 20;
  out.covariance = J * Cl * J.transpose();
  for (int k = 0; k < 4; ++k) {
    out.corners_px[k] = Vec2(c0(2 * k), c0(2 * k + 1));
    if (!out.corners_px[k].allFinite() || (out.corners_px[k] - c[k]).norm() > 3) return out;  // keep libapriltag's
  }
  out.ok = out.covariance.allFinite();
  return out;
}

}  // namespace ssiu::groundtest_internal
