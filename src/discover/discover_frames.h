// Model discrepancy of star frames (`ssiu discover frames`, docs/discrepancy.md): solve every frame,
// then compare what the camera model predicts with what was measured, name the cause from the fixed
// vocabulary (conventions.md), fit the extended camera and measure the gain on frames the fit did
// not see.
//
// Geometry: the matched stars' pixel positions against the catalog directions projected with the
// nominal camera. The base model has one small rotation per frame (the solved attitude refined
// with the nominal focal length). Candidates add focal_length (a common scale of fx and fy),
// principal_point (cx, cy), lens_distortion (k1) or pixel_aspect (fy alone: parameters pixel_aspect =
// fy/fx and focal_length_y_px), fitted jointly with the rotations by Gauss-Newton, weighted by the
// centroid sigmas; each is a Wald chi^2 against the base with the variance of the fullest model's
// residuals (stepwise: each candidate against the model of the causes named before it, fitted
// jointly with them). Photometry: vignetting = ln(flux) + 0.4 ln(10) V regressed on (r / r_corner)^2
// (the simulator's law 1 - v (r/r_corner)^2, r about the principal point, r_corner the half
// diagonal). A candidate is significant when p < alpha / m, m the candidates of its step; the lens
// distortion's k2 term is a candidate once k1 is in the model;
// the largest BIC gain among the significant ones that pass the gates enters the model, and the
// search goes on with the causes left until none passes (FrameCauseStep; docs/discrepancy.md).
// Gain: the camera fitted on the even frames is scored on the odd ones (rotations refitted there
// with the camera held) and vice versa; residual RMS with the nominal and with the fitted camera.
//
// psf_shape (needs the model's PSF sigma, FrameDiscoverOptions::psf_sigma_px): an elliptical
// Gaussian, integrated over the pixels, is fitted to a stamp around every isolated matched star
// (FitSpot); its covariance C gives T = (Cxx + Cyy) / 2 and the ellipticity e1 = (Cxx - Cyy) / 2T,
// e2 = Cxy / T. T - sigma_model^2 is regressed on (r / r_corner)^2 (common width and field
// dependence), e1 and e2 are averaged; Wald chi^2 with 4 dof against the model (T = sigma^2, e = 0).
// Gain: stamp residual RMS (in noise sigmas) of held-out frames with the model PSF and with the
// shape fitted on the other frames.
// hot_pixels: the detector's single-pixel spikes, pixel by pixel across the frames. A pixel flagged
// in at least max(2, ceil(N/2)) of N frames persists; the count of such pixels is tested against
// what spikes at random positions (cosmic rays, transient hot pixels) would give (Poisson, with the
// per-pixel rate from the per-frame counts). Gain: spikes in held-out frames not at a pixel found
// on the other frames (i.e. after masking them), before and after.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "core/camera.h"
#include "core/image.h"
#include "core/json.h"
#include "detect/detect.h"

