// Lost-in-space star identification: centroids -> catalog stars, with a verified hypothesis and the
// probability that the match is chance.
//
//   StarIdentifier id(LoadSolverCatalog(dir));
//   Identification r = id.Identify(centroids, camera, IdentifyOptions{});
//   if (r.status == SolveStatus::kSolved) ... r.matches ...
//
// Without heap allocation after init (the flight core, issue 26): the same calls into a workspace
// and a reused result (docs/identify.md, "Memory"):
//
//   IdentifyWorkspace ws(200, 800);  // allocates
//   Identification r;
//   ws.Reserve(&r);
//   id.Identify(centroids, camera, options, &ws, &r);  // per frame: no allocation, no exception
//
// Method (docs/identify.md): triangles of the centroids in brightness order, deep into the list; the
// side-length ratios (which do
// not depend on the focal length) and the log of the longest side are looked up in a FLANN kd-tree
// of catalog triangles with a tolerance from the centroid noise and the focal-length range;
// each hypothesis (vertex correspondence + handedness) gives an attitude (and focal length) that
// predicts every catalog star in the field; the other centroids that fall within verify_sigmas of a
// prediction are counted and the chance of as many by accident is a binomial tail (after tetra3 /
// cedar-solve), multiplied by the number of hypotheses tried and a sequential-testing factor.
// Accepted only below max_false_match_prob.
#pragma once

#include <cmath>
#include <cstddef>
#include <map>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "core/arena.h"
#include "core/camera.h"
#include "core/types.h"
#include "identify/solve_status.h"
#include "identify/star_catalog.h"

