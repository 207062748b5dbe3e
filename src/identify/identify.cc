#include "identify/identify.h"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "core/error.h"
#include "core/stats.h"
#include "identify/catalog_index.h"
#include "identify/wahba_svd.h"

namespace ssiu {

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kMinTrackedFraction = 0.3;  // tracking: matched / min(predicted, centroids)
constexpr int kMinTrackedMatches = 5;        // tracking: its chance probability is calibrated for >= 5
constexpr int kMaxOutliers = 5;              // more inconsistent matches than this: the hypothesis is dropped
double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }
// CPU time of the calling thread, for the optional outer safety limit (IdentifyOptions::timeout_ms).
double ThreadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double Angle(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

Mat3 ExpSo3(const Vec3& w) {
  const double t = w.norm();
  if (t < 1e-12) return Mat3::Identity();
  return Eigen::AngleAxisd(t, w / t).toRotationMatrix();
}

struct Context {
  const StarIdentifier* id;
  const std::vector<Centroid>* c;
  std::vector<int> order;        // centroid indices, brightest first
  std::vector<double> sigma_px;  // effective 1-sigma per centroid (with the systematic part)
  int m = 0;                     // verification centroids
  double median_sigma_px = 0;    // typical centroid sigma (with the systematic part)
  double match_radius_px = 0;
  bool photometry = false;  // fluxes usable as photometric evidence (all > 0, not all equal)
};

struct Verification {
  std::vector<StarMatch> matches;
  int n_cat = 0;
};

// Predicts all catalog stars in the field with R (sensor -> inertial) and the camera, and matches
// the first ctx.m centroids to them one-to-one, nearest pairs first, within radius_px.
// Centroids flagged in `excluded` (rejected as outliers of this hypothesis) are left out.
Verification Verify(const Context& ctx, const Camera& cam, const Mat3& r, double radius_px,
                    const std::vector<char>* excluded = nullptr) {
  Verification v;
  const SolverCatalog& cat = ctx.id->catalog();
  const std::vector<int> near = ctx.id->StarsWithin(r.col(2), cam.FovDiagRad() / 2 * 1.05 + 0.002);
  struct Proj {
    Vec2 px;
    int star;
  };
  std::vector<Proj> proj;
  proj.reserve(near.size());
  const Mat3 rt = r.transpose();
  for (int s : near) {
    const auto p = cam.Project(rt * cat.stars[s].unit);
    if (p && cam.InImage(*p)) proj.push_back({*p, s});
  }
  v.n_cat = static_cast<int>(proj.size());
  struct Cand {
    double d2;
    int c, p;
  };
  std::vector<Cand> cands;
  const double r2 = radius_px * radius_px;
  for (int i = 0; i < ctx.m; ++i) {
    const int ci = ctx.order[i];
    if (excluded && (*excluded)[ci]) continue;
    const Vec2 xy((*ctx.c)[ci].x_px, (*ctx.c)[ci].y_px);
    for (size_t p = 0; p < proj.size(); ++p) {
      const double d2 = (proj[p].px - xy).squaredNorm();
      if (d2 <= r2) cands.push_back({d2, ci, static_cast<int>(p)});
    }
  }
  std::sort(cands.begin(), cands.end(), [](const Cand& a, const Cand& b) { return a.d2 < b.d2; });
  std::vector<char> used_c(ctx.c->size(), 0), used_p(proj.size(), 0);
  for (const auto& k : cands) {
    if (used_c[k.c] || used_p[k.p]) continue;
    used_c[k.c] = used_p[k.p] = 1;
    StarMatch m;
    m.centroid = k.c;
    m.star = proj[k.p].star;
    m.star_id = cat.stars[m.star].id;
    m.mag = cat.stars[m.star].mag;
    m.x_px = (*ctx.c)[k.c].x_px;
    m.y_px = (*ctx.c)[k.c].y_px;
    m.b_sensor = cam.Unproject(Vec2(m.x_px, m.y_px));
    m.r_inertial = cat.stars[m.star].unit;
    m.sigma_rad = ctx.sigma_px[k.c] / cam.FocalMeanPx();
    v.matches.push_back(m);
  }
  return v;
}

// Radius (px, squared) of the hypothesis test at pixel p for a triangle of centroids tri_c (as in
// TestHypothesis: centroid noise plus the triangle's own rotation and scale error there).
struct TriangleSpread {
  Vec2 centre = Vec2::Zero();
  double sig_tri = 0, rho2 = 1;
};
TriangleSpread SpreadOf(const Context& ctx, const int tri_c[3]) {
  TriangleSpread t;
  const auto& c = *ctx.c;
  for (int i = 0; i < 3; ++i) {
    t.centre += Vec2(c[tri_c[i]].x_px, c[tri_c[i]].y_px) / 3.0;
    t.sig_tri = std::max(t.sig_tri, ctx.sigma_px[tri_c[i]]);
  }
  double rho2 = 0;
  for (int i = 0; i < 3; ++i) rho2 += (Vec2(c[tri_c[i]].x_px, c[tri_c[i]].y_px) - t.centre).squaredNorm();
  t.rho2 = std::max(rho2, 1.0);
  return t;
}
double TestRadius2(const Context& ctx, const IdentifyOptions& o, const TriangleSpread& t, const Vec2& p,
                   bool scale_searched) {
  const double g = scale_searched ? 2.0 : 1.0;
  const double floor_px = scale_searched ? 2 * ctx.match_radius_px : o.match_radius_px;
  const double d2 = (p - t.centre).squaredNorm();
  const double var = ctx.median_sigma_px * ctx.median_sigma_px + t.sig_tri * t.sig_tri * (1.0 / 3 + g * d2 / t.rho2);
  return std::max(o.verify_sigmas * o.verify_sigmas * var, floor_px * floor_px);
}

// The hypothesis test (stage 1): the attitude (and scale) come from the three triangle stars
// alone, so every other centroid is independent of the hypothesis and, under the null hypothesis
// (a chance pattern), falls near a predicted star with probability p_hit. Each predicted star gets
// the radius verify_sigmas * its position sigma: the centroid noise plus the error that the
// triangle's own noise puts into the prediction there (rotation about the triangle's centre and,
// when the focal length is searched, scale: both grow with the distance d from that centre as
// sigma_tri * d / sqrt(sum rho_i^2), rho_i the vertices' distances from the centre).
struct HypothesisTest {
  int extra = 0;     // matched centroids besides the triangle's three
  double p_hit = 0;  // chance that one random centroid falls within a predicted star's radius
  double worst = 0;  // largest (distance / radius)^2 among the extra matches
  int n_cat = 0;     // catalog stars predicted in the image
  Verification v;    // the triangle's three pairs plus the extra matches
};

HypothesisTest TestHypothesis(const Context& ctx, const IdentifyOptions& o, const Camera& cam, const Mat3& r,
                              const int tri_c[3], const int tri_s[3], bool scale_searched) {
  HypothesisTest h;
  const SolverCatalog& cat = ctx.id->catalog();
  const auto& c = *ctx.c;
  const TriangleSpread spread = SpreadOf(ctx, tri_c);
  const std::vector<int> near = ctx.id->StarsWithin(r.col(2), cam.FovDiagRad() / 2 * 1.05 + 0.002);
  struct Pred {
    Vec2 px;
    int star;
    double r2;
  };
  std::vector<Pred> pred;
  const Mat3 rt = r.transpose();
  double area_hit = 0;
  for (int s : near) {
    if (s == tri_s[0] || s == tri_s[1] || s == tri_s[2]) continue;
    const auto p = cam.Project(rt * cat.stars[s].unit);
    if (!p || !cam.InImage(*p)) continue;
    // In tolerance mode the camera model is known to be off (focal length, and often the pixel
    // aspect or distortion that the caller is about to calibrate): at least twice the refinement
    // radius, as the verification before this test used (the probability counts whatever radius).
    const double r2 = TestRadius2(ctx, o, spread, *p, scale_searched);
    area_hit += kPi * r2;
    pred.push_back({*p, s, r2});
  }
  h.n_cat = static_cast<int>(pred.size()) + 3;
  h.p_hit = std::min(1.0, area_hit / (static_cast<double>(cam.width) * cam.height));
  struct Cand {
    double score;  // squared distance over squared radius
    int c, p;
  };
  std::vector<Cand> cands;
  for (int i = 0; i < ctx.m; ++i) {
    const int ci = ctx.order[i];
    if (ci == tri_c[0] || ci == tri_c[1] || ci == tri_c[2]) continue;
    const Vec2 xy(c[ci].x_px, c[ci].y_px);
    for (size_t p = 0; p < pred.size(); ++p) {
      const double d2 = (pred[p].px - xy).squaredNorm();
      if (d2 <= pred[p].r2) cands.push_back({d2 / pred[p].r2, ci, static_cast<int>(p)});
    }
  }
  std::sort(cands.begin(), cands.end(), [](const Cand& a, const Cand& b) { return a.score < b.score; });
  std::vector<char> used_c(c.size(), 0), used_p(pred.size(), 0);
  auto add = [&](int ci, int s) {
    StarMatch m;
    m.centroid = ci;
    m.star = s;
    m.star_id = cat.stars[s].id;
    m.mag = cat.stars[s].mag;
    m.x_px = c[ci].x_px;
    m.y_px = c[ci].y_px;
    m.b_sensor = cam.Unproject(Vec2(m.x_px, m.y_px));
    m.r_inertial = cat.stars[s].unit;
    m.sigma_rad = ctx.sigma_px[ci] / cam.FocalMeanPx();
    h.v.matches.push_back(m);
  };
  for (int i = 0; i < 3; ++i) add(tri_c[i], tri_s[i]);
  for (const auto& k : cands) {
    if (used_c[k.c] || used_p[k.p]) continue;
    used_c[k.c] = used_p[k.p] = 1;
    add(k.c, pred[k.p].star);
    ++h.extra;
    h.worst = std::max(h.worst, k.score);
  }
  h.v.n_cat = h.n_cat;
  return h;
}

// Whether any of the kQuickCentroids brightest centroids outside the triangle lies within its test
// radius of a catalog star under the hypothesis (cam, r): a cheap necessary condition for the test
// to find an extra match among them.
bool AnyBrightCentroidNearAStar(const Context& ctx, const IdentifyOptions& o, const Camera& cam, const Mat3& r,
                                const int tri_c[3]) {
  constexpr int kQuickCentroids = 12;
  const TriangleSpread t = SpreadOf(ctx, tri_c);
  const auto& c = *ctx.c;
  const double f = cam.FocalMinPx();
  for (int i = 0, seen = 0; i < ctx.m && seen < kQuickCentroids; ++i) {
    const int ci = ctx.order[i];
    if (ci == tri_c[0] || ci == tri_c[1] || ci == tri_c[2]) continue;
    ++seen;
    const Vec2 p(c[ci].x_px, c[ci].y_px);
    const double radius_rad = std::sqrt(TestRadius2(ctx, o, t, p, true)) / f;
    if (!ctx.id->StarsWithin(r * cam.Unproject(p), radius_rad).empty()) return true;
  }
  return false;
}

Mat3 SvdFromMatches(const std::vector<StarMatch>& ms) {
  std::vector<VectorPair> pairs;
  pairs.reserve(ms.size());
  for (const auto& m : ms) pairs.push_back({m.b_sensor, m.r_inertial, 1.0 / (m.sigma_rad * m.sigma_rad)});
  return SolveWahbaSvd(pairs).toRotationMatrix();
}

// Pixel residuals (centroid - prediction) of the matches under (cam, r) and their Jacobians over
// x = (small rotation in the sensor frame, r -> r Exp(x[0..2]); common scale of fx and fy, 1 + x[3]),
// numerical, with the weights 1 / sigma_px^2 and the normal equations H = sum w J^T J, g = sum w J^T e.
struct PixelFit {
  std::vector<Eigen::Matrix<double, 2, 4>> j;
  std::vector<Vec2> e;
  std::vector<double> w;
  std::vector<char> ok;  // projected (a star behind the camera has no residual)
  Eigen::Matrix4d h = Eigen::Matrix4d::Zero();
  Vec4 g = Vec4::Zero();
};

PixelFit Linearize(const Context& ctx, const std::vector<StarMatch>& ms, const Camera& cam, const Mat3& r) {
  PixelFit f;
  auto residual = [&](const StarMatch& m, const Vec4& x, Vec2* out) {
    Camera c2 = cam;
    c2.ScaleFocal(1 + x[3]);
    const auto p = c2.Project((r * ExpSo3(x.head<3>())).transpose() * m.r_inertial);
    if (!p) return false;
    *out = Vec2(m.x_px, m.y_px) - *p;
    return true;
  };
  for (const auto& m : ms) {
    Vec2 e0 = Vec2::Zero();
    Eigen::Matrix<double, 2, 4> j = Eigen::Matrix<double, 2, 4>::Zero();
    const bool ok = residual(m, Vec4::Zero(), &e0);
    if (ok) {
      for (int k = 0; k < 4; ++k) {
        Vec4 dx = Vec4::Zero();
        dx[k] = 1e-7;
        Vec2 e1;
        if (!residual(m, dx, &e1)) e1 = e0;
        j.col(k) = -(e1 - e0) / 1e-7;  // of the prediction
      }
    }
    const double w = ok ? 1.0 / std::pow(ctx.sigma_px[m.centroid], 2) : 0.0;
    f.j.push_back(j);
    f.e.push_back(e0);
    f.w.push_back(w);
    f.ok.push_back(ok);
    f.h += w * j.transpose() * j;
    f.g += w * j.transpose() * e0;
  }
  return f;
}

// Gauss-Newton on pixel residuals over a small rotation (sensor frame) and a common scale of fx and fy
// (the pixel aspect fy/fx is the camera's).
void RefineFocal(const Context& ctx, const std::vector<StarMatch>& ms, Camera* cam, Mat3* r) {
  if (ms.size() < 4) return;
  for (int iter = 0; iter < 4; ++iter) {
    const PixelFit f = Linearize(ctx, ms, *cam, *r);
    const Vec4 dx = f.h.ldlt().solve(f.g);
    if (!dx.allFinite()) return;
    cam->ScaleFocal(1 + dx[3]);
    *r = *r * ExpSo3(dx.head<3>());
    if (dx.head<3>().norm() < 1e-10 && std::abs(dx[3]) < 1e-10) break;
  }
}

// Photometric evidence (docs/identify.md, step 5). Under the null hypothesis (a chance match) the
// fluxes are independent of the positions, so given the positions (which alone chose the hypothesis
// and its matches) the fluxes of the verification centroids are exchangeable. Two conditionally
// exact tests, each turned into an e-value (a statistic with mean 1 under the null):
// - the triangle: the rank order of its three fluxes against its three catalog magnitudes is one of
//   3! equally likely ones; p = P(D <= d) for d discordant pairs (ties count as discordant), exact
//   values 1/6, 3/6, 5/6, 1, and e = 1 / (p C), C = sum over the atoms of P(p = t) / t = 67/30;
// - each extra match in the test's (geometric) order: given the pairs before it, its flux is a
//   uniform draw from the N centroids not yet used. Its flux predicted from their zero point (median
//   of ln f + 0.4 ln(10) V) ranks K-th closest among those N (ties counted in), p = K / N and
//   e = (1 / (p H_N) + N / (K^2 S_N)) / 2, H_N the N-th harmonic number (= E[1/p]), S_N = sum 1/k^2.
// The product E of these has mean 1 (each factor's mean is 1 given the ones before), and so has the
// mixture (1 + E) / 2, which bounds the cost of photometry that disagrees (a colour term, a saturated
// star) to a factor 2. Returned: 2 / (1 + E), the factor on the geometric p-value. With p_g valid and
// E's null distribution not depending on the positions, P(p_g * 2 / (1 + E) <= x) <= x E[(1 + E) / 2] = x.
// `ms`: the triangle's three pairs first, then the extra matches in the order they were tested.
double PhotometricFactor(const Context& ctx, const std::vector<StarMatch>& ms) {
  if (!ctx.photometry || ms.size() < 3) return 1.0;
  const auto& c = *ctx.c;
  std::vector<double> flux, mag, other;
  std::vector<char> used(c.size(), 0);
  for (const auto& m : ms) flux.push_back(c[m.centroid].flux), mag.push_back(m.mag), used[m.centroid] = 1;
  for (int q = 0; q < ctx.m; ++q)
    if (!used[ctx.order[q]]) other.push_back(c[ctx.order[q]].flux);
  return 2.0 / (1.0 + PhotometricEvidence(flux, mag, other));
}

// The match least consistent with the others, if it is an outlier. For each match i, d_i = the drop
// of the fit's chi-square when i is left out: with the residual e_i at the least-squares optimum and
// its covariance S_i = sigma_i^2 I - J_i H^-1 J_i^T, d_i = e_i^T S_i^-1 e_i (the deleted residual of
// linear least squares: Cook & Weisberg 1982, "Residuals and Influence in Regression", ch. 2.2),
// chi-square with 2 degrees of freedom for a consistent match. Unlike the largest residual, it finds
// a wrong match with leverage (a false object at a corner that turns the fit of a small clump of stars
// fits itself and leaves its residual on the clump). The sigmas are scaled by the scatter of the
// others, s^2 = max(1, (chi^2 - d_i) / dof without i) (the externally studentised residual, ibid.):
// a camera model that is knowingly off (tolerance mode before calibration: aspect, distortion) makes
// every residual large, and only a match inconsistent with the rest is an outlier. Parameters: the
// rotation, and the scale when the focal length is fitted. Returns the index into ms, or -1 when
// every d_i / s^2 <= outlier_sigmas^2 (or too few degrees of freedom are left to tell). A match whose
// removal leaves a direction of the fit undetermined cannot be tested.
int WorstOutlier(const Context& ctx, const IdentifyOptions& o, const std::vector<StarMatch>& ms, const Camera& cam,
                 const Mat3& r, bool fit_scale) {
  const int np = fit_scale ? 4 : 3;
  const int dof_without = 2 * (static_cast<int>(ms.size()) - 1) - np;
  if (dof_without < 2) return -1;
  const PixelFit f = Linearize(ctx, ms, cam, r);
  const Eigen::MatrixXd h = f.h.topLeftCorner(np, np);
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(h);
  const Eigen::VectorXd dx = ldlt.solve(f.g.head(np));  // to the linearised optimum (r may be an SVD fit)
  if (!dx.allFinite()) return -1;
  std::vector<Vec2> e(ms.size(), Vec2::Zero());
  double chi2 = 0;
  for (size_t i = 0; i < ms.size(); ++i) {
    if (!f.ok[i]) continue;
    e[i] = f.e[i] - f.j[i].leftCols(np) * dx;
    chi2 += f.w[i] * e[i].squaredNorm();
  }
  int worst = -1;
  double worst_t = o.outlier_sigmas * o.outlier_sigmas;
  for (size_t i = 0; i < ms.size(); ++i) {
    if (!f.ok[i]) continue;
    // From the others alone (H without i): the prediction error of match i, e_(i) = (I + w J H_(i)^-1 J^T) e_i,
    // and its covariance sigma^2 I + J H_(i)^-1 J^T. This form stays exact when i has a leverage near
    // 1 (its own residual near 0): then it is the only match that fixes a direction of the fit.
    const Eigen::Matrix<double, 2, Eigen::Dynamic> j = f.j[i].leftCols(np);
    const Eigen::MatrixXd h_i = h - f.w[i] * j.transpose() * j;
    const Eigen::LDLT<Eigen::MatrixXd> ldlt_i(h_i);
    // The others must fix every direction (else match i cannot be tested).
    if (ldlt_i.info() != Eigen::Success || !(ldlt_i.vectorD().minCoeff() > 1e-9 * ldlt_i.vectorD().maxCoeff()))
      continue;
    const Eigen::Matrix<double, Eigen::Dynamic, 2> hj = ldlt_i.solve(j.transpose());
    const Mat2 jhj = j * hj;
    const Vec2 e_del = e[i] + f.w[i] * jhj * e[i];
    const Mat2 cov = Mat2::Identity() / f.w[i] + jhj;
    const double d = e_del.dot(cov.ldlt().solve(e_del));
    const double t = d / std::max(1.0, (chi2 - d) / dof_without);
    if (t > worst_t) worst_t = t, worst = static_cast<int>(i);
  }
  return worst;
}

// The union bound over the data-chosen count j of extra matches (docs/identify.md, step 5): 1 / w_j
// with weights w_1 = 3/4 and w_j = 1 / (4 (j - 1) j) for j >= 2 (summing to 1). A four-star solution
// (j = 1) has the thinnest evidence, so it gets most of the weight: 4/3 instead of 2 with the
// weights 1 / (j (j + 1)) used before; five stars pay 8 instead of 6, six 24 instead of 12, whose
// evidence is far stronger (docs/results.md, issue 14).
double CountFactor(int j) { return j <= 1 ? 4.0 / 3.0 : 4.0 * (j - 1.0) * j; }

struct Refined {
  Verification v;
  Mat3 r;
  Camera cam;
};

// Fit the attitude (and the focal length when it is uncertain) to the matches and re-match, twice.
Refined Refine(const Context& ctx, const IdentifyOptions& o, Camera cam, Mat3 r, Verification v,
               const std::vector<char>* excluded = nullptr) {
  for (int pass = 0; pass < 3; ++pass) {
    if (o.FocalSearched()) {
      RefineFocal(ctx, v.matches, &cam, &r);
      for (auto& m : v.matches) m.b_sensor = cam.Unproject(Vec2(m.x_px, m.y_px));
    } else {
      r = SvdFromMatches(v.matches);
    }
    Verification v2 = Verify(ctx, cam, r, ctx.match_radius_px, excluded);
    if (v2.matches.size() < 3) break;
    v = std::move(v2);
  }
  if (!o.FocalSearched()) r = SvdFromMatches(v.matches);
  for (auto& m : v.matches) {
    m.sigma_rad = ctx.sigma_px[m.centroid] / cam.FocalMeanPx();
    m.residual_rad = Angle(r * m.b_sensor, m.r_inertial);
  }
  return {std::move(v), r, cam};
}

Context MakeContext(const StarIdentifier* id, const std::vector<Centroid>& c, const IdentifyOptions& o) {
  Context ctx;
  ctx.id = id;
  ctx.c = &c;
  ctx.order.resize(c.size());
  std::iota(ctx.order.begin(), ctx.order.end(), 0);
  std::stable_sort(ctx.order.begin(), ctx.order.end(), [&](int a, int b) { return c[a].flux > c[b].flux; });
  ctx.sigma_px.resize(c.size());
  for (size_t i = 0; i < c.size(); ++i) {
    const double s = c[i].sigma_px > 0 ? c[i].sigma_px : o.centroid_sigma_px;
    ctx.sigma_px[i] = std::sqrt(s * s + o.systematic_px * o.systematic_px);
  }
  ctx.m = std::min<int>(o.verify_centroids, static_cast<int>(c.size()));
  // Radius from the typical (median) centroid noise, at least 2 px.
  ctx.median_sigma_px = ctx.sigma_px.empty() ? o.centroid_sigma_px : Median(ctx.sigma_px);
  // Photometry needs a flux on every centroid; equal fluxes (e.g. all 1) carry no evidence.
  ctx.photometry = o.use_photometry && !c.empty();
  for (const auto& x : c) ctx.photometry = ctx.photometry && x.flux > 0 && std::isfinite(std::log(x.flux));
  if (ctx.photometry)
    ctx.photometry = std::any_of(c.begin(), c.end(), [&](const Centroid& x) { return x.flux != c[0].flux; });
  ctx.match_radius_px = o.match_radius_px > 0 ? o.match_radius_px : std::max(2.0, 5.0 * ctx.median_sigma_px);
  return ctx;
}

void CheckCentroids(const std::vector<Centroid>& c) {
  for (size_t i = 0; i < c.size(); ++i) {
    if (!std::isfinite(c[i].x_px) || !std::isfinite(c[i].y_px) || !std::isfinite(c[i].flux) || !(c[i].sigma_px >= 0))
      throw InputError("centroids", "row " + std::to_string(i + 1) + ": non-finite position, flux or sigma");
  }
}

// Chance that k or more of n random centroids fall within radius_px of one of n_cat predicted stars.
double ChanceProbability(int n_trials, int n_cat, double radius_px, const Camera& cam, int k) {
  const double p = std::min(1.0, n_cat * kPi * radius_px * radius_px / (static_cast<double>(cam.width) * cam.height));
  return BinomialTail(n_trials, p, k);
}

}  // namespace

