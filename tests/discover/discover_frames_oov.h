// Synthetic solved frame sets for the `unexplained` test of `ssiu discover frames` (issue 18): the
// stars' measured pixels and fluxes are drawn by the test from catalog-like directions seen through a
// "true" camera plus one hidden effect, with honest centroid sigmas and photometric noise (no images:
// fast enough for CI). Effects inside the vocabulary (focal_length, principal_point,
// lens_distortion, pixel_aspect, vignetting), none, and effects outside it that no cause models:
//   bump        a local distortion: a Gaussian displacement (sigma 90-130 px, 0.4-0.8 px) in one quadrant
//   twist       a tangential field t r^2 (rotation growing with radius), 0.5-1 px at the corners
//   cti         a magnitude-dependent centroid shift along y growing with y (charge transfer), 0.06-0.12 px/mag
//               at the bottom edge
//   stitch      a sensor stitched from two halves: the stars right of the middle shifted 0.2-0.4 px along y
//   gradient    a photometric falloff linear across x (illumination), 15-30 % edge to edge
//   nonlinear   a detector response flux^(1 - g), g 0.04-0.08: faint stars too bright by 0.04-0.08 mag per mag
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "core/attitude.h"
#include "core/rng.h"
#include "discover/discover_frames.h"
#include "discover_frames_mc.h"

