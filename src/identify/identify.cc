#include "identify/identify.h"

#include <flann/flann.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include "core/error.h"
#include "identify/wahba_svd.h"

namespace ssiu {

struct StarIdentifier::Index {
  // (ratio_a, ratio_b, ln longest_rad) per triangle. The log of the longest side makes its
  // tolerance relative (d ln L = dL / L), about as large as the ratios' (~sqrt(2) dL / L), so one
  // isotropic radius search selects on shape and size together; with the shape alone a short
  // observed triangle (wide ratio tolerance) returned thousands of candidates.
  std::vector<float> features;
  std::vector<double> units;    // star unit vectors
  std::unique_ptr<flann::Index<flann::L2<float>>> triangles;
  std::unique_ptr<flann::Index<flann::L2<double>>> stars;
};

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kMinTrackedFraction = 0.3;  // tracking: matched / min(predicted, centroids)
double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

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
  double match_radius_px = 0;
};

struct Verification {
  std::vector<StarMatch> matches;
  int n_cat = 0;
};

// Predicts all catalog stars in the field with R (sensor -> inertial) and the camera, and matches
// the first ctx.m centroids to them one-to-one, nearest pairs first, within radius_px.
Verification Verify(const Context& ctx, const Camera& cam, const Mat3& r, double radius_px) {
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

Mat3 SvdFromMatches(const std::vector<StarMatch>& ms) {
  std::vector<VectorPair> pairs;
  pairs.reserve(ms.size());
  for (const auto& m : ms) pairs.push_back({m.b_sensor, m.r_inertial, 1.0 / (m.sigma_rad * m.sigma_rad)});
  return SolveWahbaSvd(pairs).toRotationMatrix();
}

// Gauss-Newton on pixel residuals over a small rotation (sensor frame) and a common scale of fx and fy
// (the pixel aspect fy/fx is the camera's).
void RefineFocal(const Context& ctx, const std::vector<StarMatch>& ms, Camera* cam, Mat3* r) {
  if (ms.size() < 4) return;
  for (int iter = 0; iter < 4; ++iter) {
    Eigen::Matrix4d h = Eigen::Matrix4d::Zero();
    Vec4 g = Vec4::Zero();
    auto residual = [&](const StarMatch& m, const Vec4& x, Vec2* out) {
      Camera c2 = *cam;
      c2.ScaleFocal(1 + x[3]);
      const Mat3 rr = *r * ExpSo3(x.head<3>());
      const auto p = c2.Project(rr.transpose() * m.r_inertial);
      if (!p) return false;
      *out = *p - Vec2(m.x_px, m.y_px);
      return true;
    };
    for (const auto& m : ms) {
      Vec2 r0;
      if (!residual(m, Vec4::Zero(), &r0)) continue;
      Eigen::Matrix<double, 2, 4> j;
      for (int k = 0; k < 4; ++k) {
        Vec4 dx = Vec4::Zero();
        dx[k] = 1e-7;
        Vec2 r1;
        if (!residual(m, dx, &r1)) r1 = r0;
        j.col(k) = (r1 - r0) / 1e-7;
      }
      const double w = 1.0 / std::pow(ctx.sigma_px[m.centroid], 2);
      h += w * j.transpose() * j;
      g += w * j.transpose() * r0;
    }
    const Vec4 dx = -h.ldlt().solve(g);
    if (!dx.allFinite()) return;
    cam->ScaleFocal(1 + dx[3]);
    *r = *r * ExpSo3(dx.head<3>());
    if (dx.head<3>().norm() < 1e-10 && std::abs(dx[3]) < 1e-10) break;
  }
}

struct Refined {
  Verification v;
  Mat3 r;
  Camera cam;
};

// Fit the attitude (and the focal length when it is uncertain) to the matches and re-match, twice.
Refined Refine(const Context& ctx, const IdentifyOptions& o, Camera cam, Mat3 r, Verification v) {
  for (int pass = 0; pass < 3; ++pass) {
    if (o.fov_tolerance_pct > 0) {
      RefineFocal(ctx, v.matches, &cam, &r);
      for (auto& m : v.matches) m.b_sensor = cam.Unproject(Vec2(m.x_px, m.y_px));
    } else {
      r = SvdFromMatches(v.matches);
    }
    Verification v2 = Verify(ctx, cam, r, ctx.match_radius_px);
    if (v2.matches.size() < 3) break;
    v = std::move(v2);
  }
  if (o.fov_tolerance_pct == 0) r = SvdFromMatches(v.matches);
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
  std::vector<double> s = ctx.sigma_px;
  double med = o.centroid_sigma_px;
  if (!s.empty()) {
    std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
    med = s[s.size() / 2];
  }
  ctx.match_radius_px = o.match_radius_px > 0 ? o.match_radius_px : std::max(2.0, 5.0 * med);
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
  if (id.focal_length_px > 0 && std::isfinite(id.focal_length_px)) camera.ScaleFocal(id.focal_length_px / camera.focal_length_px);
  return camera;
}

void IdentifyOptions::Check() const {
  auto bad = [](const std::string& f, const std::string& w) { throw InputError("identify options", f + " " + w); };
  if (pattern_centroids < 3 || pattern_centroids > 40) bad("pattern_centroids", "must be in [3, 40]");
  if (verify_centroids < pattern_centroids) bad("verify_centroids", "must be >= pattern_centroids");
  if (!(centroid_sigma_px > 0 && centroid_sigma_px < 20)) bad("centroid_sigma_px", "must be in (0, 20)");
  if (!(systematic_px >= 0 && systematic_px < 20)) bad("systematic_px", "must be in [0, 20)");
  if (!(tolerance_sigmas >= 1 && tolerance_sigmas <= 20)) bad("tolerance_sigmas", "must be in [1, 20]");
  if (!(match_radius_px >= 0 && match_radius_px < 100)) bad("match_radius_px", "must be in [0, 100)");
  if (!(fov_tolerance_pct >= 0 && fov_tolerance_pct <= 30)) bad("fov_tolerance_pct", "must be in [0, 30]");
  if (!(max_false_match_prob > 0 && max_false_match_prob < 1)) bad("max_false_match_prob", "must be in (0, 1)");
  if (min_matches < 4) bad("min_matches", "must be >= 4");
  if (max_hypotheses < 1) bad("max_hypotheses", "must be >= 1");
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

StarIdentifier::StarIdentifier(SolverCatalog catalog) : catalog_(std::move(catalog)), index_(std::make_unique<Index>()) {
  auto& ix = *index_;
  ix.features.reserve(catalog_.triangles.size() * 3);
  for (const auto& t : catalog_.triangles) {
    ix.features.push_back(t.ratio_a);
    ix.features.push_back(t.ratio_b);
    ix.features.push_back(std::log(t.longest_rad));
  }
  if (!catalog_.triangles.empty()) {
    flann::Matrix<float> m(ix.features.data(), catalog_.triangles.size(), 3);
    ix.triangles = std::make_unique<flann::Index<flann::L2<float>>>(m, flann::KDTreeSingleIndexParams(16));
    ix.triangles->buildIndex();
  }
  ix.units.reserve(catalog_.stars.size() * 3);
  for (const auto& s : catalog_.stars) ix.units.insert(ix.units.end(), {s.unit[0], s.unit[1], s.unit[2]});
  if (!catalog_.stars.empty()) {
    flann::Matrix<double> m(ix.units.data(), catalog_.stars.size(), 3);
    ix.stars = std::make_unique<flann::Index<flann::L2<double>>>(m, flann::KDTreeSingleIndexParams(16));
    ix.stars->buildIndex();
  }
}

StarIdentifier::~StarIdentifier() = default;
StarIdentifier::StarIdentifier(StarIdentifier&&) noexcept = default;
StarIdentifier& StarIdentifier::operator=(StarIdentifier&&) noexcept = default;

std::vector<int> StarIdentifier::StarsWithin(const Vec3& u, double radius_rad) const {
  std::vector<int> out;
  if (!index_->stars) return out;
  double q[3] = {u[0], u[1], u[2]};
  flann::Matrix<double> qm(q, 1, 3);
  std::vector<std::vector<int>> idx;
  std::vector<std::vector<double>> dist;
  const double chord = 2 * std::sin(std::min(radius_rad, kPi) / 2);
  flann::SearchParams sp;
  sp.sorted = false;
  index_->stars->radiusSearch(qm, idx, dist, chord * chord, sp);
  out = std::move(idx[0]);
  std::sort(out.begin(), out.end());  // brightest first (catalog order)
  return out;
}

Identification StarIdentifier::Identify(const std::vector<Centroid>& centroids, const Camera& camera,
                                        const IdentifyOptions& o) const {
  const auto t0 = Clock::now();
  o.Check();
  camera.Check();
  CheckCentroids(centroids);
  Identification out;
  out.focal_length_px = camera.focal_length_px;
  out.focal_length_y_px = camera.FocalYPx();
  const int n = static_cast<int>(centroids.size());
  if (n < o.min_matches) {
    out.status = "too_few_stars";
    out.message = std::to_string(n) + " centroids, need at least " + std::to_string(o.min_matches);
    out.timing_ms["identify"] = MsSince(t0);
    return out;
  }
  if (!index_->triangles) throw InputError(catalog_.source, "catalog has no pattern index");
  const Context ctx = MakeContext(this, centroids, o);
  const int k_pat = std::min(o.pattern_centroids, n);
  std::vector<Vec3> u(k_pat);
  for (int i = 0; i < k_pat; ++i) {
    const auto& c = centroids[ctx.order[i]];
    u[i] = camera.Unproject(Vec2(c.x_px, c.y_px));
  }
  const double f = camera.FocalMinPx();  // side tolerances hold along both axes
  const double ptol = o.fov_tolerance_pct / 100.0;
  const double fov = catalog_.fov_deg * kDegToRad;
  // ln of the focal-length scale range: observed longest side / catalog longest side.
  const double ln_scale_tol = ptol > 0 ? std::max(std::log1p(ptol), -std::log1p(-ptol)) : 0.0;

  std::vector<std::vector<int>> idx;
  std::vector<std::vector<float>> dist;
  flann::SearchParams sp;
  sp.sorted = false;
  int hyp = 0;
  double best_prob = 1.0;
  int best_k = 0;
  static const int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  // Triangles brightest first: all triangles whose faintest vertex is c come before c + 1.
  for (int c = 2; c < k_pat; ++c) {
    for (int b = 1; b < c; ++b) {
      for (int a = 0; a < b; ++a) {
        const int vtx[3] = {a, b, c};
        // Side-length tolerance (rad) from this triangle's own centroid noise (a poorly measured
        // centroid elsewhere in the frame does not widen every search).
        const double sig_tri = std::max({ctx.sigma_px[ctx.order[a]], ctx.sigma_px[ctx.order[b]], ctx.sigma_px[ctx.order[c]]});
        const double tol_side = o.tolerance_sigmas * std::sqrt(2.0) * sig_tri / f;
        const double side[3] = {Angle(u[b], u[c]), Angle(u[a], u[c]), Angle(u[a], u[b])};
        double s[3] = {side[0], side[1], side[2]};
        std::sort(s, s + 3);
        if (s[2] > fov * (1 + ptol) + tol_side || s[0] < 1e-9) continue;
        // Ratio tolerance: d(a/c) = sqrt(da^2 + (a/c)^2 dc^2) / c <= sqrt(2) tol / c; ln of the
        // longest side: the focal-length range plus tol / c.
        const double tol_r = tol_side * std::sqrt(2.0) / s[2] + 1e-4;
        const double tol_l = ln_scale_tol + 1.1 * tol_side / s[2] + 1e-4;
        float q[3] = {static_cast<float>(s[0] / s[2]), static_cast<float>(s[1] / s[2]), static_cast<float>(std::log(s[2]))};
        flann::Matrix<float> qm(q, 1, 3);
        index_->triangles->radiusSearch(qm, idx, dist, static_cast<float>(2 * tol_r * tol_r + tol_l * tol_l), sp);
        for (int ti : idx[0]) {
          const CatalogTriangle& t = catalog_.triangles[ti];
          const Vec3* r[3] = {&catalog_.stars[t.v[0]].unit, &catalog_.stars[t.v[1]].unit, &catalog_.stars[t.v[2]].unit};
          // Catalog sides from the stored features (vertex i is opposite side i, shortest first).
          const double cside[3] = {t.ratio_a * static_cast<double>(t.longest_rad), t.ratio_b * static_cast<double>(t.longest_rad),
                                   static_cast<double>(t.longest_rad)};
          const double scale = s[2] / t.longest_rad;  // observed / catalog angle ~ f_true / f_nominal
          if (std::abs(scale - 1) > ptol + tol_side / s[2]) continue;
          for (const auto& pm : kPerm) {
            // Observed vertex vtx[i] <-> catalog vertex pm[i]: opposite sides must agree (after scale).
            bool ok = true;
            for (int i = 0; i < 3 && ok; ++i) ok = std::abs(side[i] / scale - cside[pm[i]]) <= 2 * tol_side;
            if (!ok) continue;
            Camera cam = camera;
            if (ptol > 0) cam.ScaleFocal(scale);
            Vec3 bv[3];
            for (int i = 0; i < 3; ++i) {
              const auto& cc = centroids[ctx.order[vtx[i]]];
              bv[i] = cam.Unproject(Vec2(cc.x_px, cc.y_px));
            }
            // Same handedness: a rotation cannot mirror the triangle.
            const double db = bv[0].dot(bv[1].cross(bv[2]));
            const double dr = r[pm[0]]->dot(r[pm[1]]->cross(*r[pm[2]]));
            if (db * dr <= 0) continue;
            std::vector<VectorPair> pairs;
            for (int i = 0; i < 3; ++i) pairs.push_back({bv[i], *r[pm[i]], 1.0});
            const Mat3 rot = SolveWahbaSvd(pairs).toRotationMatrix();
            if (++hyp > o.max_hypotheses) {
              out.status = "no_match";
              out.message = "gave up after " + std::to_string(o.max_hypotheses) + " hypotheses";
              out.hypotheses = hyp - 1;
              out.false_match_probability = best_prob;
              out.timing_ms["identify"] = MsSince(t0);
              return out;
            }
            Verification v = Verify(ctx, cam, rot, ctx.match_radius_px * (ptol > 0 ? 2.0 : 1.0));
            if (static_cast<int>(v.matches.size()) < o.min_matches) continue;
            Refined rf = Refine(ctx, o, cam, rot, std::move(v));
            const int k = static_cast<int>(rf.v.matches.size());
            // Three matches are the hypothesis itself; the others are the evidence. Bonferroni over
            // the hypotheses tried so far.
            const double prob =
                std::min(1.0, ChanceProbability(ctx.m - 3, rf.v.n_cat, ctx.match_radius_px, rf.cam, k - 3) * hyp);
            if (prob < best_prob) best_prob = prob, best_k = k;
            if (k >= o.min_matches && prob < o.max_false_match_prob) {
              out.status = "solved";
              out.q_inertial_from_sensor = Quat(rf.r).normalized();
              if (out.q_inertial_from_sensor.w() < 0) out.q_inertial_from_sensor.coeffs() *= -1;
              out.focal_length_px = rf.cam.focal_length_px;
              out.focal_length_y_px = rf.cam.FocalYPx();
              out.false_match_probability = prob;
              out.matches = std::move(rf.v.matches);
              out.hypotheses = hyp;
              out.catalog_stars_in_field = rf.v.n_cat;
              out.message = std::to_string(k) + " stars matched";
              out.timing_ms["identify"] = MsSince(t0);
              return out;
            }
          }
        }
      }
    }
  }
  out.status = "no_match";
  out.hypotheses = hyp;
  out.false_match_probability = best_prob;
  out.message = "no hypothesis verified (" + std::to_string(hyp) + " tried, best " + std::to_string(best_k) +
                " matches, chance probability " + std::to_string(best_prob) + ")";
  out.timing_ms["identify"] = MsSince(t0);
  return out;
}

Identification StarIdentifier::MatchWithAttitude(const std::vector<Centroid>& centroids, const Camera& camera,
                                                 const Quat& q_predicted, double search_radius_px,
                                                 const IdentifyOptions& o) const {
  const auto t0 = Clock::now();
  o.Check();
  CheckCentroids(centroids);
  Identification out;
  out.focal_length_px = camera.focal_length_px;
  out.focal_length_y_px = camera.FocalYPx();
  const int n = static_cast<int>(centroids.size());
  if (n < o.min_matches) {
    out.status = "too_few_stars";
    out.message = std::to_string(n) + " centroids, need at least " + std::to_string(o.min_matches);
    return out;
  }
  const Context ctx = MakeContext(this, centroids, o);
  const Mat3 r_pred = q_predicted.normalized().toRotationMatrix();
  Verification v = Verify(ctx, camera, r_pred, std::max(search_radius_px, ctx.match_radius_px));
  const size_t initial_pairs = v.matches.size();
  if (static_cast<int>(v.matches.size()) < o.min_matches) {
    out.status = "no_match";
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
    out.status = "no_match";
    out.message = "lost lock: " + std::to_string(k) + " of " + std::to_string(static_cast<int>(expected)) +
                  " predicted stars matched";
    return out;
  }
  out.hypotheses = 1;
  out.catalog_stars_in_field = rf.v.n_cat;
  out.timing_ms["identify"] = MsSince(t0);
  if (k >= o.min_matches && prob < o.max_false_match_prob) {
    out.status = "solved";
    out.q_inertial_from_sensor = Quat(rf.r).normalized();
    if (out.q_inertial_from_sensor.w() < 0) out.q_inertial_from_sensor.coeffs() *= -1;
    out.matches = std::move(rf.v.matches);
    out.message = std::to_string(k) + " stars matched";
  } else {
    out.status = "no_match";
    out.message = "lost lock: " + std::to_string(k) + " matches, chance probability " + std::to_string(prob);
  }
  return out;
}

}  // namespace ssiu