Camera FittedCamera(Camera camera, const Identification& id) {
  if (id.focal_length_px > 0 && std::isfinite(id.focal_length_px))
    camera.ScaleFocal(id.focal_length_px / camera.focal_length_px);
  return camera;
}

void IdentifyOptions::Check() const {
  auto bad = [](const std::string& f, const std::string& w) { throw InputError("identify options", f + " " + w); };
  if (pattern_centroids < 3 || pattern_centroids > 1000) bad("pattern_centroids", "must be in [3, 1000]");
  if (verify_centroids < pattern_centroids) bad("verify_centroids", "must be >= pattern_centroids");
  if (!(centroid_sigma_px > 0 && centroid_sigma_px < 20)) bad("centroid_sigma_px", "must be in (0, 20)");
  if (!(systematic_px >= 0 && systematic_px < 20)) bad("systematic_px", "must be in [0, 20)");
  if (!(tolerance_sigmas >= 1 && tolerance_sigmas <= 20)) bad("tolerance_sigmas", "must be in [1, 20]");
  if (!(side_sigmas >= 1 && side_sigmas <= 20)) bad("side_sigmas", "must be in [1, 20]");
  if (!(match_radius_px >= 0 && match_radius_px < 100)) bad("match_radius_px", "must be in [0, 100)");
  if (!(fov_tolerance_pct >= 0 && fov_tolerance_pct <= 30)) bad("fov_tolerance_pct", "must be in [0, 30]");
  if (!(fov_min_deg == 0 && fov_max_deg == 0) && !(fov_min_deg > 0.5 && fov_min_deg < fov_max_deg && fov_max_deg < 90))
    bad("fov_range_deg", "must be MIN,MAX with 0.5 < MIN < MAX < 90 deg");
  if (FovRange() && fov_tolerance_pct > 0) bad("fov_range_deg", "and fov_tolerance_pct exclude each other");
  if (!(max_false_match_prob > 0 && max_false_match_prob < 1)) bad("max_false_match_prob", "must be in (0, 1)");
  if (min_matches < 4) bad("min_matches", "must be >= 4");
  if (max_hypotheses < 1) bad("max_hypotheses", "must be >= 1");
  if (max_patterns < 1) bad("max_patterns", "must be >= 1");
  if (!(verify_sigmas >= 1 && verify_sigmas <= 10)) bad("verify_sigmas", "must be in [1, 10]");
  if (!(outlier_sigmas >= 3 && outlier_sigmas <= 100)) bad("outlier_sigmas", "must be in [3, 100]");
  if (!(timeout_ms >= 0 && timeout_ms <= 3.6e6)) bad("timeout_ms", "must be in [0, 3600000] (0 = no limit)");
}

