#include "groundtest/solve_pictures.h"

#include "core/attitude.h"
#include "core/csv.h"

namespace ssiu {

PictureSolve SolveStandPicture(const StarIdentifier& id, const ImageView& image, const Camera& camera,
                               double gain_e_per_adu, double t_s, const SolveOptions& options) {
  SolveOptions so = options;
  so.detect.gain_e_per_adu = gain_e_per_adu;
  const SolveResult r = SolveFrame(id, image, camera, so);
  PictureSolve p;
  p.status = r.status;
  p.stars = static_cast<int>(r.identification.matches.size());
  p.sample.t_s = t_s;
  if (r.status == SolveStatus::kSolved) {
    p.sample.q = r.attitude.q_inertial_from_sensor;
    p.sample.sigma_cross_rad = r.attitude.sigma_cross_rad;
    p.sample.sigma_roll_rad = r.attitude.sigma_roll_rad;
  }
  return p;
}

void WriteAttitudeCsv(const std::string& path, const std::vector<AttitudeSample>& s) {
  std::vector<std::vector<double>> cols(7);
  for (const auto& a : s) {
    const auto q = ToWxyz(a.q);
    cols[0].push_back(a.t_s);
    for (int k = 0; k < 4; ++k) cols[1 + k].push_back(q[k]);
    cols[5].push_back(a.sigma_cross_rad * kRadToArcsec);
    cols[6].push_back(a.sigma_roll_rad * kRadToArcsec);
  }
  WriteCsv(path, {"t_s", "qw", "qx", "qy", "qz", "sigma_cross_arcsec", "sigma_roll_arcsec"}, cols);
}

}  // namespace ssiu
