// Real frames against ssiu's frame simulator, star by star (`ssiu discover frames --compare-sim`,
// docs/discrepancy.md): every solved frame is simulated at its solved attitude with the same camera,
// the simulated frames go through the same solve, and the two sides are compared: positions of the
// same catalog star, flux against catalog magnitude (zero point, slope, scatter), PSF width and
// shape (FitSpot), background level and structure, noise, solve rate and attitude error.
//
// FitSimOptions gives the extended simulator model: the measured PSF sigma, zero point, background
// level and noise put into FrameSimOptions, so that a second comparison shows the gain.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "analysis/discover_frames.h"
#include "attitude/star_solver.h"
#include "core/camera.h"
#include "core/catalog.h"
#include "core/image.h"
#include "core/json.h"
#include "sim/frame_sim.h"

namespace ssiu {

struct FrameCompareOptions {
  FrameSimOptions sim;      // the simulator model under test
  uint64_t seed = 1;        // noise seed of the first simulated frame (frame k: seed + k)
  int tile_px = 64;         // background structure: medians of tiles of this size
  double match_radius_px = 3;  // a simulated and a measured star are the same star within this
  void Check() const;       // InputError naming the field
};

// The figures of one side (measured or simulated), by the same pipeline.
struct FieldFigures {
  int frames = 0, frames_solved = 0, stars = 0;
  // ln(flux) = ln(zero_point) - 0.4 ln(10) slope V: zero_point = flux of a V = 0 star (ADU), slope 1
  // for a linear sensor in the catalog's band; scatter about the line (mag).
  double zero_point_adu = 0, flux_slope = 0, flux_scatter_mag = 0;
  double zero_point_slope1_adu = 0;  // the same with the slope held at 1 (the simulator's law)
  double psf_sigma_px = 0, psf_e1 = 0, psf_e2 = 0;  // stamp fits (FitSpot), mean
  int psf_stars = 0;
  double background_adu = 0;            // median over frames of the detector's background
  double background_structure_adu = 0;  // RMS of the tile medians about their frame's median
  double noise_adu = 0;                 // median over frames of the detector's noise sigma
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
  double position_rms_px = 0;        // measured - simulated centroid of the same star
  double flux_ratio_median = 0;      // measured / simulated flux of the same star
  double flux_ratio_scatter_mag = 0; // robust scatter of 2.5 log10 of that ratio
  int simulated_solved = 0;
  double attitude_error_median_arcsec = 0;  // simulated frames: solved vs drawn attitude
  std::vector<double> attitude_error_arcsec;
};

// The stars to simulate for a camera: the solver's default source for its FOV (widened by the
// focal-length tolerance), down to mag_max, at the catalog epoch (no proper motion applied).
StarCatalog SkyForCamera(const Camera& camera, double fov_tolerance_pct, double mag_max);

// Background structure of one frame: RMS of its tile medians about their median (ADU).
double BackgroundStructureAdu(const ImageView& image, int tile_px);

// The measured side from a solved set and its images (SolveFrameSet output).
FieldFigures MeasureFieldFigures(const SolvedFrameSet& set, const std::vector<ImageView>& images, const Camera& camera,
                                 int tile_px);

// Simulates every solved frame of `measured` at its solved attitude and compares.
FrameComparison CompareWithSimulation(const SolvedFrameSet& measured, const std::vector<ImageView>& measured_images,
                                      const Camera& camera, const StarCatalog& sky, const StarIdentifier& id,
                                      const SolveOptions& solve, const FrameCompareOptions& options);

// The simulator options that reproduce the measured figures (the extended model): PSF sigma, V = 0
// flux (slope held at 1), and the background level and noise (the level as bias, the noise as read noise: a frame
// alone cannot separate sky shot noise from read noise without the gain).
FrameSimOptions FitSimOptions(const FieldFigures& measured, const FrameSimOptions& base);

Json FrameComparisonToJson(const FrameComparison& c);
Json FieldFiguresToJson(const FieldFigures& f);
Json FrameSimOptionsDiff(const FrameSimOptions& base, const FrameSimOptions& fitted);

// DIR/PREFIX_flux.png (flux vs V, both sides) and DIR/PREFIX_sigma.png (spot sigma vs field radius).
void WriteComparePlots(const std::string& dir, const std::string& prefix, const FrameComparison& c,
                       const Camera& camera, const std::string& title);

}  // namespace ssiu