namespace ssiu {

struct FrameStar {
  int frame = 0;
  double x_px = 0, y_px = 0, sigma_px = 0.1, flux = 0, mag = 0;
  double psf_sigma_px = 0;  // fitted Gaussian sigma of the spot (0 if not fitted)
  Vec3 r_inertial = Vec3::UnitZ();
  // Stamp around the star for the PSF analysis: (2 half + 1)^2 pixels from (stamp_x0, stamp_y0),
  // row-major, NaN = left out (a spike); empty when the star is saturated, near the edge or has
  // another source in its stamp.
  int stamp_x0 = 0, stamp_y0 = 0, stamp_half = 0;
  std::vector<float> stamp;
  double noise_adu = 0;    // the frame's background noise
  bool saturated = false;  // its flux is clipped: left out of the photometric residual test
};

// A single-pixel source (the detector's hot_pixel rejection) at an integer pixel.
struct PixelSource {
  int x = 0, y = 0;
  double excess_adu = 0;
};

struct SolvedFrameSet {
  std::vector<std::string> names;
  std::vector<SolveStatus> status;  // per input frame
  std::vector<Quat> q;              // per solved frame (index = FrameStar::frame)
  std::vector<int> solved_index;    // input frame of each solved frame
  std::vector<FrameStar> stars;
  std::vector<double> background_adu, noise_adu;  // per solved frame (detector's tile medians)
  int width = 0, height = 0;
  std::vector<std::vector<PixelSource>> spikes;  // per input frame (solved or not)
};

// Solves each image (SolveFrame, with the known defects repaired when given) and collects the
// identified stars, their stamps and every frame's single-pixel spikes.
SolvedFrameSet SolveFrameSet(const StarIdentifier& id, const std::vector<ImageView>& images,
                             const std::vector<std::string>& names, const Camera& camera, const SolveOptions& options,
                             const DefectMap* known_defects = nullptr);

// Fit of A * (pixel-integrated 2-D Gaussian of covariance C centred at (x, y)) + background to a
// stamp (FrameStar layout: row-major, NaN left out; coordinates relative to the stamp's pixel 0).
// fixed_c (cxx, cyy, cxy) non-null: the shape is held and only flux, position and background fit.
struct SpotFit {
  bool ok = false;
  double x_px = 0, y_px = 0, flux_adu = 0, background_adu = 0;
  double cxx = 0, cyy = 0, cxy = 0;          // px^2 (the PSF's, before pixel integration)
  double t_px2 = 0, e1 = 0, e2 = 0;          // (cxx + cyy) / 2, (cxx - cyy) / 2t, cxy / t
  double t_var = 0, e1_var = 0, e2_var = 0;  // formal variances (residual scale)
  double rss_adu2 = 0;
  int n = 0;
};
SpotFit FitSpot(const std::vector<float>& stamp, int half, double x_guess, double y_guess, double sigma_guess_px,
                const double* fixed_c = nullptr);

struct FrameDiscoverOptions {
  double alpha = 0.01;         // family-wise false-alarm probability over the candidates
  int iterations = 6;          // Gauss-Newton iterations
  double min_sigma_px = 0.05;  // floor of the centroid sigma used as weight
  // The model's PSF sigma (px; camera.json "psf_sigma_px" or --psf-sigma-px); 0 = psf_shape not tested.
  double psf_sigma_px = 0;
  // The model's PSF ellipticity (1 - minor/major) and major-axis angle from +x towards +y (deg);
  // camera.json "psf_ellipticity" / "psf_angle_deg", as written into fitted_camera by psf_shape.
  double psf_ellipticity = 0, psf_angle_deg = 0;
  // The model's vignetting (camera.json "vignetting", flux factor 1 - v (r / r_corner)^2): the
  // vignetting cause tests what is left beyond it, and its parameter is the whole law's v.
  double vignetting = 0;
  // The model's known hot pixels [x, y] (camera.json "hot_pixels"): the caller repairs them before
  // detection (SolveFrameSet's defect map); fitted_camera carries them with those found.
  std::vector<std::array<int, 2>> hot_pixels;
  // Model tolerance added in quadrature to the sigma of the mean width and ellipticity (the stamp
  // fit's own systematic floor), so that thousands of stars do not call a 1 % departure a cause.
  double psf_width_floor_pct = 1.0;
  double psf_ellipticity_floor = 0.01;
  // Gates (docs/discrepancy.md): a candidate is named only when its parameters lie within the
  // physical bounds and its held-out improvement is significant at gain_alpha (one-sided).
  double gain_alpha = 0.01;
  // `unexplained`: after every cause of the vocabulary is fitted, the star position residuals (a map
  // over the focal plane) and the photometric residuals are tested for structure (F tests of a
  // cubic field, of cell means and of a magnitude dependence); family-wise false-alarm probability.
  double residual_alpha = 0.01;
  int residual_min_stars_per_cell = 8;  // the grid of the cell-mean tests: 2x2 .. 4x4 cells
  void Check() const;
};

struct FrameCandidate {
  std::string cause;
  std::string term;  // a further term of a cause already in the model (lens_distortion: "k2"), else empty
  double statistic = 0, p_value = 1, delta_bic = 0;
  int dof = 0;
  bool significant = false;
  // Gates, for the significant candidates tried in BIC order until one passes.
  bool evaluated = false;
  double gain = 0, gain_z = 0;  // held-out gain and the z of the held-out improvement (0: not defined)
  std::string verdict;          // "named", "held-out gain not significant", "outside bounds: ..."
};

// One residual test of `unexplained`: F test of `dof` extra columns against the fitted model.
struct FrameResidualTest {
  std::string name;  // position_polynomial, position_cells, position_magnitude, photometry_*
  double f = 0, p_value = 1;
  int dof = 0, dof_resid = 0;
  bool tested = false;
};

// The residual after every cause of the vocabulary is fitted, against the noise (the scatter the
// extra columns do not explain).
struct FrameResidual {
  bool structured = false;
  double p_value = 1;   // family-wise (Bonferroni over the tests run)
  std::string finding;  // the most significant test
  std::vector<FrameResidualTest> tests;
  // The structure of the most significant position test (the fitted extra field, px) and photometric
  // test (mag): RMS over the stars, the largest, where (pixel of that star) and its direction.
  double position_rms_px = 0, position_rms_arcsec = 0, position_max_px = 0, position_max_arcsec = 0;
  double position_max_x_px = 0, position_max_y_px = 0, position_max_angle_deg = 0;
  double position_per_mag_px = 0;  // magnitude test: largest shift per magnitude (px/mag)
  double photometry_rms_mag = 0, photometry_max_mag = 0, photometry_max_x_px = 0, photometry_max_y_px = 0;
  double photometry_per_mag = 0;  // magnitude test: slope of the flux residual (mag per mag)
  // The cell of the largest mean position residual (cells test): its centre, stars, mean (px) and chi^2.
  double cell_x_px = 0, cell_y_px = 0, cell_dx_px = 0, cell_dy_px = 0, cell_chi2 = 0;
  int cell_stars = 0, grid = 0;
};

// One cause of the extended model, in the order the causes entered: its parameters and 1-sigmas from
// the final joint fit of every named cause, and what it gained at the step it entered.
struct FrameCauseStep {
  std::string cause;
  int step = 0;
  std::map<std::string, double> parameters, sigmas;
  std::vector<std::string> terms;     // further terms that entered at later steps (lens_distortion: k2)
  double statistic = 0, p_value = 1;  // its test against the model of the step before
  double gain = 1, gain_z = 0;        // held-out gain over that model and the z of the improvement
  // The held-out figure before and after the step in the cause's unit (position RMS px for geometric
  // causes; flux RMS mag for vignetting; stamp RMS in noise sigmas for psf_shape; spikes per frame for
  // hot_pixels) and the model's held-out position RMS after the step (arcsec).
  double held_out_before = 0, held_out_after = 0, residual_rms_arcsec = 0;
};

// A cause (or a further term of one) that entered the model and left it again in the backward check:
// with the causes that entered after it, it no longer added significantly (p_value).
struct RemovedCause {
  std::string cause, term;
  double p_value = 1;
};

// The correlation of two camera parameters of the named causes in the final joint fit.
struct ParameterCorrelation {
  std::string a, b;
  double r = 0;
};

struct FrameDiscovery {
  // The first cause named (or none / unexplained); `causes` holds them all in the order they entered,
  // and `parameters` / `sigmas` the parameters of all of them from the final joint fit.
  std::string cause = "none";
  std::map<std::string, double> parameters, sigmas;
  Camera fitted_camera;
  // fitted_camera's fields beyond the geometry: the model's PSF, vignetting and known hot pixels,
  // replaced or extended by the named causes; written into the JSON's fitted_camera.
  CameraExtras fitted_camera_extras;
  // Held-out position RMS of the base and of the final model; the first cause's held-out gain.
  double residual_rms_before_arcsec = 0, residual_rms_after_arcsec = 0, gain = 1;
  double flux_rms_before_mag = 0, flux_rms_after_mag = 0;                          // vignetting only
  double stamp_rms_before = 0, stamp_rms_after = 0;  // psf_shape: held-out stamp residual, noise sigmas
  double spikes_before = 0, spikes_after = 0;        // hot_pixels: held-out spikes per frame
  std::vector<PixelSource> hot_pixels;               // persistent pixels (excess: median over frames)
  std::vector<int> hot_pixel_frames;                 // in how many frames each was flagged
  std::vector<std::string> not_tested;
  std::vector<FrameCandidate> candidates;  // the first step's candidates (each against the base)
  std::vector<FrameCauseStep> causes;
  std::vector<std::vector<FrameCandidate>> steps;  // every step's candidates against its model
  std::vector<ParameterCorrelation> correlations;
  std::vector<RemovedCause> removed;
  double gain_z = 0, gain_z_min = 0;  // the first cause's held-out z and the gate on it
  // `unexplained`: the cause that was named before the residual test found structure left.
  std::string partial_cause;
  FrameResidual residual;
  int frames = 0, frames_solved = 0, stars = 0;
  // Measured figures to compare with the simulator (docs/discrepancy.md): flux of a V = 0 star
  // (ADU, geometric mean over the stars), the scatter of flux about it (mag), median spot sigma,
  // background and noise (ADU, medians over frames).
  double zero_point_adu = 0, photometric_scatter_mag = 0, psf_sigma_median_px = 0;
  double psf_sigma_fit_px = 0, psf_e1 = 0, psf_e2 = 0;  // stamp fits (mean), whether or not a cause
  int psf_stars = 0;
  double background_median_adu = 0, noise_median_adu = 0;
  // Per star, for the quiver plot: position and residual (measured - model, px) before and after.
  std::vector<double> x_px, y_px, dx_before_px, dy_before_px, dx_after_px, dy_after_px;
};

FrameDiscovery DiscoverFrames(const SolvedFrameSet& set, const Camera& camera, const FrameDiscoverOptions& options);

Json FrameDiscoveryToJson(const FrameDiscovery& d);

// DIR/residuals_before.png and DIR/residuals_after.png: residual vectors across the field.
void WriteResidualQuiver(const std::string& dir, const FrameDiscovery& d, const Camera& camera);

}  // namespace ssiu