namespace ssiu::testing {

inline const std::vector<std::string>& OutOfVocabularyFrameEffects() {
  static const std::vector<std::string> k = {"bump", "twist", "cti", "stitch", "gradient", "nonlinear"};
  return k;
}
inline const std::vector<std::string>& SyntheticFrameCauses() {
  static const std::vector<std::string> k = {"none",         "focal_length", "principal_point", "lens_distortion",
                                             "pixel_aspect", "vignetting"};
  return k;
}

struct SyntheticFrameSet {
  Camera nominal;
  SolvedFrameSet set;
  std::string effect;
  double bump_x_px = 0, bump_y_px = 0;  // bump: the centre of the displacement
};

inline SyntheticFrameSet MakeSyntheticFrameSet(const std::string& effect, uint64_t seed, int frames = 4,
                                               int stars = 45) {
  Rng rng(seed);
  SyntheticFrameSet out;
  out.effect = effect;
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  out.nominal = cam;
  Camera truth = cam;
  auto sign = [&] { return rng.Uniform() < 0.5 ? -1.0 : 1.0; };
  if (effect == "focal_length") truth.focal_length_px *= 1 + sign() * rng.Uniform(500, 1500) * 1e-6;
  if (effect == "principal_point")
    truth.cx_px += sign() * rng.Uniform(5, 15), truth.cy_px += sign() * rng.Uniform(5, 15);
  if (effect == "lens_distortion") truth.distortion.k1 = sign() * rng.Uniform(0.02, 0.06);
  if (effect == "pixel_aspect")
    truth.focal_length_y_px = truth.focal_length_px * (1 + sign() * rng.Uniform(1000, 2500) * 1e-6);
  const double vignetting = effect == "vignetting" ? rng.Uniform(0.2, 0.4) : 0.0;
  // Out-of-vocabulary effects.
  const double bump_x = (rng.Uniform() < 0.5 ? 0.25 : 0.75) * cam.width,
               bump_y = (rng.Uniform() < 0.5 ? 0.25 : 0.75) * cam.height;
  const double bump_s = rng.Uniform(90, 130), bump_a = rng.Uniform(0.4, 0.8), bump_dir = rng.Uniform(0, 2 * kPi);
  const double twist = sign() * rng.Uniform(0.5, 1.0);  // px at the corner
  const double cti = rng.Uniform(0.06, 0.12);           // px per mag at the bottom edge
  const double stitch = sign() * rng.Uniform(0.2, 0.4);
  const double grad = sign() * rng.Uniform(0.15, 0.30), gamma = rng.Uniform(0.04, 0.08);
  out.bump_x_px = bump_x, out.bump_y_px = bump_y;
  const double half_diag = 0.5 * std::hypot(cam.width, cam.height);
  const double mag0 = 3.0;
  out.set.width = cam.width, out.set.height = cam.height;
  for (int f = 0; f < frames; ++f) {
    const Quat q = RandomAttitude(seed * 1000 + f);
    AddSolvedFrame(&out.set, q);
    for (int i = 0; i < stars; ++i) {
      FrameStar s;
      s.frame = f;
      const double y_draw = rng.Uniform(10, cam.height - 11);  // y first: argument order is the compiler's
      s.r_inertial = q * cam.Unproject(Vec2(rng.Uniform(10, cam.width - 11), y_draw));
      const Vec3 v = q.conjugate() * s.r_inertial;
      const auto p = truth.Project(v);
      if (!p || !cam.InImage(*p, -5)) continue;
      s.mag = mag0 + 3.5 * std::pow(rng.Uniform(), 0.6);  // more faint stars than bright ones
      // Centroid sigma: 0.03 px for the brightest, growing as the flux falls (photon and read noise).
      s.sigma_px = 0.03 * std::sqrt(1 + std::pow(10, 0.4 * (s.mag - mag0)));
      double x = p->x(), y = p->y();
      const double a = (x - cam.cx_px) / half_diag, b = (y - cam.cy_px) / half_diag;
      if (effect == "bump") {
        const double g =
            bump_a * std::exp(-0.5 * (std::pow(x - bump_x, 2) + std::pow(y - bump_y, 2)) / (bump_s * bump_s));
        x += g * std::cos(bump_dir), y += g * std::sin(bump_dir);
      }
      if (effect == "twist") {
        const double r2 = a * a + b * b;
        x += -twist * b * r2, y += twist * a * r2;
      }
      if (effect == "stitch" && x > cam.cx_px) y += stitch;
      if (effect == "cti") y += cti * (s.mag - mag0) * (y / cam.height);
      s.x_px = x + s.sigma_px * rng.Normal();
      s.y_px = y + s.sigma_px * rng.Normal();
      // Flux: 1e6 ADU at V = 0, 0.02 mag of scatter for the brightest growing to 0.08 mag.
      double ln_flux = std::log(1e6) - 0.4 * std::log(10.0) * s.mag;
      const double u =
          (std::pow(x - cam.cx_px, 2) + std::pow(y - cam.cy_px, 2)) / (std::pow(cam.cx_px, 2) + std::pow(cam.cy_px, 2));
      if (vignetting > 0) ln_flux += std::log(1 - vignetting * u);
      if (effect == "gradient") ln_flux += std::log(1 + grad * (x - cam.cx_px) / cam.width);
      if (effect == "nonlinear") ln_flux *= 1 - gamma;
      const double sigma_mag = 0.02 * std::sqrt(1 + 15 * std::pow(10, 0.4 * (s.mag - mag0 - 3.5)));
      s.flux = std::exp(ln_flux + sigma_mag * 0.4 * std::log(10.0) * rng.Normal());
      s.noise_adu = 28;
      out.set.stars.push_back(s);
    }
  }
  return out;
}

struct OovSummary {
  int sets = 0, right = 0, unexplained = 0, wrong = 0, none = 0;
};

// n sets of each effect in `effects`; `right` counts the expected answer (the cause itself inside
// the vocabulary, `unexplained` outside), `wrong` a cause of the vocabulary named for another.
inline std::map<std::string, OovSummary> RunSyntheticFrames(const std::vector<std::string>& effects, int n,
                                                            uint64_t seed0, bool verbose, int frames = 4,
                                                            int stars = 45) {
  std::map<std::string, OovSummary> out;
  for (int k = 0; k < n; ++k) {
    for (size_t e = 0; e < effects.size(); ++e) {
      const std::string& effect = effects[e];
      const SyntheticFrameSet c = MakeSyntheticFrameSet(effect, seed0 + 1000 * k + e, frames, stars);
      const FrameDiscovery d = DiscoverFrames(c.set, c.nominal, FrameDiscoverOptions{});
      const bool inside = std::find(SyntheticFrameCauses().begin(), SyntheticFrameCauses().end(), effect) !=
                          SyntheticFrameCauses().end();
      OovSummary& s = out[effect];
      ++s.sets;
      s.right += inside ? d.cause == effect : d.cause == "unexplained";
      s.unexplained += d.cause == "unexplained";
      s.none += d.cause == "none";
      s.wrong += d.cause != "none" && d.cause != "unexplained" && d.cause != effect;
      if (verbose) {
        std::printf(
            "%-16s found %-16s partial %-16s residual p %.2g (%s) pos rms %.3f px max %.3f px at (%.0f, %.0f); "
            "cell (%.0f, %.0f) (%.3f, %.3f) px; per mag %.3f px; phot rms %.3f mag, per mag %.3f\n",
            effect.c_str(), d.cause.c_str(), d.partial_cause.c_str(), d.residual.p_value, d.residual.finding.c_str(),
            d.residual.position_rms_px, d.residual.position_max_px, d.residual.position_max_x_px,
            d.residual.position_max_y_px, d.residual.cell_x_px, d.residual.cell_y_px, d.residual.cell_dx_px,
            d.residual.cell_dy_px, d.residual.position_per_mag_px, d.residual.photometry_rms_mag,
            d.residual.photometry_per_mag);
      }
    }
  }
  return out;
}

}  // namespace ssiu::testing
