// Real frames against ssiu's frame simulator, star by star (`ssiu discover frames --compare-sim`,
// docs/discrepancy.md): every solved frame is simulated at its solved attitude with the same camera,
// the simulated frames go through the same solve, and the two sides are compared: positions of the
// same catalog star, flux against catalog magnitude (zero point, slope, scatter), PSF width and
// shape (FitSpot), background level and structure, noise, solve rate and attitude error.
//
// FitSimOptions gives the extended simulator model: the measured PSF sigma (at the centre and the
// corners), ellipticity and angle, zero point, background level, gradient and noise put into
// FrameSimOptions, so that a second comparison shows the gain.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "core/camera.h"
#include "core/catalog.h"
#include "core/image.h"
#include "core/json.h"
#include "discover/discover_frames.h"
#include "sim/frame_sim.h"

namespace ssiu {

struct FrameCompareOptions {
  FrameSimOptions sim;         // the simulator model under test
  uint64_t seed = 1;           // noise seed of the first simulated frame (frame k: seed + k)
  int tile_px = 64;            // background structure: medians of tiles of this size
  double match_radius_px = 3;  // a simulated and a measured star are the same star within this
  void Check() const;          // InputError naming the field
};

// The figures of one side (measured or simulated), by the same pipeline.
struct FieldFigures {
  int frames = 0, frames_solved = 0, stars = 0;
  // ln(flux) = ln(zero_point) - 0.4 ln(10) slope V: zero_point = flux of a V = 0 star (ADU), slope 1
  // for a linear sensor in the catalog's band; scatter about the line (mag).
  double zero_point_adu = 0, flux_slope = 0, flux_scatter_mag = 0;
  double zero_point_slope1_adu = 0;                 // the same with the slope held at 1 (the simulator's law)
  double psf_sigma_px = 0, psf_e1 = 0, psf_e2 = 0;  // stamp fits (FitSpot), medians
  int psf_stars = 0;
  // The same as ellipticity 1 - minor/major and major-axis angle (from +x towards +y, deg) of the
  // median (e1, e2): |e| = (a^2 - b^2) / (a^2 + b^2) (FrameSimOptions::psf_ellipticity's definition).
  double psf_ellipticity = 0, psf_angle_deg = 0;
  // Stamp-fit sigma against u = (r / r_corner)^2 (r from the principal point, r_corner half the frame
  // diagonal; the simulator's law, straight line, one 3.5-sigma clip): values at u = 0 and u = 1.
  // 0 when the stars do not span the field (u range < 0.2) or fewer than 8. change_se: the standard
  // error of corner - centre (robust residual scale).
  double psf_sigma_centre_px = 0, psf_sigma_corner_px = 0, psf_sigma_change_se_px = 0;
  double background_adu = 0;            // median over frames of the detector's background
  double background_structure_adu = 0;  // RMS of the tile medians about their frame's median
  // A plane fitted to each frame's tile medians: the corner amplitude (median over frames, ADU; the
  // simulator's background_gradient_e_per_s in ADU) and direction (deg, from +x towards +y, of the
  // summed unit vectors); coherence = length of the mean unit vector (1: every frame the same
  // direction); the RMS of the tile medians about the plane (median over frames).
  double background_gradient_adu = 0, background_gradient_angle_deg = 0, background_gradient_coherence = 0;
  double background_plane_residual_adu = 0;
  // The radial term: median over frames of radial_adu and of -radial_adu / level_adu, the sky's
  // vignetting 1 - v (r / r_corner)^2 if the whole level is sky (no bias or offset in it).
  double background_radial_adu = 0, background_vignetting = 0;
  double background_centre_adu = 0;  // the fit's level at the frame centre (median over frames)
  double star_u_mean = 0;            // mean (r / r_corner)^2 of the stars in the flux fit
  double noise_adu = 0;              // median over frames of the detector's noise sigma
};

struct StarPair {
  int frame = 0;  // solved-frame index of the measured set
  double mag = 0;
  double x_measured_px = 0, y_measured_px = 0, x_simulated_px = 0, y_simulated_px = 0;
  double flux_measured_adu = 0, flux_simulated_adu = 0;
  double sigma_measured_px = 0, sigma_simulated_px = 0;  // detector's Gaussian sigma
};

struct FrameComparison {
  FieldFigures measured, simulated;
  std::vector<StarPair> pairs;
  double position_rms_px = 0;         // measured - simulated centroid of the same star
  double flux_ratio_median = 0;       // measured / simulated flux of the same star
  double flux_ratio_scatter_mag = 0;  // robust scatter of 2.5 log10 of that ratio
  int simulated_solved = 0;
  double attitude_error_median_arcsec = 0;  // simulated frames: solved vs drawn attitude
  std::vector<double> attitude_error_arcsec;
};

// The stars to simulate for a camera: the solver's default source for its FOV (widened by the
// focal-length tolerance), down to mag_max, at the catalog epoch (no proper motion applied).
StarCatalog SkyForCamera(const Camera& camera, double fov_tolerance_pct, double mag_max);

// Background structure of one frame: RMS of its tile medians about their median (ADU).
double BackgroundStructureAdu(const ImageView& image, int tile_px);

// The simulator's sky law fitted (least squares) to one frame's tile medians,
// (level + gx dx + gy dy)(1 - v u) = level + gx dx + gy dy + radial u + (gx' dx + gy' dy) u, with (dx, dy)
// from the frame centre to the tile centre (px) and u = (dx^2 + dy^2) / r_corner^2 (r_corner half the
// diagonal): the plane's corner amplitude |gx| (w-1)/2 + |gy| (h-1)/2 (ADU) and direction, the radial
// change centre -> corner (ADU, = -v level) and the RMS of the medians about the fit. ok = false
// below 7 tiles.
struct BackgroundPlane {
  bool ok = false;
  double level_adu = 0, gx_adu_per_px = 0, gy_adu_per_px = 0, radial_adu = 0;
  double amplitude_adu = 0, angle_deg = 0, residual_rms_adu = 0;
};
BackgroundPlane FitBackgroundPlane(const ImageView& image, int tile_px);

// The measured side from a solved set and its images (SolveFrameSet output).
FieldFigures MeasureFieldFigures(const SolvedFrameSet& set, const std::vector<ImageView>& images, const Camera& camera,
                                 int tile_px);

// Simulates every solved frame of `measured` at its solved attitude and compares.
FrameComparison CompareWithSimulation(const SolvedFrameSet& measured, const std::vector<ImageView>& measured_images,
                                      const Camera& camera, const StarCatalog& sky, const StarIdentifier& id,
                                      const SolveOptions& solve, const FrameCompareOptions& options);

// The simulator options that reproduce the measured figures (the extended model): PSF sigma (centre
// and corner when their difference is over 3 standard errors, else the median), ellipticity and angle, V = 0 flux
// (slope held at 1), the background level, gradient and noise. The level goes into the bias except the gradient's
// amplitude, which is sky (background_e_per_s, so that the sky stays >= 0 across the frame); the noise
// into the read noise less that sky's shot noise (a frame alone cannot separate sky shot noise from
// read noise without the gain; base's gain and exposure are taken as the camera's). A background
// vignetting over 0.02 makes the whole centre level sky (bias 0) with that vignetting, which also dims the
// stars: the V = 0 flux is divided by 1 - v star_u_mean.
FrameSimOptions FitSimOptions(const FieldFigures& measured, const FrameSimOptions& base);

Json FrameComparisonToJson(const FrameComparison& c);
Json FieldFiguresToJson(const FieldFigures& f);
Json FrameSimOptionsDiff(const FrameSimOptions& base, const FrameSimOptions& fitted);

// DIR/PREFIX_flux.png (flux vs V, both sides) and DIR/PREFIX_sigma.png (spot sigma vs field radius).
void WriteComparePlots(const std::string& dir, const std::string& prefix, const FrameComparison& c,
                       const Camera& camera, const std::string& title);

}  // namespace ssiu