double PhotometricEvidence(const std::vector<double>& pair_flux, const std::vector<double>& pair_mag,
                           const std::vector<double>& other_flux) {
  if (pair_flux.size() < 3 || pair_flux.size() != pair_mag.size())
    throw InputError("photometry", "need >= 3 pairs with a magnitude each");
  int disc = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = i + 1; j < 3; ++j) disc += !((pair_flux[i] - pair_flux[j]) * (pair_mag[i] - pair_mag[j]) < 0);
  static constexpr double kTriP[4] = {1.0 / 6, 3.0 / 6, 5.0 / 6, 1.0};
  static constexpr double kTriC = 1.0 + 2.0 / 3 + 2.0 / 5 + 1.0 / 6;  // sum over the atoms of P(p = t) / t
  double e = 1.0 / (kTriP[disc] * kTriC);
  const double k_mag = 0.4 * std::log(10.0);
  std::vector<double> zp;  // ln f + 0.4 ln(10) V of the pairs so far: the zero point
  for (int i = 0; i < 3; ++i) zp.push_back(std::log(pair_flux[i]) + k_mag * pair_mag[i]);
  for (size_t i = 3; i < pair_flux.size(); ++i) {
    std::vector<double> z = zp;
    std::sort(z.begin(), z.end());
    const size_t h = z.size() / 2;
    const double ln_k = z.size() % 2 ? z[h] : 0.5 * (z[h - 1] + z[h]);
    const double pred = ln_k - k_mag * pair_mag[i];
    const double d = std::abs(std::log(pair_flux[i]) - pred);
    // The pool: this match and the later ones, and the centroids in no pair (K counts ties in).
    int pool = 0, within = 0;
    auto count = [&](double f) { ++pool, within += std::abs(std::log(f) - pred) <= d; };
    for (size_t q = i; q < pair_flux.size(); ++q) count(pair_flux[q]);
    for (double f : other_flux) count(f);
    double h_n = 0, s_n = 0;
    for (int k = 1; k <= pool; ++k) h_n += 1.0 / k, s_n += 1.0 / (static_cast<double>(k) * k);
    const double kk = std::max(1, within);
    // The mean of two calibrators, each of mean 1 for K uniform on {1..N}: 1 / (p H_N) and the steeper
    // N / (K^2 S_N), S_N = sum 1/k^2 (~N / 1.64 for K = 1 instead of N / H_N, ~N / 4.3 at N = 40; it
    // falls faster with K, so the mean keeps most of the harmonic one's value for noisy fluxes).
    e *= 0.5 * (pool / (kk * h_n) + pool / (kk * kk * s_n));
    zp.push_back(std::log(pair_flux[i]) + k_mag * pair_mag[i]);
  }
  return e;
}