namespace ssiu {

struct Centroid {
  double x_px = 0, y_px = 0;
  double flux = 0;      // brightness for ordering (any unit); 0 for all = keep input order
  double sigma_px = 0;  // 1-sigma position noise; 0 = IdentifyOptions::centroid_sigma_px
};

struct IdentifyOptions {
  // Deep search: triangles of up to this many brightest centroids, in brightness order (every
  // triangle whose faintest vertex is the c-th centroid before those of the (c+1)-th), so the bright
  // ones come first but false objects brighter than the stars do not stop the search.
  int pattern_centroids = 100;
  int verify_centroids = 150;      // brightest centroids used in verification (>= pattern_centroids)
  double centroid_sigma_px = 0.3;  // position noise when a centroid carries none
  double systematic_px = 0.5;      // unmodelled position error (distortion, catalog) added in quadrature
  double tolerance_sigmas = 4.0;   // pattern key lookup tolerance in noise sigmas
  // Each side of a candidate triangle must then agree with the catalog's within this many sigmas of
  // its own error (docs/identify.md, step 2): fewer chance hypotheses, so a smaller factor h.
  double side_sigmas = 3.5;
  double match_radius_px = 0.0;  // refinement match radius; 0 = max(2 px, 5 sigma)
  // Hypothesis test radius, in sigmas of each predicted star's position error (centroid noise and
  // the error the triangle's own noise puts into the hypothesis there); the chance probability is
  // computed for exactly this radius.
  double verify_sigmas = 3.5;
  // A refined match whose deleted residual (the drop of the fit's chi-square without it, 2 degrees of
  // freedom) exceeds outlier_sigmas^2 is left out and the rest refit (docs/identify.md, step 6).
  double outlier_sigmas = 5.0;
  double fov_tolerance_pct = 0.0;  // focal length known to +/- this percent: search and refine it
  // Unknown field of view (`--fov-range-deg MIN,MAX`): the horizontal FOV is searched in [min, max]
  // deg and the focal length found and refined; the camera's own focal length is ignored (its pixel
  // aspect fy/fx is kept). 0, 0 = off. Not with fov_tolerance_pct. The catalog must span the range
  // (CatalogBuildOptions::fov_min_deg .. fov_deg).
  double fov_min_deg = 0.0, fov_max_deg = 0.0;
  // Accept a hypothesis only below this chance probability. 1e-4 (1e-5 before issue 14's four-star
  // solutions): calibrated in every mode (observed false rates at or below it, docs/results.md), and
  // it solves 95% of Kelvins-style scenes with >= 4 stars among up to 80 false objects.
  double max_false_match_prob = 1e-4;
  int min_matches = 4;  // fewer verified matches: never solved
  // The work budget (docs/identify.md, "Work budget"): the search gives up (no_match) after
  // max_hypotheses hypotheses (vertex correspondences that pass the side check, each tested or, with
  // an unknown FOV, pre-screened) or max_patterns centroid triangles looked up in the index, whichever
  // comes first. Counts, not time, so that a frame gives the same answer on every processor and at
  // every load. max_hypotheses also sets the sequential-testing factor 1 + ln(max_hypotheses) (step 5).
  // 12,000: what 50 ms of CPU bought in the focal-searched modes (the unknown-FOV scenes of
  // bench/identify_bench.cc solved at up to 11,785); a fixed focal length needs far fewer (<= 477 on
  // ESA's 1000 false-star scenes). 200,000 patterns: more than the 161,700 triangles of the default 100
  // pattern centroids, so it binds only when pattern_centroids is raised.
  int max_hypotheses = 12000;
  int max_patterns = 200000;
  // An outer safety limit on the CPU time of the calling thread (0 = off, the default): a search that
  // hits it before the counts depends on the processor's speed (Identification::stop says which
  // limit ended a search).
  double timeout_ms = 0.0;
  // Photometric evidence (docs/identify.md, step 5): under a chance match the matched centroids'
  // fluxes are independent of the catalog magnitudes, so their agreement multiplies the chance
  // probability by a calibrated factor (at most 2 when the photometry disagrees). Off when the
  // centroids carry no usable flux (any <= 0, or all equal).
  bool use_photometry = true;
  // The hypothesis test expects only the catalog stars that the triangle's photometric zero point
  // predicts brighter than the faintest verification centroid plus this margin (mag): fainter ones
  // are no place for a chance match (docs/identify.md, step 4). Only with photometry; 0 = every star
  // in the field. The margin covers colour terms and saturation; it changes power, never validity.
  double detect_limit_margin_mag = 0.5;
  // A fixed focal length refined by default (docs/identify.md, "Focal length"): with at least
  // refine_focal_min_matches matches, the focal length is fitted with the attitude when the F-test of
  // that one extra parameter on the stars' pixel residuals gives p < refine_focal_p, and then used
  // (matches, attitude, the JSON's focal_length_px with its sigma). 0 = keep the camera's focal length
  // (tracking, the flight core: a calibrated camera, whose focal length should not wander frame to frame).
  double refine_focal_p = 1e-3;
  int refine_focal_min_matches = 4;
  // And the principal point, where the stars can tell it from a turn of the attitude: with at least
  // refine_principal_min_matches matches, at least 2 in each quadrant of the image, (cx, cy) is fitted
  // with the attitude (and the scale, when refined) when the F-test of those two extra parameters
  // gives p < refine_principal_p (docs/identify.md, "Focal length"). 0 = keep the camera's (and so
  // does refine_focal_p = 0: a calibrated camera keeps all its numbers).
  double refine_principal_p = 1e-5;
  int refine_principal_min_matches = 12;
  void Check() const;  // throws InputError naming the field
  bool FovRange() const { return fov_max_deg > 0; }
  bool FocalSearched() const { return fov_tolerance_pct > 0 || FovRange(); }
};

// Why a lost-in-space search ended.
enum class SearchStop {
  kNone,              // no search (too few centroids; tracking)
  kAccepted,          // a hypothesis passed the test
  kExhausted,         // every triangle of the pattern centroids tried
  kHypothesisBudget,  // max_hypotheses reached
  kPatternBudget,     // max_patterns reached
  kTimeout,           // timeout_ms of CPU time reached (the one outcome that depends on the processor)
};
const char* SearchStopName(SearchStop s);  // "none", "accepted", "exhausted", "hypothesis_budget", ...
inline std::ostream& operator<<(std::ostream& os, SearchStop v) { return os << SearchStopName(v); }

struct StarMatch {
  int centroid = -1;  // index into the input centroids
  int star = -1;      // index into SolverCatalog::stars
  StarId star_id = kInvalidStarId;
  double mag = 0;
  double x_px = 0, y_px = 0;
  Vec3 b_sensor = Vec3::UnitZ();    // measured direction (with the fitted focal length)
  Vec3 r_inertial = Vec3::UnitZ();  // catalog direction
  double sigma_rad = 0;             // 1-sigma angular noise of b_sensor
  double residual_rad = 0;          // angle between b_sensor and the solution's prediction
};

struct Identification {
  SolveStatus status = SolveStatus::kTooFewStars;
  std::string message;
  Quat q_inertial_from_sensor = Quat::Identity();  // from the matches (SVD); QUEST refines it
  double focal_length_px = 0;                      // fx used (fitted when the focal length is searched)
  double focal_length_y_px = 0;                    // fy used (the camera's aspect fy/fx is kept)
  bool focal_length_fitted = false;  // the focal length was searched and fitted (tolerance or unknown FOV)
  double focal_length_sigma_px = 0;  // its 1-sigma from the fit (jointly with the attitude); 0 when not fitted
  // A fixed focal length that the stars rejected and that was refitted (IdentifyOptions::refine_focal_p);
  // focal_length_fitted is then true too. The scale test's p-value (NaN when not tested).
  bool focal_length_refined = false;
  double focal_length_p_value = std::nan("");
  // The principal point refitted (IdentifyOptions::refine_principal_p): its value and 1-sigma, and the
  // test's p-value (NaN when not tested: too few stars, or not across the field).
  bool principal_point_refined = false;
  double cx_px = std::nan(""), cy_px = std::nan(""), principal_point_sigma_px = std::nan("");
  double principal_point_p_value = std::nan("");
  // What the refitted principal point's uncertainty adds to the attitude's covariance (rad^2, sensor
  // axes; zero unless refined): SolveAttitude adds it, since the stars that placed the principal
  // point also placed the boresight.
  Mat3 principal_point_attitude_cov_rad2 = Mat3::Zero();
  int outliers_rejected = 0;         // refined matches left out as inconsistent with the others
  double false_match_probability = 1.0;
  // The photometric factor in false_match_probability (2 / (1 + E), docs/identify.md step 5); 1 = not used.
  double photometric_factor = 1.0;
  ScratchVec<StarMatch> matches;  // (ScratchVec: the flight core's in the caller's memory, core/arena.h)
  int hypotheses = 0;  // hypotheses counted against max_hypotheses (the accepted one's index h when solved)
  int patterns = 0;    // centroid triangles looked up in the pattern index (against max_patterns)
  SearchStop stop = SearchStop::kNone;
  int catalog_stars_in_field = 0;
  std::map<std::string, double> timing_ms;
  // The workspace forms (IdentifyWorkspace): what was left out and why (the by-value forms throw
  // InputError for a non-finite centroid or a catalog that does not serve the call instead).
  int centroids_skipped = 0;       // centroids with a non-finite position or flux, or a sigma < 0 or NaN: not used
  bool centroids_clamped = false;  // more usable centroids than max_centroids (the brightest were used), or
                                   // pattern_centroids above max_pattern_centroids (that many used)
  bool stars_clamped = false;      // more catalog stars about the field than max_stars_in_field (the brightest used)
  bool input_error = false;        // the catalog has no pattern index or does not span the FOV range (no_match)
};

// The scratch storage of the workspace forms of StarIdentifier::Identify and MatchWithAttitude: made
// once (it allocates all it needs, Bytes()), then a call allocates nothing, throws nothing and reads
// no clock (but for IdentifyOptions::timeout_ms when set) when `diagnostics` is off and the result
// was prepared with Reserve. Sizes: max_centroids usable centroids (more: the brightest, flagged
// centroids_clamped), max_stars_in_field catalog stars in the circle about a field that identify
// predicts from (half the diagonal + 5%; more: the brightest, flagged stars_clamped), and
// max_pattern_centroids for IdentifyOptions::pattern_centroids. The match candidates take
// min(max_centroids, max_verify_centroids) x max_stars_in_field x 16 bytes, most of the total. One call at a time per workspace.
struct IdentifyWorkspace {
  // InputError when a size is out of range (max_centroids in [1, 100000], max_stars_in_field in
  // [1, 1000000], max_pattern_centroids in [3, 1000]).
  // max_verify_centroids: room for IdentifyOptions::verify_centroids (more: that many used, flagged
  // centroids_clamped); the match candidates take min(max_centroids, it) x max_stars_in_field x 16 bytes.
  // Every buffer comes from `mr` (the heap by default; the flight core's arena, core/arena.h).
  IdentifyWorkspace(int max_centroids, int max_stars_in_field, int max_pattern_centroids = 100,
                    int max_verify_centroids = 150, std::pmr::memory_resource* mr = std::pmr::get_default_resource());
  ~IdentifyWorkspace();
  IdentifyWorkspace(IdentifyWorkspace&&) noexcept;
  IdentifyWorkspace& operator=(IdentifyWorkspace&&) noexcept;

