#include "identify/identify.h"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>
#include <string>

#include "core/error.h"
#include "identify/catalog_index.h"
#include "identify/identify_internal.h"
#include "identify/wahba_svd.h"

namespace ssiu {

using namespace identify_internal;  // NOLINT: the stage's own helpers

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



// A catalog star predicted in the image (pixel; squared test radius where the test uses one).
struct Pred {
  Vec2 px;
  int star;
  double r2;
};
// A centroid-prediction pair within reach; key: squared distance, or over the squared radius.
struct Cand {
  double key;
  int c, p;
};


}  // namespace

const char* SearchStopName(SearchStop s) {
  switch (s) {
    case SearchStop::kNone:
      return "none";
    case SearchStop::kAccepted:
      return "accepted";
    case SearchStop::kExhausted:
      return "exhausted";
    case SearchStop::kHypothesisBudget:
      return "hypothesis_budget";
    case SearchStop::kPatternBudget:
      return "pattern_budget";
    case SearchStop::kTimeout:
      return "timeout";
  }
  return "none";
}

// Every buffer of a call, sized on construction (K centroids, S stars in a field, P pattern centroids):
// a call only clears and refills them. `grow` (the by-value forms): no sizes, the buffers grow as needed.
struct IdentifyWorkspace::Scratch {
  bool grow = false;
  size_t max_centroids = 0, max_stars = 0, max_pattern = 0, max_verify = 0;
  ScratchVec<Centroid> centroids;  // the usable centroids, in input order
  ScratchVec<int> input_index;     // their indices in the input
  ScratchVec<int> order;           // brightest first
  ScratchVec<double> sigma_px, median;
  ScratchVec<Vec3> unit;   // pattern centroids' directions
  ScratchVec<double> ang;  // and their angles (P x P)
  ScratchVec<int> near;    // catalog stars about the field
  ScratchVec<Pred> pred;
  ScratchVec<Cand> cands;  // K x S
  ScratchVec<char> used_c, used_p, excluded;
  ScratchVec<StarMatch> test, cur, next, kept;  // matches: a test's, the refined ones, scratch
  ScratchVec<int> test_extras;
  ScratchVec<VectorPair> pairs;
  PixelFit fit;
  ScratchVec<Vec2> resid;
  ScratchVec<double> flux, mag, other, zp, z;  // photometry
  ScratchVec<char> used;

  Scratch(size_t k, size_t s, size_t p, size_t v, bool grow_as_needed, std::pmr::memory_resource* mr)
      : grow(grow_as_needed),
        max_centroids(k),
        max_stars(s),
        max_pattern(p),
        max_verify(std::min(k, v)),
        centroids(mr),
        input_index(mr),
        order(mr),
        sigma_px(mr),
        median(mr),
        unit(mr),
        ang(mr),
        near(mr),
        pred(mr),
        cands(mr),
        used_c(mr),
        used_p(mr),
        excluded(mr),
        test(mr),
        cur(mr),
        next(mr),
        kept(mr),
        test_extras(mr),
        pairs(mr),
        fit(mr),
        resid(mr),
        flux(mr),
        mag(mr),
        other(mr),
        zp(mr),
        z(mr),
        used(mr) {
    if (grow) return;
    for (auto* v : {&input_index, &order, &test_extras}) v->reserve(k);
    for (auto* v : {&sigma_px, &median, &flux, &mag, &other, &zp, &z}) v->reserve(k);
    for (auto* v : {&used_c, &excluded, &used, &fit.ok}) v->reserve(k);
    fit.w.reserve(k);
    for (auto* v : {&test, &cur, &next, &kept}) v->reserve(k);
    centroids.reserve(k);
    pairs.reserve(k);
    fit.j.reserve(k);
    fit.e.reserve(k);
    resid.reserve(k);
    unit.reserve(p);
    ang.reserve(p * p);
    near.reserve(s);
    pred.reserve(s);
    used_p.reserve(s);
    cands.reserve(max_verify * s);  // only the verification centroids are paired with stars
  }

  template <class V>
  static size_t Held(const V& v) {
    return v.capacity() * sizeof(typename V::value_type);
  }
  size_t Bytes() const {
    size_t b = sizeof(*this) + Held(centroids) + Held(unit) + Held(ang) + Held(pred) + Held(cands) + Held(pairs) +
               Held(fit.j) + Held(fit.e) + Held(resid);
    for (const auto* v : {&input_index, &order, &near, &test_extras}) b += Held(*v);
    for (const auto* v : {&sigma_px, &median, &flux, &mag, &other, &zp, &z}) b += Held(*v);
    b += Held(fit.w) + Held(fit.ok);
    for (const auto* v : {&used_c, &used_p, &excluded, &used}) b += Held(*v);
    for (const auto* v : {&test, &cur, &next, &kept}) b += Held(*v);
    return b;
  }
};