double BinomialTail(int n, double p, int k) {
  if (k <= 0) return 1.0;
  if (k > n) return 0.0;
  if (p <= 0) return 0.0;
  if (p >= 1) return 1.0;
  double sum = 0;
  for (int i = k; i <= n; ++i) {
    const double l = std::lgamma(n + 1.0) - std::lgamma(i + 1.0) - std::lgamma(n - i + 1.0) + i * std::log(p) +
                     (n - i) * std::log1p(-p);
    sum += std::exp(l);
  }
  return std::min(1.0, sum);
}

StarIdentifier::StarIdentifier(SolverCatalog catalog) : catalog_(std::move(catalog)) {
  // A catalog built or loaded by star_catalog.h carries its index; one assembled otherwise gets it here.
  if (catalog_.index && catalog_.index->Fits(catalog_)) {
    index_ = catalog_.index;
  } else {
    index_ = std::make_shared<const CatalogIndex>(catalog_);
    catalog_.index = index_;
  }
}

StarIdentifier::~StarIdentifier() = default;
StarIdentifier::StarIdentifier(StarIdentifier&&) noexcept = default;
StarIdentifier& StarIdentifier::operator=(StarIdentifier&&) noexcept = default;

std::vector<int> StarIdentifier::StarsWithin(const Vec3& u, double radius_rad) const {
  return index_->StarsWithin(u, radius_rad);
}