  // On: a result's message and timing_ms are filled (allocating, reading the clock). Off: neither.
  bool diagnostics = false;
  // Room in out->matches for max_centroids matches, so that refilling *out never allocates.
  void Reserve(Identification* out) const;
  // Heap bytes held (construction's allocation).
  size_t Bytes() const;
  int max_centroids() const;
  int max_stars_in_field() const;
  int max_pattern_centroids() const;
  int max_verify_centroids() const;

  struct Scratch;  // identify.cc

 private:
  friend class StarIdentifier;
  IdentifyWorkspace();  // the by-value forms': no sizes, buffers that grow as needed
  ResourcePtr<Scratch> s_;
};

// `camera` with the focal lengths that `id` used (fitted when the focal length is searched); the aspect is kept.
Camera FittedCamera(Camera camera, const Identification& id);

// The focal-length test of a fixed-focal lost-in-space solve (IdentifyOptions::refine_focal_p) again,
// on a solved `id`'s matches as they now are: their r_inertial made apparent (aberration, proper
// motion: attitude/star_solver.h ApplySkyCorrections), which moves the stars by a scale of up to 1e-4
// that the search, made on catalog directions, took for the focal length's. `camera` is the one given
// to Identify. The focal length (the camera's when the test is not significant), its sigma and
// p-value, the matches' b_sensor, sigma_rad and residual_rad, and the attitude are updated; the
// matches themselves are kept. Does nothing unless id was solved with a fixed focal length and
// refine_focal_p > 0.
void RetestFocalLength(const Camera& camera, const IdentifyOptions& options, Identification* id);
// The principal point's test (IdentifyOptions::refine_principal_p) on a solved fixed-focal `id`, after
// the focal length's: where it is significant, (cx, cy) with its sigma and p-value, the focal length
// (refitted with it when it was refined), the matches' b_sensor, sigma_rad, residual_rad and the
// attitude are updated; the p-value is NaN when not tested. `camera` is the one given to Identify.
void RetestPrincipalPoint(const Camera& camera, const IdentifyOptions& options, Identification* id);

class StarIdentifier {
 public:
  explicit StarIdentifier(SolverCatalog catalog);
  ~StarIdentifier();
  StarIdentifier(StarIdentifier&&) noexcept;
  StarIdentifier& operator=(StarIdentifier&&) noexcept;

