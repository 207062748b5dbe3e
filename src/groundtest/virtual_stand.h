// The virtual test stand (`ssiu groundtest simulate`): what the tracker sees of the mask through the
// collimator (finite holes, defocused PSF, stray light, detector noise) for a sequence of stand
// positions with a hidden stand-to-tracker misalignment and encoder noise, and the auxiliary
// camera's photo of the plate's fiducials.
//
//   StandSimulation s = SimulateStand(mask, StandSimOptions{}, seed);
//   // s.pictures[i].frame -> Detect/SolveFrame; s.pictures[i].photo -> reference.h; s.truth ...
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/image.h"
#include "core/json.h"
#include "groundtest/mask.h"
#include "groundtest/stand.h"
#include "sim/frame_sim.h"

namespace ssiu {

// Photometry and detector of the tracker view: FrameSimOptions' optics, photometry and detector
// fields (psf_sigma_px, defocus_radius_px, exposure_s, mag0_flux_e_per_s, background_e_per_s,
// dark_current_e_per_s, read_noise_e, gain_e_per_adu, bias_adu, full_well_e, bit_depth, shot_noise);
// its defect and interferer fields are not used (the stand has no sky).
struct TrackerViewOptions {
  FrameSimOptions detector = [] {
    FrameSimOptions d;
    d.defocus_radius_px = 1.5;  // a collimator test is rarely at perfect focus
    return d;
  }();
  double stray_gradient = 0.5;                   // stray light: background * (1 + g * x / half-width), linear
  double stray_glow_e_per_s = 3000.0;            // plus a broad glow (Gaussian, sigma = 1/3 of the frame) ...
  double glow_x_frac = 0.2, glow_y_frac = -0.3;  // ... centred at this offset (fraction of the half size)
  void Check() const;
};

// What the tracker at attitude q_C_from_S sees of the plate at `pose`. Each hole is a uniform disk of
// angular radius (d/2)/F convolved with the defocus disk and the Gaussian PSF; flux from the hole's
// effective magnitude. `stars_in_view` (optional) receives the true pixel positions.
struct ViewStar {
  StarId star_id = kInvalidStarId;
  double x_px = 0, y_px = 0, radius_px = 0, flux_e = 0;
};
Image16 RenderTrackerView(const Mask& m, const PlatePose& pose, const Quat& q_c_from_s, const TrackerViewOptions& o,
                          uint64_t seed, std::vector<ViewStar>* stars_in_view = nullptr);

// The auxiliary camera: a calibrated camera looking at the plate's lens-side face; X_aux = R X_C + t
// (default: 600 mm from the plate centre, 15 deg off the collimator axis).
struct AuxCamera {
  Camera camera = MakeCamera(1280, 960, 40.0);
  Mat3 r_aux_from_c = Eigen::AngleAxisd(-15.0 * kDegToRad, Vec3::UnitY()).toRotationMatrix();  // 15 deg oblique
  Vec3 t_aux_mm = Vec3(0, 0, 600.0);
};
Json AuxCameraToJson(const AuxCamera& a);
AuxCamera AuxCameraFromJson(const Json& j, const std::string& source);
AuxCamera LoadAuxCamera(const std::string& path);

struct PhotoOptions {
  double noise_dn = 2.0;  // Gaussian pixel noise (8-bit counts)
  // Optical blur sigma. libapriltag's edge refinement samples the gradient +/-1 px across an edge:
  // on sharp photos its corners are biased by up to 0.1 px (measured, 8 tags: -0.11 px at 0 blur,
  // -0.04 at 0.7, < 0.01 at 1.5), which turns into a plate shift of ~10 arcsec. Take the photos
  // slightly defocused; 1.5 px is the default here.
  double blur_px = 1.5;
  int supersample = 3;     // rendered at this many times the resolution per axis, blurred, box-averaged
  std::string tag_family;  // "" = the mask's; another family draws the wrong tags (tests)
  bool hide_tags = false;  // draw the plate without fiducials (tests)
  void Check() const;
};
// 8-bit photo of the plate (at `pose`) by the auxiliary camera: AddPhotoNoise(RenderAuxScene(...)).
std::vector<uint8_t> RenderAuxPhoto(const Mask& m, const PlatePose& pose, const AuxCamera& aux, const PhotoOptions& o,
                                    uint64_t seed);
// The photo before its noise: the blurred scene integrated over each pixel, in counts (row-major, the aux
// camera's size; `seed` jitters the samples across edges). A plate that does not move in the camera (the
// stand's pictures) is rendered once and each picture's noise drawn on it.
std::vector<float> RenderAuxScene(const Mask& m, const PlatePose& pose, const AuxCamera& aux, const PhotoOptions& o,
                                  uint64_t seed);
// Gaussian pixel noise (o.noise_dn, drawn from `seed`) on a scene, rounded and clamped to 8 bits.
std::vector<uint8_t> AddPhotoNoise(const std::vector<float>& scene, const PhotoOptions& o, uint64_t seed);

struct StandSimOptions {
  int positions = 6;                                // stand positions (pictures)
  double step_s = 60.0;                             // time between pictures
  double max_angle_deg = 1.5;                       // stand az/el spread (uniform within +/-), roll up to 3x that
  // A slow slew instead of random positions: the stand steps evenly from (-max, -max/2) to (+max,
  // +max/2) deg in az/el, no roll, so that the mask's stars cross the field (the sequence of
  // `ssiu performance`, ECSS-E-ST-60-20C's FOV and pixel spatial errors: docs/standards.md).
  bool slew = false;
  Vec3 misalignment_arcmin = Vec3(3.0, -2.0, 4.0);  // hidden q_mis rotation vector (sensor axes)
  double encoder_sigma_arcsec = 2.0;                // encoder read-out noise per axis
  double plate_shift_mm = 0.05;                     // plate displacement in its holder (x, y), fixed
  double plate_turn_deg = 0.05;                     // plate in-plane turn, fixed
  TrackerViewOptions view;
  AuxCamera aux;
  PhotoOptions photo;
  void Check() const;
};

struct StandPicture {
  double t_s = 0;
  double az_deg = 0, el_deg = 0, rot_deg = 0;              // true stand angles
  double enc_az_deg = 0, enc_el_deg = 0, enc_rot_deg = 0;  // as the encoders read them
  Quat q_c_from_s = Quat::Identity();
  Quat q_true = Quat::Identity();  // what an ideal tracker reports (inertial <- S)
  Image16 frame;
  std::vector<ViewStar> stars;
  std::vector<uint8_t> photo;
};

struct StandSimulation {
  Quat q_mis = Quat::Identity();
  PlatePose plate;
  Quat q_c_from_m = Quat::Identity();
  std::vector<StandPicture> pictures;
  Json TruthJson(const Mask& m) const;
};

StandSimulation SimulateStand(const Mask& m, const StandSimOptions& o, uint64_t seed);

}  // namespace ssiu