namespace {

// Step 1 of docs/identify.md: the focal-length scale searched, as the range [lo, hi] of f_true /
// f_nominal: +/- the tolerance, or with an unknown FOV the range's focal lengths around their
// geometric mean (the camera returned then has that mean focal length).
Camera SearchedCamera(const Camera& camera_in, const IdentifyOptions& o, const SolverCatalog& catalog, double* scale_lo,
                      double* scale_hi) {
  Camera camera = camera_in;
  *scale_lo = 1 - o.fov_tolerance_pct / 100.0, *scale_hi = 1 + o.fov_tolerance_pct / 100.0;
  if (!o.FovRange()) return camera;
  const double cat_min = catalog.fov_min_deg > 0 ? catalog.fov_min_deg : catalog.fov_deg;
  if (o.fov_max_deg > catalog.fov_deg * (1 + kCatalogFovTolerance) ||
      o.fov_min_deg < cat_min * (1 - kCatalogFovTolerance)) {
    char msg[200];
    std::snprintf(msg, sizeof msg, "built for fields of view %.2f-%.2f deg, the search needs %.2f-%.2f deg", cat_min,
                  catalog.fov_deg, o.fov_min_deg, o.fov_max_deg);
    throw InputError(catalog.source, msg);
  }
  const double f_hi = 0.5 * camera.width / std::tan(0.5 * o.fov_min_deg * kDegToRad);
  const double f_lo = 0.5 * camera.width / std::tan(0.5 * o.fov_max_deg * kDegToRad);
  const double f0 = std::sqrt(f_lo * f_hi);
  camera.ScaleFocal(f0 / camera.focal_length_px);
  *scale_lo = f_lo / f0;
  *scale_hi = f_hi / f0;
  return camera;
}

// Angles between the k_pat brightest centroids (row-major k_pat x k_pat), once: a deep search forms
// each pair's side in many triangles.
std::vector<double> PatternAngles(const std::vector<Centroid>& centroids, const Context& ctx, const Camera& camera,
                                  int k_pat) {
  std::vector<Vec3> u(k_pat);
  for (int i = 0; i < k_pat; ++i) {
    const auto& c = centroids[ctx.order[i]];
    u[i] = camera.Unproject(Vec2(c.x_px, c.y_px));
  }
  std::vector<double> ang(static_cast<size_t>(k_pat) * k_pat, 0.0);
  for (int i = 0; i < k_pat; ++i)
    for (int j = i + 1; j < k_pat; ++j) ang[i * k_pat + j] = ang[j * k_pat + i] = Angle(u[i], u[j]);
  return ang;
}

// An observed triangle (pattern vertices vtx, sides side[i] opposite vertex i, longest s_max) put
// against a catalog triangle (unit vectors r, sides cside) under the vertex correspondence pm.
struct TriangleMatch {
  const int* vtx;
  const int* pm;
  const double* side;
  const double* cside;
  const Vec3* const* r;
  double side_sigma;  // 1-sigma of a side from the triangle's centroid noise (rad)
  double s_max;
  double scale0;  // observed / catalog longest side
};

// Step 3 of docs/identify.md: observed vertex vtx[i] <-> catalog vertex pm[i] is a hypothesis when
// opposite sides agree, each within side_sigmas of its own error, and the handedness is the same (a
// rotation cannot mirror a triangle); then *cam (its focal length scaled by the sides when searched),
// *rot (Wahba on the three pairs) and the centroids and catalog stars of the triangle.
bool TriangleHypothesis(const Context& ctx, const IdentifyOptions& o, const std::vector<Centroid>& centroids,
                        const CatalogTriangle& t, const TriangleMatch& m, bool focal_searched, Camera* cam, Mat3* rot,
                        int tri_c[3], int tri_s[3]) {
  const int* pm = m.pm;
  // A side's error (two centroids' errors along it) has a sigma <= sqrt(2) sig_tri / f. With the
  // focal length searched the sides are compared after the scale of the longest, which adds its error
  // times the side ratio rho: sigma <= sqrt(2) sig_tri sqrt(1 + rho^2) / f. (Before: 2 tol_side = 8
  // sqrt(2) sigmas, looser than the key box, so every box hit was a hypothesis; docs/identify.md step
  // 2 has the gain.)
  for (int i = 0; i < 3; ++i) {
    const double rho = focal_searched ? m.side[i] / m.s_max : 0.0;
    const double lim = o.side_sigmas * m.side_sigma * std::sqrt(1 + rho * rho);
    if (!(std::abs(m.side[i] / (focal_searched ? m.scale0 : 1.0) - m.cside[pm[i]]) <= lim)) return false;
  }
  if (focal_searched) {
    // Least-squares scale over the three sides of this correspondence.
    double num = 0, den = 0;
    for (int i = 0; i < 3; ++i) num += m.side[i] * m.cside[pm[i]], den += m.cside[pm[i]] * m.cside[pm[i]];
    cam->ScaleFocal(num / den);
  }
  Vec3 bv[3];
  for (int i = 0; i < 3; ++i) {
    tri_c[i] = ctx.order[m.vtx[i]];
    tri_s[i] = t.v[pm[i]];
    const auto& cc = centroids[tri_c[i]];
    bv[i] = cam->Unproject(Vec2(cc.x_px, cc.y_px));
  }
  const double db = bv[0].dot(bv[1].cross(bv[2]));
  const double dr = m.r[pm[0]]->dot(m.r[pm[1]]->cross(*m.r[pm[2]]));
  if (db * dr <= 0) return false;
  std::vector<VectorPair> pairs;
  for (int i = 0; i < 3; ++i) pairs.push_back({bv[i], *m.r[pm[i]], 1.0});
  *rot = SolveWahbaSvd(pairs).toRotationMatrix();
  return true;
}

// The chance terms of a hypothesis that passed the threshold (step 4): u the per-centroid hit
// probability at the test's worst distance, hyp its index h, seq_factor H, k the matches in the test.
struct ChanceTerms {
  double u = 0, prob = 1, phot = 1, seq_factor = 1;
  int hyp = 0, k = 0;
};

// Step 5: an accepted hypothesis refined on its matches (and focal length); then the match least
// consistent with the others left out while it is an outlier, refit and re-matched without it: one
// wrong match (or a star far from its catalog position) can turn a refit, and with a free scale the
// roll of a small clump of stars, by far more than the reported sigma. A rejected extra match is no
// evidence: the chance is recomputed without it. False: the hypothesis is not kept after all.
bool FinishHypothesis(const Context& ctx, const IdentifyOptions& o, const Camera& cam, const Mat3& rot,
                      HypothesisTest ht, const ChanceTerms& ct, bool focal_searched, size_t n_centroids,
                      Identification* out) {
  std::vector<int> test_extras;  // centroids of the test's extra matches (its evidence)
  for (size_t i = 3; i < ht.v.matches.size(); ++i) test_extras.push_back(ht.v.matches[i].centroid);
  const std::vector<StarMatch> ht_matches = ht.v.matches;
  Refined rf = Refine(ctx, o, cam, rot, std::move(ht.v));
  std::vector<char> excluded(n_centroids, 0);
  int rejected = 0, lost_evidence = 0;
  for (int worst; (worst = WorstOutlier(ctx, o, rf.v.matches, rf.cam, rf.r, focal_searched)) >= 0;) {
    if (++rejected > kMaxOutliers || rf.v.matches.size() <= 3) break;
    const int ci = rf.v.matches[worst].centroid;
    excluded[ci] = 1;
    lost_evidence += static_cast<int>(std::count(test_extras.begin(), test_extras.end(), ci));
    rf.v.matches.erase(rf.v.matches.begin() + worst);
    rf = Refine(ctx, o, rf.cam, rf.r, std::move(rf.v), &excluded);
  }
  if (rejected > kMaxOutliers || static_cast<int>(rf.v.matches.size()) < o.min_matches) return false;
  double prob_final = ct.prob, phot_final = ct.phot;
  if (lost_evidence > 0) {
    // The test again without the rejected evidence (u kept: an upper bound).
    const int j = ht.extra - lost_evidence;
    if (j + 3 < o.min_matches) return false;
    std::vector<StarMatch> kept(ht_matches.begin(), ht_matches.begin() + 3);
    for (size_t i = 3; i < ht_matches.size(); ++i)
      if (!excluded[ht_matches[i].centroid]) kept.push_back(ht_matches[i]);
    phot_final = PhotometricFactor(ctx, kept);
    prob_final = std::min(1.0, BinomialTail(ctx.m - 3, ct.u, j) * CountFactor(j) * phot_final * ct.hyp * ct.seq_factor);
    if (prob_final >= o.max_false_match_prob) return false;
  }
  out->status = SolveStatus::kSolved;
  out->q_inertial_from_sensor = Quat(rf.r).normalized();
  if (out->q_inertial_from_sensor.w() < 0) out->q_inertial_from_sensor.coeffs() *= -1;
  out->focal_length_px = rf.cam.focal_length_px;
  out->focal_length_y_px = rf.cam.FocalYPx();
  out->false_match_probability = prob_final;
  out->photometric_factor = phot_final;
  out->focal_length_fitted = focal_searched;
  if (focal_searched) {
    // The scale's 1-sigma from the pixel fit's normal equations (rotation and scale jointly).
    const Eigen::Matrix4d h = Linearize(ctx, rf.v.matches, rf.cam, rf.r).h;
    const double var = h.ldlt().solve(Vec4::UnitW())[3];
    out->focal_length_sigma_px = var > 0 ? std::sqrt(var) * rf.cam.focal_length_px : std::nan("");
  }
  out->outliers_rejected = rejected;
  out->matches = std::move(rf.v.matches);
  out->hypotheses = ct.hyp;
  out->catalog_stars_in_field = rf.v.n_cat;
  out->message = std::to_string(out->matches.size()) + " stars matched (" + std::to_string(ct.k) + " in the test";
  if (rejected > 0) out->message += ", " + std::to_string(rejected) + " left out as inconsistent";
  out->message += ")";
  return true;
}

}  // namespace

