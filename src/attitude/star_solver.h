// The star tracker pipeline: frame or centroids -> verified identification -> QUEST attitude, and a
// tracker that re-uses the previous attitude. `ssiu solve` and `ssiu track` are thin wrappers.
//
//   StarIdentifier id(LoadOrBuildCatalog(DefaultSourceFor(fov_deg), catalog_options));
//   SolveResult r = SolveFrame(id, frame.image.view(), camera, SolveOptions{});
//   WriteJsonFile("-", SolveResultToJson(r));
#pragma once

#include <map>
#include <ostream>
#include <string>
#include <vector>

#include "attitude/quest.h"
#include "core/astrometry.h"
#include "core/camera.h"
#include "core/image.h"
#include "core/json.h"
#include "detect/detect.h"
#include "identify/identify.h"

namespace ssiu {

struct SolveOptions {
  IdentifyOptions identify;
  // Identification needs only the brighter stars; a high threshold keeps noise peaks and faint
  // residuals of hot pixels out of the patterns (5 sigma gives ~1000 detections on the
  // openstartracker frames, none of which solve; 8 sigma solves them).
  DetectOptions detect = [] {
    DetectOptions d;
    d.threshold_sigma = 8.0;
    return d;
  }();
  // The detector's Gaussian-fit centroid sigma is scaled by this before weighting. On the simulated
  // frames of the 1000-frame long test (tests/attitude/sim_frames_longtest.cc) the normalised
  // centroid errors have a robust sigma of 1.01 and an rms of 1.03 within 5 sigma, but 0.3% of them
  // lie beyond (blends with faint neighbours) and bring the plain rms to 1.20. Identify's outlier
  // test leaves such matches out of the attitude, so the scale is the rms within 5 sigma: the long
  // test's mean NEES is 2.95 at 1.03 (2.30 at 1.17), its distribution chi-square with 3 dof at
  // every quantile from 25% to 99% once scaled; the 50-frame normal test's median NEES is 3.25 at
  // 1.03, 3.31 at 1.02 (bound 3.27).
  double detector_sigma_scale = 1.03;
  double track_search_radius_px = 25.0;  // tracking: how far a star may be from its prediction
  // The camera's vignetting (camera.json `vignetting`, flux factor 1 - vignetting (r / r_corner)^2,
  // core/camera.h): the fluxes are divided by it before identification, so that the photometric evidence
  // compares the catalog magnitudes with the light the optics let through. 0 = none; in [0, 1).
  double vignetting = 0;
  // Frame time and observer velocity (docs/identify.md, "Time and motion"): with a time, the matched
  // catalog stars are brought to the frame's date with proper motion and aberrated (annual, plus the
  // spacecraft's velocity when given) before the attitude fit, so that q is the attitude in ICRS.
  // Identification itself does not need them (the field's differential aberration is < 4 arcsec).
  // Tracker::Update and the unit processor take sky.time as the time of t_s = 0.
  SkyCorrections sky;
  void Check() const;  // throws InputError naming the field
};

// camera.json's fields beyond the geometry (CameraExtras) as detection and solving use them: its
// psf_sigma_px is the detector's expected PSF where the options set none (0), so that the matched
// filter and the interferer tests are made for the optics even on a frame with too few bright stars to
// measure it; its vignetting is taken out of the fluxes before identification. (Its hot_pixels are the
// defect map: MarkHotPixels.)
void UseCameraExtras(const CameraExtras& e, DetectOptions* o);
void UseCameraExtras(const CameraExtras& e, SolveOptions* o);

// How a frame was identified: lost in space, or by tracking from a predicted attitude (JSON "mode").
enum class SolveMode { kLostInSpace, kTracking };
inline const char* SolveModeName(SolveMode m) { return m == SolveMode::kTracking ? "tracking" : "lost_in_space"; }
inline std::ostream& operator<<(std::ostream& os, SolveMode v) { return os << SolveModeName(v); }

struct SolveResult {
  SolveStatus status = SolveStatus::kTooFewStars;
  SolveMode mode = SolveMode::kLostInSpace;
  std::string message;
  Identification identification;
  AttitudeSolution attitude;
  std::vector<Centroid> centroids;  // what was identified (detections or the CSV)
  SkyCorrections sky;               // the corrections applied to the matches (sky.active(): any)
  double catalog_epoch_year = 0;    // epoch of the catalog positions
  Detections detections;            // empty when solved from centroids
  std::map<std::string, double> timing_ms;
};

// The solver catalog in `dir` (built and saved there when absent), or with an empty dir the cached
// catalog (identify/star_catalog.h CatalogCacheDir) for the camera's larger FOV (x or y) widened by the
// focal-length tolerance. source "" = DefaultSourceFor(FOV); mag_max 0 = from the FOV.
StarIdentifier MakeIdentifierForCamera(const std::string& dir, const Camera& camera, double fov_tolerance_pct,
                                       double mag_max = 0, const std::string& source = "");

// Unknown field of view (IdentifyOptions::fov_min_deg/fov_max_deg): the catalog for horizontal FOVs
// fov_min_deg..fov_max_deg (stars for the smallest, triangles up to the largest; docs/identify.md).
StarIdentifier MakeIdentifierForFovRange(const std::string& dir, const Camera& camera, double fov_min_deg,
                                         double fov_max_deg, double mag_max = 0, const std::string& source = "");

// The identifier a solve with `options` needs: MakeIdentifierForFovRange when the field of view is
// unknown (options.FovRange()), else MakeIdentifierForCamera with options.fov_tolerance_pct.
StarIdentifier MakeIdentifierFor(const std::string& dir, const Camera& camera, const IdentifyOptions& options,
                                 double mag_max = 0, const std::string& source = "");

// Centroid list from detections (flux, and the fit's 1-sigma as the position noise).
std::vector<Centroid> CentroidsFromDetections(const Detections& d, double sigma_scale = 1.0);
// The same into `out`, cleared and refilled (no allocation once its capacity holds d.stars.size()).
void CentroidsFromDetections(const Detections& d, double sigma_scale, std::vector<Centroid>* out);
// Divides the fluxes by the camera's vignetting 1 - v (r / r_corner)^2 (SolveOptions::vignetting; floored
// at 0.05 so that a corner beyond the law's reach stays finite), in place: no allocation.
void TakeOutVignetting(const Camera& camera, double v, std::vector<Centroid>* centroids);
// Reads a centroid CSV: x_px,y_px[,flux][,sigma_px]. InputError naming the file/column/row.
std::vector<Centroid> ReadCentroidsCsv(const std::string& path);

SolveResult SolveCentroids(const StarIdentifier& id, const std::vector<Centroid>& centroids, const Camera& camera,
                           const SolveOptions& options);
SolveResult SolveFrame(const StarIdentifier& id, const ImageView& image, const Camera& camera,
                       const SolveOptions& options, const DefectMap* defects = nullptr);

// The matches' catalog directions -> their apparent directions at sky.time (proper motion from the
// catalog's epoch, aberration); nothing when !sky.active(). Call before SolveAttitude.
void ApplySkyCorrections(const StarIdentifier& id, const SkyCorrections& sky, Identification* identification);

// The JSON of `ssiu solve` (docs/identify.md): status, q [w,x,y,z], ra/dec/roll (deg), sigmas
// (arcsec), focal length, false-match probability, matches, timing; unsolved fields are null;
// time_utc and corrections (SolveCorrectionsToJson).
Json SolveResultToJson(const SolveResult& r);
// {"time_utc": ISO 8601 or null, "corrections": {"proper_motion_epoch": year or null, "catalog_epoch":
// year, "annual_aberration": bool, "velocity_kms": [x,y,z] or null, "aberration_arcsec": displacement
// at the boresight (null when q_inertial_from_sensor is null: unsolved)}}, merged into `j`.
void AddCorrectionsToJson(const SkyCorrections& sky, double catalog_epoch_year, const Quat* q_inertial_from_sensor,
                          Json* j);

// FITS TAN WCS header (80-character cards, END-terminated) of a solution: CRPIX at the principal
// point (FITS 1-based pixels), CRVAL its RA/Dec, CD from the attitude and fx, fy. A camera with
// distortion gets TAN-SIP: A/B (and inverse AP/BP) polynomials fitted to the camera model.
std::string TanWcsHeader(const Quat& q_inertial_from_sensor, const Camera& camera);

// Lost-in-space on the first frame, then prediction from the previous attitude and rate
// (constant-rate extrapolation from the last two solutions), falling back to lost in space when
// the lock is lost.
class Tracker {
 public:
  Tracker(const StarIdentifier& id, const Camera& camera, const SolveOptions& options)
      : id_(id), camera_(camera), options_(options) {}
  // t_s: frame time; frames without times use their index.
  SolveResult Update(const std::vector<Centroid>& centroids, double t_s);
  bool locked() const { return locked_; }

 private:
  const StarIdentifier& id_;
  Camera camera_;
  SolveOptions options_;
  bool locked_ = false;
  bool have_rate_ = false;
  Quat q_last_ = Quat::Identity();
  Vec3 w_sensor_rad_s_ = Vec3::Zero();
  double t_last_ = 0;
};

}  // namespace ssiu
