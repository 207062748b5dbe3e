// Star-frame simulator: a camera, a star catalog and an attitude -> a 16-bit CCD frame plus the
// truth (every star drawn, every artefact injected). Every effect can be switched off or given a
// strength, because later stages hide effects in data and must find them. Deterministic per seed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/astrometry.h"
#include "core/camera.h"
#include "core/catalog.h"
#include "core/image.h"
#include "core/json.h"
#include "core/types.h"

namespace ssiu {

struct FrameSimOptions {
  // Optics and photometry
  double psf_sigma_px = 1.2;  // Gaussian PSF sigma (pixel-integrated)
  // PSF options are in pixels of the frame: with non-square pixels (camera focal_length_y_px) a round
  // optical PSF is an ellipse, psf_ellipticity = 1 - min(fx, fy) / max(fx, fy), psf_angle_deg 0 when fy < fx.
  double defocus_radius_px = 0.0;  // > 0: PSF = uniform disk of this radius convolved with the Gaussian
  // Elliptical PSF: 1 - minor/major axis (of the Gaussian's sigmas; camera.json "psf_ellipticity" as
  // `ssiu discover frames` psf_shape writes it), major axis at psf_angle_deg from +x towards +y. The
  // mean variance (a^2 + b^2) / 2 stays sigma^2 (FitSpot's T). 0 = round.
  double psf_ellipticity = 0.0;
  double psf_angle_deg = 0.0;
  // Field-dependent width: sigma(r) = psf_sigma_px + (corner - psf_sigma_px) (r / r_corner)^2, r from
  // the principal point, r_corner = half the frame diagonal; 0 = psf_sigma_px everywhere.
  double psf_sigma_corner_px = 0.0;
  double exposure_s = 0.1;
  // Motion during the exposure: the sensor's angular rate relative to inertial space, in sensor axes
  // (deg/s). Each star (and false star) is smeared along the path it projects to over
  // [-exposure/2, +exposure/2] around the attitude given (mid-exposure); 0 = a still frame.
  double rate_x_dps = 0.0, rate_y_dps = 0.0, rate_z_dps = 0.0;
  // Time and motion (docs/simulator.md): with time_utc (ISO 8601 UTC, mid-exposure) set, stars are
  // drawn at their apparent directions at that time: proper motion from the catalog's epoch
  // (StarCatalog::epoch_year) when proper_motion, stellar aberration when aberration (the Earth's
  // barycentric velocity plus velocity_*_kms, the spacecraft's velocity relative to the Earth, ICRS).
  // "" = the catalog directions as they are (no time, no motion).
  std::string time_utc;
  bool proper_motion = true;
  bool aberration = true;
  double velocity_x_kms = 0.0, velocity_y_kms = 0.0, velocity_z_kms = 0.0;
  double mag0_flux_e_per_s = 5.0e6;  // photo-electrons per second from a V = 0 star (aperture, QE)
  double mag_max = 7.5;              // faintest catalog star drawn (SNR about 10 there)
  double vignetting = 0.0;           // flux factor 1 - vignetting * (r / r_corner)^2
  // Detector
  double background_e_per_s = 1000.0;  // sky + stray light, per pixel
  // Linear sky gradient: the sky at the frame's corners differs from the centre's by up to +-this
  // (the corner furthest along background_gradient_angle_deg, from +x towards +y, gets +this); the
  // sky is clipped at 0 where the gradient would make it negative.
  double background_gradient_e_per_s = 0.0;
  double background_gradient_angle_deg = 0.0;
  double dark_current_e_per_s = 50.0;  // per pixel
  double read_noise_e = 10.0;
  double gain_e_per_adu = 0.5;
  double bias_adu = 200.0;
  double full_well_e = 40000.0;  // above the ADC range at this gain: saturation is at 65535 ADU
  int bit_depth = 16;
  bool shot_noise = true;
  // Defects and interferers
  int defect_seed = 1;  // hot/dead pixel positions and rates: a property of the sensor,
                        // the same in every frame of one camera (unlike the noise seed)
  int hot_pixels = 40;
  double hot_pixel_min_e_per_s = 2.0e3;  // hot pixel dark rates, log-uniform in [min, max]
  double hot_pixel_max_e_per_s = 2.0e5;
  int dead_pixels = 5;
  int cosmic_rays = 3;
  double cosmic_ray_e_per_px = 3000.0;  // deposited charge per pixel of track (mean)
  double cosmic_ray_max_length_px = 12.0;
  int streaks = 0;  // satellite streaks
  double streak_flux_e_per_px = 400.0;
  int false_stars = 0;  // point sources not in the catalog (planets, unknown objects)

  void Check() const;  // throws InputError naming the field
};

// Reads options from a JSON object (keys as the field names above); unknown keys are an error.
FrameSimOptions FrameSimOptionsFromJson(const Json& j, const std::string& source);
Json FrameSimOptionsToJson(const FrameSimOptions& o);
// The numeric options by name (the JSON keys), for command-line flags; Set throws InputError on an
// unknown name or a non-whole value for a count.
std::vector<std::string> FrameSimOptionNames();
void SetFrameSimOption(FrameSimOptions* o, const std::string& name, double value);

struct SimStar {
  StarId star_id = kInvalidStarId;  // kInvalidStarId for an injected false star
  double mag = 0;
  double x_px = 0, y_px = 0;        // true (distorted) position at mid-exposure
  double smear_px = 0;              // length of the image's path during the exposure (0 when still)
  double flux_e = 0, flux_adu = 0;  // total signal in the exposure
  double snr = 0;                   // ideal SNR of the flux in a PSF-matched aperture
  bool saturated = false;
};

struct SimArtefact {
  std::string type;                                   // hot_pixel, dead_pixel, cosmic_ray, streak
  double x_px = 0, y_px = 0;                          // position (midpoint for tracks)
  double x0_px = 0, y0_px = 0, x1_px = 0, y1_px = 0;  // track ends (tracks only)
  double signal_e = 0;                                // hot pixel dark charge, track charge
};

struct SimulatedFrame {
  Image16 image;
  Quat q_inertial_from_sensor = Quat::Identity();
  uint64_t seed = 0;
  double noise_adu = 0;        // the background's per-pixel noise sigma (ADU), for checks
  std::vector<SimStar> stars;  // every star drawn on the frame
  std::vector<SimArtefact> artefacts;
};

SimulatedFrame SimulateFrame(const Camera& camera, const StarCatalog& catalog, const Quat& q_inertial_from_sensor,
                             const FrameSimOptions& options, uint64_t seed);

// The time and motion the options render (core/astrometry.h): inactive without time_utc.
SkyCorrections SkyForSimulation(const FrameSimOptions& o);

// A random attitude (uniform over rotations) from a seed.
Quat RandomAttitude(uint64_t seed);

// The truth JSON of a simulated frame (the simulator's output contract).
Json TruthToJson(const SimulatedFrame& frame, const Camera& camera, const FrameSimOptions& options);

}  // namespace ssiu