namespace {

using Scratch = IdentifyWorkspace::Scratch;

struct Context {
  const SolverCatalog* cat;
  const CatalogIndex* index;
  const Centroid* c;  // the usable centroids (the workspace's copy)
  int n = 0;          // how many
  Scratch* s;
  Identification* report;  // for stars_clamped
  const int* order;        // centroid indices, brightest first
  const double* sigma_px;  // effective 1-sigma per centroid (with the systematic part)
  int m = 0;               // verification centroids
  double median_sigma_px = 0;  // typical centroid sigma (with the systematic part)
  double match_radius_px = 0;
  bool photometry = false;  // fluxes usable as photometric evidence (all > 0, not all equal)
  // ln of the faintest verification centroid's flux less the margin (detect_limit_margin_mag): a
  // catalog star predicted fainter than this is not expected among the centroids (TestHypothesis).
  // -inf: every predicted star is expected (no photometry, or the margin 0).
  double ln_flux_limit = -std::numeric_limits<double>::infinity();
};

// Catalog stars within radius_rad of u into ctx.s->near, brightest first; more than the workspace
// holds: the brightest, flagged in the report.
void StarsNear(const Context& ctx, const Vec3& u, double radius_rad) {
  auto& near = ctx.s->near;
  const size_t cap = ctx.s->grow ? std::max<size_t>(near.capacity(), 64) : ctx.s->max_stars;
  near.resize(cap);
  size_t n = ctx.index->StarsWithin(u, radius_rad, near.data(), cap);
  if (n > cap && ctx.s->grow) {
    near.resize(n);
    n = ctx.index->StarsWithin(u, radius_rad, near.data(), n);
  } else if (n > cap) {
    n = cap;
    ctx.report->stars_clamped = true;
  }
  near.resize(n);
}

StarMatch MakeMatch(const Context& ctx, const Camera& cam, int ci, int star) {
  const CatalogStar& cs = ctx.cat->stars[star];
  StarMatch m;
  m.centroid = ci;
  m.star = star;
  m.star_id = cs.id;
  m.mag = cs.mag;
  m.x_px = ctx.c[ci].x_px;
  m.y_px = ctx.c[ci].y_px;
  m.b_sensor = cam.Unproject(Vec2(m.x_px, m.y_px));
  m.r_inertial = cs.unit;
  m.sigma_rad = ctx.sigma_px[ci] / cam.FocalMeanPx();
  return m;
}

// Predicts all catalog stars in the field with R (sensor -> inertial) and the camera, and matches
// the first ctx.m centroids to them one-to-one, nearest pairs first, within radius_px, into *out.
// Centroids flagged in `excluded` (rejected as outliers of this hypothesis) are left out. Returns
// the number of catalog stars predicted in the image.
int Verify(const Context& ctx, const Camera& cam, const Mat3& r, double radius_px, const ScratchVec<char>* excluded,
           ScratchVec<StarMatch>* out) {
  Scratch& s = *ctx.s;
  StarsNear(ctx, r.col(2), cam.FovDiagRad() / 2 * 1.05 + 0.002);
  auto& proj = s.pred;
  proj.clear();
  const Mat3 rt = r.transpose();
  for (int st : s.near) {
    const auto p = cam.Project(rt * ctx.cat->stars[st].unit);
    if (p && cam.InImage(*p)) proj.push_back({*p, st, 0.0});
  }
  auto& cands = s.cands;
  cands.clear();
  const double r2 = radius_px * radius_px;
  for (int i = 0; i < ctx.m; ++i) {
    const int ci = ctx.order[i];
    if (excluded && (*excluded)[ci]) continue;
    const Vec2 xy(ctx.c[ci].x_px, ctx.c[ci].y_px);
    for (size_t p = 0; p < proj.size(); ++p) {
      const double d2 = (proj[p].px - xy).squaredNorm();
      if (d2 <= r2) cands.push_back({d2, ci, static_cast<int>(p)});
    }
  }
  std::sort(cands.begin(), cands.end(), [](const Cand& a, const Cand& b) { return a.key < b.key; });
  s.used_c.assign(ctx.n, 0);
  s.used_p.assign(proj.size(), 0);
  out->clear();
  for (const auto& k : cands) {
    if (s.used_c[k.c] || s.used_p[k.p]) continue;
    s.used_c[k.c] = s.used_p[k.p] = 1;
    out->push_back(MakeMatch(ctx, cam, k.c, proj[k.p].star));
  }
  return static_cast<int>(proj.size());
}

// Radius (px, squared) of the hypothesis test at pixel p for a triangle of centroids tri_c (as in
// TestHypothesis: centroid noise plus the triangle's own rotation and scale error there).
struct TriangleSpread {
  Vec2 centre = Vec2::Zero();
  double sig_tri = 0, rho2 = 1;
};
TriangleSpread SpreadOf(const Context& ctx, const int tri_c[3]) {
  TriangleSpread t;
  const Centroid* c = ctx.c;
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
// The matches (the triangle's three pairs plus the extra matches) are in ctx.s->test.
struct HypothesisTest {
  int extra = 0;     // matched centroids besides the triangle's three
  double p_hit = 0;  // chance that one random centroid falls within a predicted star's radius
  double worst = 0;  // largest (distance / radius)^2 among the extra matches
  int n_cat = 0;     // catalog stars predicted in the image
};

HypothesisTest TestHypothesis(const Context& ctx, const IdentifyOptions& o, const Camera& cam, const Mat3& r,
                              const int tri_c[3], const int tri_s[3], bool scale_searched) {
  HypothesisTest h;
  Scratch& sc = *ctx.s;
  const Centroid* c = ctx.c;
  const TriangleSpread spread = SpreadOf(ctx, tri_c);
  StarsNear(ctx, r.col(2), cam.FovDiagRad() / 2 * 1.05 + 0.002);
  auto& pred = sc.pred;
  pred.clear();
  const Mat3 rt = r.transpose();
  // The triangle's photometric zero point (median of ln f + 0.4 ln(10) V over its vertices): a star
  // it predicts fainter than the faintest verification centroid (less a margin) cannot be among them,
  // so it is no place where a chance centroid could count as a match (a smaller p_hit). The rule
  // depends on fluxes and the hypothesis, not on the other centroids' positions, so under the null
  // hypothesis they remain uniform and the chance probability stays exact.
  const double k_mag = 0.4 * std::log(10.0);
  double zp = 0;
  const bool limited = std::isfinite(ctx.ln_flux_limit);
  if (limited) {
    double z[3];
    for (int i = 0; i < 3; ++i) z[i] = std::log(c[tri_c[i]].flux) + k_mag * ctx.cat->stars[tri_s[i]].mag;
    zp = std::max(std::min(z[0], z[1]), std::min(std::max(z[0], z[1]), z[2]));
  }
  double area_hit = 0;
  int n_in_image = 0;
  for (int s : sc.near) {
    if (s == tri_s[0] || s == tri_s[1] || s == tri_s[2]) continue;
    const auto p = cam.Project(rt * ctx.cat->stars[s].unit);
    if (!p || !cam.InImage(*p)) continue;
    ++n_in_image;
    if (limited && zp - k_mag * ctx.cat->stars[s].mag < ctx.ln_flux_limit) continue;
    // In tolerance mode the camera model is known to be off (focal length, and often the pixel
    // aspect or distortion that the caller is about to calibrate): at least twice the refinement
    // radius, as the verification before this test used (the probability counts whatever radius).
    const double r2 = TestRadius2(ctx, o, spread, *p, scale_searched);
    area_hit += kPi * r2;
    pred.push_back({*p, s, r2});
  }
  h.n_cat = n_in_image + 3;
  h.p_hit = std::min(1.0, area_hit / (static_cast<double>(cam.width) * cam.height));
  auto& cands = sc.cands;  // key: squared distance over squared radius
  cands.clear();
  for (int i = 0; i < ctx.m; ++i) {
    const int ci = ctx.order[i];
    if (ci == tri_c[0] || ci == tri_c[1] || ci == tri_c[2]) continue;
    const Vec2 xy(c[ci].x_px, c[ci].y_px);
    for (size_t p = 0; p < pred.size(); ++p) {
      const double d2 = (pred[p].px - xy).squaredNorm();
      if (d2 <= pred[p].r2) cands.push_back({d2 / pred[p].r2, ci, static_cast<int>(p)});
    }
  }
  std::sort(cands.begin(), cands.end(), [](const Cand& a, const Cand& b) { return a.key < b.key; });
  sc.used_c.assign(ctx.n, 0);
  sc.used_p.assign(pred.size(), 0);
  sc.test.clear();
  for (int i = 0; i < 3; ++i) sc.test.push_back(MakeMatch(ctx, cam, tri_c[i], tri_s[i]));
  for (const auto& k : cands) {
    if (sc.used_c[k.c] || sc.used_p[k.p]) continue;
    sc.used_c[k.c] = sc.used_p[k.p] = 1;
    sc.test.push_back(MakeMatch(ctx, cam, k.c, pred[k.p].star));
    ++h.extra;
    h.worst = std::max(h.worst, k.key);
  }
  return h;
}

// Whether any of the kQuickCentroids brightest centroids outside the triangle lies within its test
// radius of a catalog star under the hypothesis (cam, r): a cheap necessary condition for the test
// to find an extra match among them.
bool AnyBrightCentroidNearAStar(const Context& ctx, const IdentifyOptions& o, const Camera& cam, const Mat3& r,
                                const int tri_c[3]) {
  constexpr int kQuickCentroids = 12;
  const TriangleSpread t = SpreadOf(ctx, tri_c);
  const Centroid* c = ctx.c;
  const double f = cam.FocalMinPx();
  for (int i = 0, seen = 0; i < ctx.m && seen < kQuickCentroids; ++i) {
    const int ci = ctx.order[i];
    if (ci == tri_c[0] || ci == tri_c[1] || ci == tri_c[2]) continue;
    ++seen;
    const Vec2 p(c[ci].x_px, c[ci].y_px);
    const double radius_rad = std::sqrt(TestRadius2(ctx, o, t, p, true)) / f;
    if (ctx.index->AnyStarWithin(r * cam.Unproject(p), radius_rad)) return true;
  }
  return false;
}

Mat3 SvdFromMatches(const Context& ctx, const ScratchVec<StarMatch>& ms) {
  auto& pairs = ctx.s->pairs;
  pairs.clear();
  for (const auto& m : ms) pairs.push_back({m.b_sensor, m.r_inertial, 1.0 / (m.sigma_rad * m.sigma_rad)});
  return SolveWahbaSvd(pairs.data(), pairs.size()).toRotationMatrix();
}

// The pixel fit of the matches with the workspace's sigmas, in ctx.s->fit.
const PixelFit& Linearize(const Context& ctx, const ScratchVec<StarMatch>& ms, const Camera& cam, const Mat3& r) {
  return LinearizeInto(ms, cam, r, {ctx.sigma_px, 0}, &ctx.s->fit);
}

// The rotation and the scale, with the workspace's sigmas.
void RefineFocal(const Context& ctx, const ScratchVec<StarMatch>& ms, Camera* cam, Mat3* r) {
  if (ms.size() >= 4) PixelGaussNewton(ms, {ctx.sigma_px, 0}, &ctx.s->fit, true, cam, r);
}

// Photometric evidence (docs/identify.md, step 5). Under the null hypothesis (a chance match) the
// fluxes are independent of the positions, so given the positions (which alone chose the hypothesis
// and its matches) the fluxes of the verification centroids are exchangeable. Two conditionally
// exact tests, each turned into an e-value (a statistic with mean 1 under the null):
// - the triangle: given its faintest vertex, the c-th brightest centroid, its three fluxes are one of
//   the T = 3 (c-1)(c-2) equally likely ordered triples of that flux and two of the c - 1 brighter
//   ones (the search goes brightest first; the geometry picks the rest); p = the fraction of them
//   whose zero points (ln f + 0.4 ln(10) V against the triangle's three magnitudes) agree at least as
//   closely as the triangle's own (their scatter), and e = 1 / (p H_T) (TriangleZeroPointP). Where the
//   fluxes follow the magnitudes to a few hundredths of a magnitude, as on ESA's scenes, p is about
//   (spread / range of ln f)^2 and e reaches 10^2-10^4 (a rank test of the three, before, at most 2.7);
// - each extra match in the test's (geometric) order: given the pairs before it, its flux is a
//   uniform draw from the N centroids not yet used. Its flux predicted from their zero point (median
//   of ln f + 0.4 ln(10) V) ranks K-th closest among those N (ties counted in), p = K / N and
//   e = (1 / (p H_N) + N / (K^2 S_N)) / 2, H_N the N-th harmonic number (= E[1/p]), S_N = sum 1/k^2.
// The product E of these has mean 1 (each factor's mean is 1 given the ones before), and so has the
// mixture (1 + E) / 2, which bounds the cost of photometry that disagrees (a colour term, a saturated
// star) to a factor 2. Returned: 2 / (1 + E), the factor on the geometric p-value. With p_g valid and
// E's null distribution not depending on the positions, P(p_g * 2 / (1 + E) <= x) <= x E[(1 + E) / 2] = x.
// `ms`: the triangle's three pairs first, then the extra matches in the order they were tested.
double PhotometricFactor(const Context& ctx, const ScratchVec<StarMatch>& ms) {
  if (!ctx.photometry || ms.size() < 3) return 1.0;
  Scratch& s = *ctx.s;
  const Centroid* c = ctx.c;
  s.flux.clear();
  s.mag.clear();
  s.other.clear();
  s.used.assign(ctx.n, 0);
  for (const auto& m : ms) s.flux.push_back(c[m.centroid].flux), s.mag.push_back(m.mag), s.used[m.centroid] = 1;
  for (int q = 0; q < ctx.m; ++q)
    if (!s.used[ctx.order[q]]) s.other.push_back(c[ctx.order[q]].flux);
  return 2.0 / (1.0 + PhotometricEvidenceOf(s.flux.data(), s.mag.data(), s.flux.size(), s.other.data(),
                                            s.other.size(), &s.zp, &s.z));
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
int WorstOutlier(const Context& ctx, const IdentifyOptions& o, const ScratchVec<StarMatch>& ms, const Camera& cam,
                 const Mat3& r, bool fit_scale) {
  const int np = fit_scale ? 4 : 3;
  const int dof_without = 2 * (static_cast<int>(ms.size()) - 1) - np;
  if (dof_without < 2) return -1;
  const PixelFit& f = Linearize(ctx, ms, cam, r);
  // Dynamic sizes (3 or 4 parameters) held in fixed storage: no heap.
  using MatP = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 4, 4>;
  using VecP = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 4, 1>;
  const MatP h = f.h.topLeftCorner(np, np);
  const Eigen::LDLT<MatP> ldlt(h);
  const VecP dx = ldlt.solve(f.g.head(np));  // to the linearised optimum (r may be an SVD fit)
  if (!dx.allFinite()) return -1;
  auto& e = ctx.s->resid;
  e.assign(ms.size(), Vec2::Zero());
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
    const Eigen::Matrix<double, 2, Eigen::Dynamic, 0, 2, 4> j = f.j[i].leftCols(np);
    const MatP h_i = h - f.w[i] * j.transpose() * j;
    const Eigen::LDLT<MatP> ldlt_i(h_i);
    // The others must fix every direction (else match i cannot be tested).
    if (ldlt_i.info() != Eigen::Success || !(ldlt_i.vectorD().minCoeff() > 1e-9 * ldlt_i.vectorD().maxCoeff()))
      continue;
    const Eigen::Matrix<double, Eigen::Dynamic, 2, 0, 4, 2> hj = ldlt_i.solve(j.transpose());
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
  Mat3 r;
  Camera cam;
  int n_cat = 0;
};

// Fit the attitude (and the focal length when it is uncertain) to the matches in ctx.s->cur (n_cat
// catalog stars predicted) and re-match, twice; the matches are refined in place.
Refined Refine(const Context& ctx, Camera cam, Mat3 r, int n_cat, const ScratchVec<char>* excluded, bool fit_scale) {
  Scratch& s = *ctx.s;
  for (int pass = 0; pass < 3; ++pass) {
    if (fit_scale) {
      RefineFocal(ctx, s.cur, &cam, &r);
      for (auto& m : s.cur) m.b_sensor = cam.Unproject(Vec2(m.x_px, m.y_px));
    } else {
      r = SvdFromMatches(ctx, s.cur);
    }
    const int n_cat2 = Verify(ctx, cam, r, ctx.match_radius_px, excluded, &s.next);
    if (s.next.size() < 3) break;
    std::swap(s.cur, s.next);
    n_cat = n_cat2;
  }
  if (!fit_scale) r = SvdFromMatches(ctx, s.cur);
  for (auto& m : s.cur) {
    m.sigma_rad = ctx.sigma_px[m.centroid] / cam.FocalMeanPx();
    m.residual_rad = Angle(r * m.b_sensor, m.r_inertial);
  }
  return {r, cam, n_cat};
}

bool Usable(const Centroid& c) {
  return std::isfinite(c.x_px) && std::isfinite(c.y_px) && std::isfinite(c.flux) && c.sigma_px >= 0;
}

// The usable centroids (finite position and flux, sigma >= 0) into the workspace in input order, at
// most max_centroids: then the brightest (ties: the first). Counts and flags go to *out.
void TakeCentroids(const Centroid* c, size_t n, Scratch* s, Identification* out) {
  auto& kept = s->input_index;
  kept.clear();
  // Brighter first, then earlier: the order MakeContext sorts by.
  auto before = [c](int a, int b) { return c[a].flux > c[b].flux || (c[a].flux == c[b].flux && a < b); };
  bool heap = false;  // when full, kept is a heap whose top is the faintest kept
  for (size_t i = 0; i < n; ++i) {
    if (!Usable(c[i])) {
      ++out->centroids_skipped;
      continue;
    }
    const int k = static_cast<int>(i);
    if (s->grow || kept.size() < s->max_centroids) {
      kept.push_back(k);
      continue;
    }
    out->centroids_clamped = true;
    if (!heap) std::make_heap(kept.begin(), kept.end(), before), heap = true;
    if (kept.empty() || !before(k, kept.front())) continue;
    std::pop_heap(kept.begin(), kept.end(), before);
    kept.back() = k;
    std::push_heap(kept.begin(), kept.end(), before);
  }
  if (heap) std::sort(kept.begin(), kept.end());
  s->centroids.clear();
  for (int k : kept) s->centroids.push_back(c[k]);
}

// Matches' centroid indices from the workspace's to the input's.
void ToInputIndices(const Scratch& s, Identification* out) {
  for (auto& m : out->matches) m.centroid = s.input_index[m.centroid];
}

Context MakeContext(const StarIdentifier* id, const CatalogIndex* index, Scratch* s, Identification* report,
                    const IdentifyOptions& o) {
  Context ctx;
  ctx.cat = &id->catalog();
  ctx.index = index;
  ctx.s = s;
  ctx.report = report;
  const auto& c = s->centroids;
  ctx.c = c.data();
  ctx.n = static_cast<int>(c.size());
  // Brightest first, ties in input order (a stable sort, without its buffer).
  s->order.resize(c.size());
  std::iota(s->order.begin(), s->order.end(), 0);
  std::sort(s->order.begin(), s->order.end(),
            [&](int a, int b) { return c[a].flux > c[b].flux || (c[a].flux == c[b].flux && a < b); });
  s->sigma_px.resize(c.size());
  for (size_t i = 0; i < c.size(); ++i) {
    const double sg = c[i].sigma_px > 0 ? c[i].sigma_px : o.centroid_sigma_px;
    s->sigma_px[i] = std::sqrt(sg * sg + o.systematic_px * o.systematic_px);
  }
  ctx.order = s->order.data();
  ctx.sigma_px = s->sigma_px.data();
  ctx.m = std::min<int>(o.verify_centroids, ctx.n);
  if (!s->grow && ctx.m > static_cast<int>(s->max_verify)) {  // the workspace's room for candidate pairs
    ctx.m = static_cast<int>(s->max_verify);
    report->centroids_clamped = true;
  }
  // Radius from the typical (median) centroid noise, at least 2 px (Median, in the workspace).
  if (c.empty()) {
    ctx.median_sigma_px = o.centroid_sigma_px;
  } else {
    s->median.assign(s->sigma_px.begin(), s->sigma_px.end());
    std::nth_element(s->median.begin(), s->median.begin() + s->median.size() / 2, s->median.end());
    ctx.median_sigma_px = s->median[s->median.size() / 2];
  }
  // Photometry needs a flux on every centroid; equal fluxes (e.g. all 1) carry no evidence.
  ctx.photometry = o.use_photometry && !c.empty();
  for (const auto& x : c) ctx.photometry = ctx.photometry && x.flux > 0 && std::isfinite(std::log(x.flux));
  if (ctx.photometry)
    ctx.photometry = std::any_of(c.begin(), c.end(), [&](const Centroid& x) { return x.flux != c[0].flux; });
  ctx.match_radius_px = o.match_radius_px > 0 ? o.match_radius_px : std::max(2.0, 5.0 * ctx.median_sigma_px);
  if (ctx.photometry && o.detect_limit_margin_mag > 0 && ctx.m > 0)
    ctx.ln_flux_limit = std::log(c[ctx.order[ctx.m - 1]].flux) - 0.4 * std::log(10.0) * o.detect_limit_margin_mag;
  return ctx;
}

void CheckCentroids(const std::vector<Centroid>& c) {
  for (size_t i = 0; i < c.size(); ++i) {
    if (!Usable(c[i]))
      throw InputError("centroids", "row " + std::to_string(i + 1) + ": non-finite position, flux or sigma");
  }
}

// *out emptied for a new call, keeping the room of its matches and message.
void Reset(Identification* out) {
  ScratchVec<StarMatch> matches = std::move(out->matches);
  std::string message = std::move(out->message);
  std::map<std::string, double> timing = std::move(out->timing_ms);
  matches.clear();
  message.clear();
  timing.clear();
  *out = Identification{};
  out->matches = std::move(matches);
  out->message = std::move(message);
  out->timing_ms = std::move(timing);
}

// Chance that k or more of n random centroids fall within radius_px of one of n_cat predicted stars.
double ChanceProbability(int n_trials, int n_cat, double radius_px, const Camera& cam, int k) {
  const double p = std::min(1.0, n_cat * kPi * radius_px * radius_px / (static_cast<double>(cam.width) * cam.height));
  return BinomialTail(n_trials, p, k);
}

}  // namespace


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
  if (!(refine_focal_p >= 0 && refine_focal_p < 1)) bad("refine_focal_p", "must be in [0, 1)");
  if (!(refine_principal_p >= 0 && refine_principal_p < 1)) bad("refine_principal_p", "must be in [0, 1)");
  if (refine_principal_min_matches < 4) bad("refine_principal_min_matches", "must be >= 4");
  if (!(detect_limit_margin_mag >= 0 && detect_limit_margin_mag <= 20))
    bad("detect_limit_margin_mag", "must be in [0, 20]");
  if (refine_focal_min_matches < 4) bad("refine_focal_min_matches", "must be >= 4");
  if (!(max_false_match_prob > 0 && max_false_match_prob < 1)) bad("max_false_match_prob", "must be in (0, 1)");
  if (min_matches < 4) bad("min_matches", "must be >= 4");
  if (max_hypotheses < 1) bad("max_hypotheses", "must be >= 1");
  if (max_patterns < 1) bad("max_patterns", "must be >= 1");
  if (!(verify_sigmas >= 1 && verify_sigmas <= 10)) bad("verify_sigmas", "must be in [1, 10]");
  if (!(outlier_sigmas >= 3 && outlier_sigmas <= 100)) bad("outlier_sigmas", "must be in [3, 100]");
  if (!(timeout_ms >= 0 && timeout_ms <= 3.6e6)) bad("timeout_ms", "must be in [0, 3600000] (0 = no limit)");
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
// geometric mean (the camera returned then has that mean focal length). False when the catalog does
// not serve that range (*why, when given, says so).
bool SearchedCamera(const Camera& camera_in, const IdentifyOptions& o, const SolverCatalog& catalog, Camera* camera,
                    double* scale_lo, double* scale_hi, std::string* why) {
  *camera = camera_in;
  *scale_lo = 1 - o.fov_tolerance_pct / 100.0, *scale_hi = 1 + o.fov_tolerance_pct / 100.0;
  if (!o.FovRange()) return true;
  const double cat_min = catalog.fov_min_deg > 0 ? catalog.fov_min_deg : catalog.fov_deg;
  if (o.fov_max_deg > catalog.fov_deg * (1 + kCatalogFovTolerance) ||
      o.fov_min_deg < cat_min * (1 - kCatalogFovTolerance)) {
    if (why) {
      char msg[200];
      std::snprintf(msg, sizeof msg, "built for fields of view %.2f-%.2f deg, the search needs %.2f-%.2f deg", cat_min,
                    catalog.fov_deg, o.fov_min_deg, o.fov_max_deg);
      *why = msg;
    }
    return false;
  }
  const double f_hi = 0.5 * camera->width / std::tan(0.5 * o.fov_min_deg * kDegToRad);
  const double f_lo = 0.5 * camera->width / std::tan(0.5 * o.fov_max_deg * kDegToRad);
  const double f0 = std::sqrt(f_lo * f_hi);
  camera->ScaleFocal(f0 / camera->focal_length_px);
  *scale_lo = f_lo / f0;
  *scale_hi = f_hi / f0;
  return true;
}

// Angles between the k_pat brightest centroids (row-major k_pat x k_pat, in ctx.s->ang), once: a deep
// search forms each pair's side in many triangles.
const ScratchVec<double>& PatternAngles(const Context& ctx, const Camera& camera, int k_pat) {
  auto& u = ctx.s->unit;
  u.resize(k_pat);
  for (int i = 0; i < k_pat; ++i) {
    const Centroid& c = ctx.c[ctx.order[i]];
    u[i] = camera.Unproject(Vec2(c.x_px, c.y_px));
  }
  auto& ang = ctx.s->ang;
  ang.assign(static_cast<size_t>(k_pat) * k_pat, 0.0);
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
bool TriangleHypothesis(const Context& ctx, const IdentifyOptions& o, const CatalogTriangle& t, const TriangleMatch& m, bool focal_searched, Camera* cam, Mat3* rot,
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
    const Centroid& cc = ctx.c[tri_c[i]];
    bv[i] = cam->Unproject(Vec2(cc.x_px, cc.y_px));
  }
  const double db = bv[0].dot(bv[1].cross(bv[2]));
  const double dr = m.r[pm[0]]->dot(m.r[pm[1]]->cross(*m.r[pm[2]]));
  if (db * dr <= 0) return false;
  const VectorPair pairs[3] = {{bv[0], *m.r[pm[0]], 1.0}, {bv[1], *m.r[pm[1]], 1.0}, {bv[2], *m.r[pm[2]], 1.0}};
  *rot = SolveWahbaSvd(pairs, 3).toRotationMatrix();
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
                      const HypothesisTest& ht, const ChanceTerms& ct, bool focal_searched, bool diagnostics,
                      Identification* out) {
  Scratch& s = *ctx.s;
  const ScratchVec<StarMatch>& ht_matches = s.test;  // the test's: the triangle's three, then the extras
  s.test_extras.clear();  // centroids of the test's extra matches (its evidence)
  for (size_t i = 3; i < ht_matches.size(); ++i) s.test_extras.push_back(ht_matches[i].centroid);
  s.cur.assign(ht_matches.begin(), ht_matches.end());
  bool fit_scale = focal_searched;
  Refined rf = Refine(ctx, cam, rot, ht.n_cat, nullptr, fit_scale);
  auto& excluded = s.excluded;
  excluded.assign(ctx.n, 0);
  int rejected = 0, lost_evidence = 0;
  auto leave_out_outliers = [&] {
    for (int worst; (worst = WorstOutlier(ctx, o, s.cur, rf.cam, rf.r, fit_scale)) >= 0;) {
      if (++rejected > kMaxOutliers || s.cur.size() <= 3) break;
      const int ci = s.cur[worst].centroid;
      excluded[ci] = 1;
      lost_evidence += static_cast<int>(std::count(s.test_extras.begin(), s.test_extras.end(), ci));
      s.cur.erase(s.cur.begin() + worst);
      rf = Refine(ctx, rf.cam, rf.r, rf.n_cat, &excluded, fit_scale);
    }
  };
  leave_out_outliers();
  // A fixed focal length that the stars themselves reject (the scale test, ScaleFitP) is refitted
  // with the attitude, the stars matched again with it and the outliers looked for again.
  double scale_p = std::nan("");
  if (!focal_searched && o.refine_focal_p > 0 && rejected <= kMaxOutliers &&
      static_cast<int>(s.cur.size()) >= o.refine_focal_min_matches) {
    Camera c1 = rf.cam;
    Mat3 r1 = rf.r;
    scale_p = ScaleFitP(s.cur, {ctx.sigma_px, 0}, &s.fit, &c1, &r1);
    if (scale_p < o.refine_focal_p) {
      fit_scale = true;
      for (auto& m : s.cur) m.b_sensor = c1.Unproject(Vec2(m.x_px, m.y_px));
      rf = Refine(ctx, c1, r1, rf.n_cat, &excluded, true);
      leave_out_outliers();
    }
  }
  if (rejected > kMaxOutliers || static_cast<int>(s.cur.size()) < o.min_matches) return false;
  double prob_final = ct.prob, phot_final = ct.phot;
  if (lost_evidence > 0) {
    // The test again without the rejected evidence (u kept: an upper bound).
    const int j = ht.extra - lost_evidence;
    if (j + 3 < o.min_matches) return false;
    s.kept.assign(ht_matches.begin(), ht_matches.begin() + 3);
    for (size_t i = 3; i < ht_matches.size(); ++i)
      if (!excluded[ht_matches[i].centroid]) s.kept.push_back(ht_matches[i]);
    phot_final = PhotometricFactor(ctx, s.kept);
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
  out->focal_length_fitted = fit_scale;
  out->focal_length_refined = fit_scale && !focal_searched;
  out->focal_length_p_value = scale_p;
  if (fit_scale) {
    // The scale's 1-sigma from the pixel fit's normal equations (rotation and scale jointly).
    const Eigen::Matrix4d h = Linearize(ctx, s.cur, rf.cam, rf.r).h;
    const double var = h.ldlt().solve(Vec4::UnitW())[3];
    out->focal_length_sigma_px = var > 0 ? std::sqrt(var) * rf.cam.focal_length_px : std::nan("");
  }
  out->outliers_rejected = rejected;
  out->matches.assign(s.cur.begin(), s.cur.end());
  ToInputIndices(s, out);
  out->hypotheses = ct.hyp;
  out->catalog_stars_in_field = rf.n_cat;
  if (diagnostics) {
    out->message = std::to_string(out->matches.size()) + " stars matched (" + std::to_string(ct.k) + " in the test";
    if (rejected > 0) out->message += ", " + std::to_string(rejected) + " left out as inconsistent";
    out->message += ")";
  }
  return true;
}

}  // namespace

IdentifyWorkspace::IdentifyWorkspace(int max_centroids, int max_stars_in_field, int max_pattern_centroids,
                                     int max_verify_centroids, std::pmr::memory_resource* mr) {
  auto bad = [](const std::string& f, const std::string& w) { throw InputError("identify workspace", f + " " + w); };
  if (max_centroids < 1 || max_centroids > 100000) bad("max_centroids", "must be in [1, 100000]");
  if (max_stars_in_field < 1 || max_stars_in_field > 1000000) bad("max_stars_in_field", "must be in [1, 1000000]");
  if (max_pattern_centroids < 3 || max_pattern_centroids > 1000) bad("max_pattern_centroids", "must be in [3, 1000]");
  if (max_verify_centroids < 3 || max_verify_centroids > 100000) bad("max_verify_centroids", "must be in [3, 100000]");
  if (static_cast<double>(std::min(max_centroids, max_verify_centroids)) * max_stars_in_field * sizeof(Cand) > 1e9)
    bad("max_verify_centroids x max_stars_in_field", "needs more than 1 GB of match candidates");
  s_ = MakeInResource<Scratch>(mr, max_centroids, max_stars_in_field, max_pattern_centroids, max_verify_centroids,
                               false, mr);
}

IdentifyWorkspace::IdentifyWorkspace()
    : s_(MakeInResource<Scratch>(std::pmr::get_default_resource(), 0, 0, 0, 0, true,
                                 std::pmr::get_default_resource())) {}
IdentifyWorkspace::~IdentifyWorkspace() = default;
IdentifyWorkspace::IdentifyWorkspace(IdentifyWorkspace&&) noexcept = default;
IdentifyWorkspace& IdentifyWorkspace::operator=(IdentifyWorkspace&&) noexcept = default;

int IdentifyWorkspace::max_centroids() const { return static_cast<int>(s_->max_centroids); }
int IdentifyWorkspace::max_stars_in_field() const { return static_cast<int>(s_->max_stars); }
int IdentifyWorkspace::max_pattern_centroids() const { return static_cast<int>(s_->max_pattern); }
int IdentifyWorkspace::max_verify_centroids() const { return static_cast<int>(s_->max_verify); }
void IdentifyWorkspace::Reserve(Identification* out) const { out->matches.reserve(s_->max_centroids); }
size_t IdentifyWorkspace::Bytes() const { return sizeof(*this) + s_->Bytes(); }

Identification StarIdentifier::Identify(const std::vector<Centroid>& centroids, const Camera& camera,
                                        const IdentifyOptions& o) const {
  // What the workspace form reports as data, refused here as before (it does not throw).
  o.Check();
  camera.Check();
  CheckCentroids(centroids);
  Camera searched;
  double lo = 1, hi = 1;
  std::string why;
  if (!SearchedCamera(camera, o, catalog_, &searched, &lo, &hi, &why)) throw InputError(catalog_.source, why);
  if (static_cast<int>(centroids.size()) >= o.min_matches && index_->Empty())
    throw InputError(catalog_.source, "catalog has no pattern index");
  IdentifyWorkspace ws;
  ws.diagnostics = true;
  Identification out;
  Identify(centroids.data(), centroids.size(), camera, o, &ws, &out);
  return out;
}

Identification StarIdentifier::MatchWithAttitude(const std::vector<Centroid>& centroids, const Camera& camera,
                                                 const Quat& q_predicted, double search_radius_px,
                                                 const IdentifyOptions& o) const {
  o.Check();
  CheckCentroids(centroids);
  IdentifyWorkspace ws;
  ws.diagnostics = true;
  Identification out;
  MatchWithAttitude(centroids.data(), centroids.size(), camera, q_predicted, search_radius_px, o, &ws, &out);
  return out;
}

SolveStatus StarIdentifier::Identify(const Centroid* centroids, size_t n_centroids, const Camera& camera_in,
                                     const IdentifyOptions& o, IdentifyWorkspace* ws, Identification* out) const {
  const bool diag = ws->diagnostics;
  const auto t0 = diag ? Clock::now() : Clock::time_point();
  Scratch& sc = *ws->s_;
  Reset(out);
  double scale_lo = 1, scale_hi = 1;
  Camera camera;
  if (!SearchedCamera(camera_in, o, catalog_, &camera, &scale_lo, &scale_hi, diag ? &out->message : nullptr)) {
    out->status = SolveStatus::kNoMatch;
    out->input_error = true;
    return out->status;
  }
  const bool focal_searched = o.FocalSearched();
  // Unknown FOV: no focal length until one is found (null in the JSON).
  out->focal_length_px = o.FovRange() ? std::nan("") : camera.focal_length_px;
  out->focal_length_y_px = o.FovRange() ? std::nan("") : camera.FocalYPx();
  TakeCentroids(centroids, n_centroids, &sc, out);
  const int n = static_cast<int>(sc.centroids.size());
  if (n < o.min_matches) {
    out->status = SolveStatus::kTooFewStars;
    if (diag) {
      out->message = std::to_string(n) + " centroids, need at least " + std::to_string(o.min_matches);
      out->timing_ms["identify"] = MsSince(t0);
    }
    return out->status;
  }
  if (index_->Empty()) {
    out->status = SolveStatus::kNoMatch;
    out->input_error = true;
    if (diag) out->message = "catalog has no pattern index";
    return out->status;
  }
  const Context ctx = MakeContext(this, index_.get(), &sc, out, o);
  int k_pat = std::min(o.pattern_centroids, n);
  if (!sc.grow && k_pat > static_cast<int>(sc.max_pattern)) {
    k_pat = static_cast<int>(sc.max_pattern);
    out->centroids_clamped = true;
  }
  const auto& ang = PatternAngles(ctx, camera, k_pat);
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

  int hyp = 0, patterns = 0;
  double best_prob = 1.0;
  int best_k = 0;
  auto give_up = [&](SearchStop stop) {
    out->status = SolveStatus::kNoMatch;
    out->stop = stop;
    out->hypotheses = hyp;
    out->patterns = patterns;
    out->false_match_probability = best_prob;
    if (diag) {
      std::string why;
      if (stop == SearchStop::kTimeout) why = "timed out after " + std::to_string(hyp) + " hypotheses";
      if (stop == SearchStop::kPatternBudget) why = "gave up after " + std::to_string(patterns) + " patterns";
      if (stop == SearchStop::kHypothesisBudget) why = "gave up after " + std::to_string(hyp) + " hypotheses";
      if (stop == SearchStop::kExhausted) why = "no hypothesis verified (" + std::to_string(hyp) + " tried)";
      out->message =
          why + " (best " + std::to_string(best_k) + " matches, chance probability " + std::to_string(best_prob) + ")";
      out->timing_ms["identify"] = MsSince(t0);
    }
    return out->status;
  };
  static const int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  // Triangles brightest first: all triangles whose faintest vertex is c come before c + 1.
  for (int c = 2; c < k_pat; ++c) {
    for (int b = 1; b < c; ++b) {
      if (o.timeout_ms > 0 && ThreadCpuMs() > deadline_cpu_ms) return give_up(SearchStop::kTimeout);
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
        if (patterns == o.max_patterns) return give_up(SearchStop::kPatternBudget);
        ++patterns;
        bool ended = false;  // a budget reached or a hypothesis accepted: *out is the answer
        index_->ForEachInBox(s[0] / s[2], s[1] / s[2], std::log(s[2]) - ln_mid, tol_r, tol_l, catalog_, [&](int ti) {
          const CatalogTriangle& t = catalog_.triangles[ti];
          const Vec3* r[3] = {&catalog_.stars[t.v[0]].unit, &catalog_.stars[t.v[1]].unit, &catalog_.stars[t.v[2]].unit};
          // Catalog sides from the stored features (vertex i is opposite side i, shortest first).
          const double cside[3] = {t.ratio_a * static_cast<double>(t.longest_rad),
                                   t.ratio_b * static_cast<double>(t.longest_rad), static_cast<double>(t.longest_rad)};
          const double scale0 = s[2] / t.longest_rad;  // observed / catalog angle ~ f_true / f_nominal
          if (scale0 < scale_lo - tol_side / s[2] || scale0 > scale_hi + tol_side / s[2]) return true;
          for (const auto& pm : kPerm) {
            TriangleMatch tm{vtx, pm, side, cside, r, side_sigma, s[2], scale0};
            Camera cam = camera;
            Mat3 rot;
            int tri_c[3], tri_s[3];
            if (!TriangleHypothesis(ctx, o, t, tm, focal_searched, &cam, &rot, tri_c, tri_s)) continue;
            if (hyp == o.max_hypotheses) {
              give_up(SearchStop::kHypothesisBudget);
              ended = true;
              return false;
            }
            ++hyp;
            // Unknown FOV: hundreds of catalog triangles fit each query; skip the full test (which
            // predicts every catalog star in the field) unless one of the brightest other centroids
            // has a catalog star within its test radius. A skipped hypothesis still counts in h.
            if (o.FovRange() && !AnyBrightCentroidNearAStar(ctx, o, cam, rot, tri_c)) continue;
            const HypothesisTest ht = TestHypothesis(ctx, o, cam, rot, tri_c, tri_s, focal_searched);
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
            const double phot = PhotometricFactor(ctx, sc.test);
            const double prob =
                std::min(1.0, BinomialTail(ctx.m - 3, u, ht.extra) * j_factor * phot * hyp * seq_factor);
            if (prob < best_prob) best_prob = prob, best_k = k;
            if (prob >= o.max_false_match_prob) continue;
            // Accepted: refined, outliers left out (FinishHypothesis).
            if (!FinishHypothesis(ctx, o, cam, rot, ht, {u, prob, phot, seq_factor, hyp, k}, focal_searched, diag, out))
              continue;
            out->patterns = patterns;
            out->stop = SearchStop::kAccepted;
            if (diag) out->timing_ms["identify"] = MsSince(t0);
            ended = true;
            return false;
          }
          return true;
        });
        if (ended) return out->status;
      }
    }
  }
  return give_up(SearchStop::kExhausted);
}

SolveStatus StarIdentifier::MatchWithAttitude(const Centroid* centroids, size_t n_centroids, const Camera& camera,
                                              const Quat& q_predicted, double search_radius_px,
                                              const IdentifyOptions& o, IdentifyWorkspace* ws,
                                              Identification* out) const {
  const bool diag = ws->diagnostics;
  const auto t0 = diag ? Clock::now() : Clock::time_point();
  Scratch& sc = *ws->s_;
  Reset(out);
  const int min_k = std::max(o.min_matches, kMinTrackedMatches);
  out->focal_length_px = camera.focal_length_px;
  out->focal_length_y_px = camera.FocalYPx();
  TakeCentroids(centroids, n_centroids, &sc, out);
  const int n = static_cast<int>(sc.centroids.size());
  if (n < min_k) {
    out->status = SolveStatus::kTooFewStars;
    if (diag) out->message = std::to_string(n) + " centroids, need at least " + std::to_string(min_k);
    return out->status;
  }
  const Context ctx = MakeContext(this, index_.get(), &sc, out, o);
  const Mat3 r_pred = q_predicted.normalized().toRotationMatrix();
  const int n_cat0 = Verify(ctx, camera, r_pred, std::max(search_radius_px, ctx.match_radius_px), nullptr, &sc.cur);
  const size_t initial_pairs = sc.cur.size();
  if (static_cast<int>(sc.cur.size()) < min_k) {
    out->status = SolveStatus::kNoMatch;
    if (diag) {
      out->message = "lost lock: " + std::to_string(sc.cur.size()) + " stars near their predicted positions";
      out->timing_ms["identify"] = MsSince(t0);
    }
    return out->status;
  }
  // Tracking keeps the focal length found (or refined) when the lock was acquired.
  const Refined rf = Refine(ctx, camera, r_pred, n_cat0, nullptr, false);
  const int k = static_cast<int>(sc.cur.size());
  // The refit attitude has three free parameters that can line up a few wrong pairs (a 5-degree
  // jump found 5 such matches in a test): count them out as in lost in space, take a Bonferroni
  // factor for the candidate pairs of the wide first search, and require that a fair share of the
  // stars that should be visible are matched.
  const double n_pairs = std::max(1.0, static_cast<double>(initial_pairs));
  const double prob =
      std::min(1.0, ChanceProbability(ctx.m - 3, rf.n_cat, ctx.match_radius_px, camera, k - 3) * n_pairs);
  const double expected = std::min(rf.n_cat, ctx.m);
  out->false_match_probability = prob;
  if (k < kMinTrackedFraction * expected) {
    out->status = SolveStatus::kNoMatch;
    if (diag)
      out->message = "lost lock: " + std::to_string(k) + " of " + std::to_string(static_cast<int>(expected)) +
                     " predicted stars matched";
    return out->status;
  }
  out->hypotheses = 1;
  out->catalog_stars_in_field = rf.n_cat;
  if (diag) out->timing_ms["identify"] = MsSince(t0);
  if (k >= min_k && prob < o.max_false_match_prob) {
    out->status = SolveStatus::kSolved;
    out->q_inertial_from_sensor = Quat(rf.r).normalized();
    if (out->q_inertial_from_sensor.w() < 0) out->q_inertial_from_sensor.coeffs() *= -1;
    out->matches.assign(sc.cur.begin(), sc.cur.end());
    ToInputIndices(sc, out);
    if (diag) out->message = std::to_string(k) + " stars matched";
  } else {
    out->status = SolveStatus::kNoMatch;
    if (diag) out->message = "lost lock: " + std::to_string(k) + " matches, chance probability " + std::to_string(prob);
  }
  return out->status;
}

}  // namespace ssiu