  // Lost in space. InputError for bad options, camera or centroids (any non-finite), or a catalog
  // without the pattern index or the FOV range asked for.
  Identification Identify(const std::vector<Centroid>& centroids, const Camera& camera,
                          const IdentifyOptions& options) const;
  // Tracking: match directly against the stars predicted by q_predicted (search radius in pixels),
  // then refine and verify as in Identify (no pattern search, no Bonferroni factor).
  Identification MatchWithAttitude(const std::vector<Centroid>& centroids, const Camera& camera,
                                   const Quat& q_predicted, double search_radius_px,
                                   const IdentifyOptions& options) const;

  // The same into *out (cleared and refilled) with the scratch storage of *ws: the one
  // implementation, which the forms above wrap. Options and camera must have passed Check()
  // (not checked here); a non-finite centroid is skipped (Identification::centroids_skipped), a catalog
  // that cannot serve the call is input_error with status no_match. Allocates nothing and throws
  // nothing (IdentifyWorkspace). Returns out->status.
  SolveStatus Identify(const Centroid* centroids, size_t n_centroids, const Camera& camera,
                       const IdentifyOptions& options, IdentifyWorkspace* ws, Identification* out) const;
  SolveStatus Identify(const std::vector<Centroid>& centroids, const Camera& camera, const IdentifyOptions& options,
                       IdentifyWorkspace* ws, Identification* out) const {
    return Identify(centroids.data(), centroids.size(), camera, options, ws, out);
  }
  SolveStatus MatchWithAttitude(const Centroid* centroids, size_t n_centroids, const Camera& camera,
                                const Quat& q_predicted, double search_radius_px, const IdentifyOptions& options,
                                IdentifyWorkspace* ws, Identification* out) const;
  SolveStatus MatchWithAttitude(const std::vector<Centroid>& centroids, const Camera& camera, const Quat& q_predicted,
                                double search_radius_px, const IdentifyOptions& options, IdentifyWorkspace* ws,
                                Identification* out) const {
    return MatchWithAttitude(centroids.data(), centroids.size(), camera, q_predicted, search_radius_px, options, ws,
                             out);
  }

  const SolverCatalog& catalog() const { return catalog_; }
  // Indices of catalog stars within radius_rad of the unit vector u, brightest first (allocates).
  std::vector<int> StarsWithin(const Vec3& u, double radius_rad) const;

 private:
  SolverCatalog catalog_;
  std::shared_ptr<const CatalogIndex> index_;  // the catalog's own (star_catalog.h), or built here
};

// Photometric e-value of a hypothesis (docs/identify.md, step 5): pairs are the triangle's three
// (centroid flux > 0, catalog V) first, then the extra matches in the order they were tested;
// other_flux the fluxes of the verification centroids in no pair. Under a chance match (fluxes
// exchangeable given the positions) its mean is exactly 1; large when the fluxes follow the magnitudes.
double PhotometricEvidence(const std::vector<double>& pair_flux, const std::vector<double>& pair_mag,
                           const std::vector<double>& other_flux);

// P(X >= k) for X ~ Binomial(n, p).
double BinomialTail(int n, double p, int k);

}  // namespace ssiu