Identification StarIdentifier::Identify(const std::vector<Centroid>& centroids, const Camera& camera_in,
                                        const IdentifyOptions& o) const {
  const auto t0 = Clock::now();
  o.Check();
  camera_in.Check();
  CheckCentroids(centroids);
  double scale_lo = 1, scale_hi = 1;
  const Camera camera = SearchedCamera(camera_in, o, catalog_, &scale_lo, &scale_hi);
  const bool focal_searched = o.FocalSearched();
  Identification out;
  // Unknown FOV: no focal length until one is found (null in the JSON).
  out.focal_length_px = o.FovRange() ? std::nan("") : camera.focal_length_px;
  out.focal_length_y_px = o.FovRange() ? std::nan("") : camera.FocalYPx();
  const int n = static_cast<int>(centroids.size());
  if (n < o.min_matches) {
    out.status = SolveStatus::kTooFewStars;
    out.message = std::to_string(n) + " centroids, need at least " + std::to_string(o.min_matches);
    out.timing_ms["identify"] = MsSince(t0);
    return out;
  }
  if (index_->Empty()) throw InputError(catalog_.source, "catalog has no pattern index");
  const Context ctx = MakeContext(this, centroids, o);
  const int k_pat = std::min(o.pattern_centroids, n);
  const std::vector<double> ang = PatternAngles(centroids, ctx, camera, k_pat);
  // Side tolerances hold along both axes; angles are at the nominal focal length (the side checks
  // against the catalog, in true angles, are then looser by the scale at most).
  const double f = camera.FocalMinPx();
  const double fov = catalog_.fov_deg * kDegToRad;
  // ln of the catalog's longest side lies in ln(observed) - [ln hi, ln lo] (observed angles are
  // at the nominal focal length, i.e. scale = f_true / f_nominal times the catalog's).
  const double ln_mid = 0.5 * (std::log(scale_hi) + std::log(scale_lo));
  const double ln_half = 0.5 * (std::log(scale_hi) - std::log(scale_lo));
  // Sequential testing: the search stops at the first hypothesis h (1-based) whose chance
  // probability p_h passes p_h * h * H <= alpha, H = 1 + ln(max_hypotheses) >= sum_{h<=max} 1/h, so
  // that the chance of accepting any chance pattern over the whole search is at most
  // sum_h alpha / (h H) <= alpha (a union bound with weights 1/(h H)). Every hypothesis counts in h
  // and the search never tests one past max_hypotheses, whatever else stops it (max_patterns, the
  // timeout, the end of the triangles): those only end the sum earlier.
  const double seq_factor = 1.0 + std::log(static_cast<double>(o.max_hypotheses));
  const double deadline_cpu_ms = o.timeout_ms > 0 ? ThreadCpuMs() + o.timeout_ms : 0.0;

  std::vector<std::vector<int>> idx(1);
  int hyp = 0, patterns = 0;
  double best_prob = 1.0;
  int best_k = 0;
  auto give_up = [&](SearchStop stop, const std::string& why) {
    out.status = SolveStatus::kNoMatch;
    out.stop = stop;
    out.message =
        why + " (best " + std::to_string(best_k) + " matches, chance probability " + std::to_string(best_prob) + ")";
    out.hypotheses = hyp;
    out.patterns = patterns;
    out.false_match_probability = best_prob;
    out.timing_ms["identify"] = MsSince(t0);
    return out;
  };
  static const int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  // Triangles brightest first: all triangles whose faintest vertex is c come before c + 1.
  for (int c = 2; c < k_pat; ++c) {
    for (int b = 1; b < c; ++b) {
      if (o.timeout_ms > 0 && ThreadCpuMs() > deadline_cpu_ms)
        return give_up(SearchStop::kTimeout, "timed out after " + std::to_string(hyp) + " hypotheses");
      for (int a = 0; a < b; ++a) {
        const int vtx[3] = {a, b, c};
        // Side-length tolerance (rad) from this triangle's own centroid noise (a poorly measured
        // centroid elsewhere in the frame does not widen every search).
        const double sig_tri =
            std::max({ctx.sigma_px[ctx.order[a]], ctx.sigma_px[ctx.order[b]], ctx.sigma_px[ctx.order[c]]});
        const double side_sigma = std::sqrt(2.0) * sig_tri / f;
        const double tol_side = o.tolerance_sigmas * side_sigma;
        const double side[3] = {ang[b * k_pat + c], ang[a * k_pat + c], ang[a * k_pat + b]};
        double s[3] = {side[0], side[1], side[2]};
        std::sort(s, s + 3);
        if (s[2] > fov * scale_hi + tol_side || s[0] < 1e-9) continue;
        // Ratio tolerance: d(a/c) = sqrt(da^2 + (a/c)^2 dc^2) / c <= sqrt(2) tol / c; ln of the
        // longest side: the focal-length range plus tol / c (relative, at the smallest scale).
        const double tol_r = tol_side * std::sqrt(2.0) / s[2] + 1e-4;
        const double tol_l = ln_half + 1.1 * tol_side / (s[2] * scale_lo) + 1e-4;
        std::vector<int>& cand = idx[0];
        cand.clear();
        if (patterns == o.max_patterns)
          return give_up(SearchStop::kPatternBudget, "gave up after " + std::to_string(patterns) + " patterns");
        ++patterns;
        index_->ForEachInBox(s[0] / s[2], s[1] / s[2], std::log(s[2]) - ln_mid, tol_r, tol_l, catalog_,
                             [&](int ti) { cand.push_back(ti); });
        for (int ti : idx[0]) {
          const CatalogTriangle& t = catalog_.triangles[ti];
          const Vec3* r[3] = {&catalog_.stars[t.v[0]].unit, &catalog_.stars[t.v[1]].unit, &catalog_.stars[t.v[2]].unit};
          // Catalog sides from the stored features (vertex i is opposite side i, shortest first).
          const double cside[3] = {t.ratio_a * static_cast<double>(t.longest_rad),
                                   t.ratio_b * static_cast<double>(t.longest_rad), static_cast<double>(t.longest_rad)};
          const double scale0 = s[2] / t.longest_rad;  // observed / catalog angle ~ f_true / f_nominal
          if (scale0 < scale_lo - tol_side / s[2] || scale0 > scale_hi + tol_side / s[2]) continue;
          for (const auto& pm : kPerm) {
            TriangleMatch tm{vtx, pm, side, cside, r, side_sigma, s[2], scale0};
            Camera cam = camera;
            Mat3 rot;
            int tri_c[3], tri_s[3];
            if (!TriangleHypothesis(ctx, o, centroids, t, tm, focal_searched, &cam, &rot, tri_c, tri_s)) continue;
            if (hyp == o.max_hypotheses)
              return give_up(SearchStop::kHypothesisBudget, "gave up after " + std::to_string(hyp) + " hypotheses");
            ++hyp;
            // Unknown FOV: hundreds of catalog triangles fit each query; skip the full test (which
            // predicts every catalog star in the field) unless one of the brightest other centroids
            // has a catalog star within its test radius. A skipped hypothesis still counts in h.
            if (o.FovRange() && !AnyBrightCentroidNearAStar(ctx, o, cam, rot, tri_c)) continue;
            HypothesisTest ht = TestHypothesis(ctx, o, cam, rot, tri_c, tri_s, focal_searched);
            const int k = ht.extra + 3;
            if (k < o.min_matches) continue;
            // Three matches are the hypothesis itself; the others are the evidence: j = extra
            // centroids all within t sigmas of distinct predictions, t the largest of their
            // normalised distances. A random centroid comes that close to some prediction with
            // probability u = p_hit (t / verify_sigmas)^2, so the chance of j or more such among the
            // m - 3 others is the binomial tail at u (the j-th order statistic of uniform p-values).
            // The count j is itself random: for a fixed j, BinomialTail(n, p_hit t_j^2, j) is an exact
            // p-value of the j-th closest distance t_j, but taking j = the observed count picks one of
            // several such tests (measured: ~3x too many chance solves on random centroids). A
            // weighted union bound over j with weights 1 / (j (j + 1)) (summing to 1) makes it valid:
            // the factor j (j + 1) is 2 for four stars, 6 for five.
            const double u = ht.p_hit * ht.worst;
            const double j_factor = CountFactor(ht.extra);
            // Photometry (PhotometricFactor): an independent test of the same null, <= 2.
            const double phot = PhotometricFactor(ctx, ht.v.matches);
            const double prob =
                std::min(1.0, BinomialTail(ctx.m - 3, u, ht.extra) * j_factor * phot * hyp * seq_factor);
            if (prob < best_prob) best_prob = prob, best_k = k;
            if (prob >= o.max_false_match_prob) continue;
            // Accepted: refined, outliers left out (FinishHypothesis).
            if (!FinishHypothesis(ctx, o, cam, rot, std::move(ht), {u, prob, phot, seq_factor, hyp, k}, focal_searched,
                                  centroids.size(), &out))
              continue;
            out.patterns = patterns;
            out.stop = SearchStop::kAccepted;
            out.timing_ms["identify"] = MsSince(t0);
            return out;
          }
        }
      }
    }
  }
  return give_up(SearchStop::kExhausted, "no hypothesis verified (" + std::to_string(hyp) + " tried)");
}

