#include "cli/smear_flags.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

#include "core/csv.h"
#include "core/error.h"
#include "core/types.h"

namespace ssiu::cli {

void AddSmearFlags(CLI::App* cmd, SmearFlags* f, const std::string& axes) {
  f->rate = cmd->add_option("--rate-dps", f->rate_text,
                            "Angular rate relative to inertial space during the exposure, X,Y,Z deg/s in " + axes +
                                ": the detector fits stars smeared along the path it predicts (needs --camera "
                                "and --exposure-s)")
                ->type_name("X,Y,Z");
  f->exposure = cmd->add_option("--exposure-s", f->exposure_s,
                                "Exposure time (s) for --rate-dps (camera.json carries none, so it is required)");
}

Vec3 SmearRateRadS(const SmearFlags& f, bool camera_given) {
  if (!f.given()) throw InputError("--exposure-s", "given without --rate-dps");
  // One token "X,Y,Z" (a list option would swallow the positional frame that follows it).
  if (f.rate_text.empty() || f.rate_text.back() == ',') {
    throw InputError("--rate-dps", "an empty component (give X,Y,Z deg/s)");
  }
  std::vector<double> v;
  std::stringstream ss(f.rate_text);
  for (std::string cell; std::getline(ss, cell, ',');) {
    double x = 0;
    if (!ParseDecimal(cell, &x)) {
      throw InputError("--rate-dps", "'" + cell + "' is not a finite decimal number (give X,Y,Z deg/s)");
    }
    v.push_back(x);
  }
  if (v.size() != 3) {
    throw InputError("--rate-dps", "needs three components X,Y,Z (deg/s), got " + std::to_string(v.size()));
  }
  const Vec3 w_dps(v[0], v[1], v[2]);
  if (!camera_given) throw InputError("--rate-dps", "needs --camera (the smear is projected through it)");
  if (!f.exposure_given()) {
    throw InputError("--exposure-s", "required with --rate-dps (camera.json has no exposure time)");
  }
  if (!(std::isfinite(f.exposure_s) && f.exposure_s > 0 && f.exposure_s < 100)) {
    throw InputError("--exposure-s", "must be a finite number in (0, 100) s");
  }
  return w_dps * kDegToRad;
}

ExpectedSmear SmearModel(const Vec3& rate_rad_s, double exposure_s, const Camera& camera) {
  ExpectedSmear s;
  s.rate_rad_s = rate_rad_s;
  s.exposure_s = exposure_s;
  s.camera = camera;
  // The detector's smeared fit costs roughly the square of the smear length (measured on a 1024 px
  // frame: 122 px took 2.1 s, 610 px 51 s); longer predicted smears are refused rather than run
  // for minutes. The longest smear is at the centre, an edge or a corner (rates across and about
  // the boresight).
  double longest_px = 0;
  for (double fy : {0.0, 0.5, 1.0})
    for (double fx : {0.0, 0.5, 1.0}) {
      const Vec2 p(fx * (camera.width - 1), fy * (camera.height - 1));
      const auto a = s.PathAt(p, -0.5 * exposure_s), b = s.PathAt(p, 0.5 * exposure_s);
      // A star leaving the hemisphere in front of the camera: longer than any frame.
      longest_px = std::max(longest_px, a && b ? (*b - *a).norm() : HUGE_VAL);
    }
  if (!(longest_px <= kMaxSmearPx)) {
    std::ostringstream m;
    m << "with --exposure-s " << exposure_s << " the stars smear by up to "
      << (std::isfinite(longest_px) ? std::to_string(static_cast<long>(longest_px)) + " px" : "more than the frame")
      << ", above the " << kMaxSmearPx << " px the detector's smear model is run for";
    throw InputError("--rate-dps", m.str());
  }
  return s;
}

ExpectedSmear SmearFromFlags(const SmearFlags& f, const Camera* camera) {
  if (!f.given() && !f.exposure_given()) return ExpectedSmear{};
  const Vec3 w = SmearRateRadS(f, camera != nullptr);
  return SmearModel(w, f.exposure_s, *camera);
}

void RefuseSmearFlags(const SmearFlags& f, const std::string& why) {
  if (f.given()) throw InputError("--rate-dps", why);
  if (f.exposure_given()) throw InputError("--exposure-s", why);
}

}  // namespace ssiu::cli
