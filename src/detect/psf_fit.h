// Internal to detect: sub-pixel centroid of one source by a weighted least-squares fit of a
// pixel-integrated circular Gaussian plus a local constant background.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "core/arena.h"
#include "core/image.h"

namespace ssiu {

struct PsfFitOptions {
  double sigma_guess_px = 1.2;
  double gain_e_per_adu = 0;  // > 0: shot noise enters the weights (then the fit is ~ML)
  double saturation_adu = 65535;
  bool fit = true;          // false: weighted moments only
  int max_iterations = 12;  // converged fits take 3-6; noise blobs would wander on
  // Expected motion smear (end minus start of the star's image over the exposure, px). Nonzero: the
  // model is the Gaussian averaged along that segment centred on (x, y), the window grows by the
  // smear, and elongation is measured against the smeared model's own shape (1 = as predicted).
  double smear_dx_px = 0, smear_dy_px = 0;
  // Largest half-size of the window (r plus the smear) in each axis; 0 = no limit. A larger window is
  // cut to it (PsfFit::window_clamped): the scratch's room.
  int max_half_px = 0;
};

struct PsfFit {
  bool ok = false;
  double x_px = 0, y_px = 0;
  double flux_adu = 0, background_adu = 0, sigma_px = 0;
  double snr = 0;
  double x_sigma_px = 0, y_sigma_px = 0;
  double elongation = 1;  // sqrt of the ratio of the second-moment eigenvalues
  double major_sigma_px = 0;
  int iterations = 0;
  bool window_clamped = false;  // the window was cut to PsfFitOptions::max_half_px
};

// A non-owning reference to a pixel test bool(int x, int y) (std::function may allocate; this never
// does). The callable must outlive the call it is passed to.
class PixelTest {
 public:
  template <class F>
  PixelTest(const F& f)  // NOLINT: implicit, as for std::function
      : obj_(&f), fn_([](const void* o, int x, int y) { return static_cast<bool>((*static_cast<const F*>(o))(x, y)); }) {}
  bool operator()(int x, int y) const { return fn_(obj_, x, y); }

 private:
  const void* obj_;
  bool (*fn_)(const void*, int, int);
};

// Pixel-integrated 1-D Gaussian of one axis and its derivatives (psf_fit.cc).
struct PsfProfile {
  explicit PsfProfile(std::pmr::memory_resource* mr = std::pmr::get_default_resource()) : f(mr), dc(mr), ds(mr) {}
  ScratchVec<double> f, dc, ds;
  void Compute(int i0, int n, double c, double s);
};

// The Gaussian averaged along the smear segment, every window pixel (psf_fit.cc).
struct PsfSmearModel {
  explicit PsfSmearModel(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : f(mr), dx(mr), dy(mr), ds(mr), px(mr), py(mr) {}
  ScratchVec<double> f, dx, dy, ds;
  PsfProfile px, py;
  void Compute(int x0, int nx, int y0, int ny, double cx, double cy, double s, double sdx, double sdy);
};

// The buffers of one fit, reused from fit to fit: reserved for windows up to side x side pixels, a
// fit with PsfFitOptions::max_half_px <= (side - 1) / 2 allocates nothing.
struct PsfFitScratch {
  explicit PsfFitScratch(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : v(mr), w_cur(mr), w_new(mr), use(mr), fx(mr), fy(mr), sm(mr) {}
  ScratchVec<double> v, w_cur, w_new;
  ScratchVec<uint8_t> use;
  PsfProfile fx, fy;
  PsfSmearModel sm;
  void Reserve(int side_px);
};

// Fits the window of half-size r around (px, py). level / sigma_n: local background and noise
// (ADU). is_bad(x, y) marks pixels to leave out (defects, dead pixels); saturated pixels are left
// out too.
PsfFit FitPsf(const ImageView& img, int px, int py, int r, double level, double sigma_n, const PsfFitOptions& options,
              const std::function<bool(int, int)>& is_bad);
// The same with the buffers given (the one implementation; the form above makes a local scratch).
PsfFit FitPsf(const ImageView& img, int px, int py, int r, double level, double sigma_n, const PsfFitOptions& options,
              PixelTest is_bad, PsfFitScratch* scratch);

}  // namespace ssiu