Identification StarIdentifier::MatchWithAttitude(const std::vector<Centroid>& centroids, const Camera& camera,
                                                 const Quat& q_predicted, double search_radius_px,
                                                 const IdentifyOptions& o) const {
  const auto t0 = Clock::now();
  o.Check();
  const int min_k = std::max(o.min_matches, kMinTrackedMatches);
  CheckCentroids(centroids);
  Identification out;
  out.focal_length_px = camera.focal_length_px;
  out.focal_length_y_px = camera.FocalYPx();
  const int n = static_cast<int>(centroids.size());
  if (n < min_k) {
    out.status = SolveStatus::kTooFewStars;
    out.message = std::to_string(n) + " centroids, need at least " + std::to_string(min_k);
    return out;
  }
  const Context ctx = MakeContext(this, centroids, o);
  const Mat3 r_pred = q_predicted.normalized().toRotationMatrix();
  Verification v = Verify(ctx, camera, r_pred, std::max(search_radius_px, ctx.match_radius_px));
  const size_t initial_pairs = v.matches.size();
  if (static_cast<int>(v.matches.size()) < min_k) {
    out.status = SolveStatus::kNoMatch;
    out.message = "lost lock: " + std::to_string(v.matches.size()) + " stars near their predicted positions";
    out.timing_ms["identify"] = MsSince(t0);
    return out;
  }
  IdentifyOptions fixed = o;
  fixed.fov_tolerance_pct = 0;  // tracking keeps the focal length found when the lock was acquired
  Refined rf = Refine(ctx, fixed, camera, r_pred, std::move(v));
  const int k = static_cast<int>(rf.v.matches.size());
  // The refit attitude has three free parameters that can line up a few wrong pairs (a 5-degree
  // jump found 5 such matches in a test): count them out as in lost in space, take a Bonferroni
  // factor for the candidate pairs of the wide first search, and require that a fair share of the
  // stars that should be visible are matched.
  const double n_pairs = std::max(1.0, static_cast<double>(initial_pairs));
  const double prob =
      std::min(1.0, ChanceProbability(ctx.m - 3, rf.v.n_cat, ctx.match_radius_px, camera, k - 3) * n_pairs);
  const double expected = std::min(rf.v.n_cat, ctx.m);
  out.false_match_probability = prob;
  if (k < kMinTrackedFraction * expected) {
    out.status = SolveStatus::kNoMatch;
    out.message = "lost lock: " + std::to_string(k) + " of " + std::to_string(static_cast<int>(expected)) +
                  " predicted stars matched";
    return out;
  }
  out.hypotheses = 1;
  out.catalog_stars_in_field = rf.v.n_cat;
  out.timing_ms["identify"] = MsSince(t0);
  if (k >= min_k && prob < o.max_false_match_prob) {
    out.status = SolveStatus::kSolved;
    out.q_inertial_from_sensor = Quat(rf.r).normalized();
    if (out.q_inertial_from_sensor.w() < 0) out.q_inertial_from_sensor.coeffs() *= -1;
    out.matches = std::move(rf.v.matches);
    out.message = std::to_string(k) + " stars matched";
  } else {
    out.status = SolveStatus::kNoMatch;
    out.message = "lost lock: " + std::to_string(k) + " matches, chance probability " + std::to_string(prob);
  }
  return out;
}

}  // namespace ssiu
