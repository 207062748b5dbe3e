// Monte Carlo versions of the normal tests (label `long`): does the stated uncertainty of the
// AprilTag plate pose and of the recovered misalignment hold over many random stands?
#include <cmath>
#include <cstdio>
#include <memory>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/rng.h"
#include "groundtest/compare.h"
#include "groundtest/reference.h"
#include "groundtest/solve_pictures.h"
#include "groundtest/virtual_stand.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

struct McSetup {
  Camera cam = MakeCamera(1024, 1024, 16.6);
  std::unique_ptr<StarIdentifier> id;
  McSetup() {
    CatalogBuildOptions co;
    co.fov_deg = 16.6;
    id = std::make_unique<StarIdentifier>(BuildSolverCatalog(LoadXplanetBsc(DefaultBscPath(), 7.0), co));
  }
};

TEST(GroundtestMonteCarlo, AprilTagPoseZScores) {
  McSetup s;
  Rng rng(5);
  double z2[3] = {0, 0, 0}, zs2[3] = {0, 0, 0}, chi2 = 0;
  const int n = 30;
  for (int i = 0; i < n; ++i) {
    const Quat q = QuatFromRaDecRoll(rng.Uniform(0, 2 * kPi), rng.Uniform(-1.2, 1.2), rng.Uniform(0, 2 * kPi));
    const Mask m = DesignMask(s.cam, s.id->catalog().stars, q, MaskOptions{});
    PlatePose p;
    p.t_c_mm = Vec3(rng.Normal() * 0.2, rng.Normal() * 0.2, rng.Normal() * 0.5);
    p.r_c_from_p =
        QuatFromRotationVector(Vec3(rng.Normal(), rng.Normal(), rng.Normal()) * 0.3 * kDegToRad).toRotationMatrix();
    AuxCamera aux;
    PhotoOptions po;
    po.noise_dn = 3.0;
    FiducialOptions fo;
    fo.pixel_noise_dn = po.noise_dn;  // the expected accuracy from the stated pixel noise
    const auto photo = RenderAuxPhoto(m, p, aux, po, 100 + i);
    const PlatePoseEstimate e =
        EstimatePlatePose(m, aux, photo.data(), aux.camera.width, aux.camera.height, "photo", fo);
    const Vec3 err = RotationVector(e.q_c_from_m * MaskRotation(m, p).conjugate());
    for (int k = 0; k < 3; ++k) z2[k] += err(k) * err(k) / e.q_c_from_m_noise_cov_rad2(k, k) / n;
    for (int k = 0; k < 3; ++k) zs2[k] += err(k) * err(k) / e.q_c_from_m_cov_rad2(k, k) / n;
    chi2 += e.corner_chi2_per_dof / n;
  }
  std::printf(
      "AprilTag mask-rotation z-score RMS over %d photos against the pixel-noise prediction: %.2f %.2f %.2f; against "
      "the stated sigma: %.2f %.2f %.2f; mean corner chi2/dof %.2f\n",
      n, std::sqrt(z2[0]), std::sqrt(z2[1]), std::sqrt(z2[2]), std::sqrt(zs2[0]), std::sqrt(zs2[1]), std::sqrt(zs2[2]),
      chi2);
  // z^2 averaged over 30 photos: chi2(30)/30 stays below 1.7 (99.9%), i.e. z RMS below 1.3.
  for (double v : z2) EXPECT_LT(std::sqrt(v), 1.3);
  EXPECT_LT(chi2, 1.3);
}

TEST(GroundtestMonteCarlo, MisalignmentRecoveryCoverage) {
  McSetup s;
  Rng rng(9);
  const int runs = 12;
  int within3 = 0, axes = 0;
  double z2 = 0, chi2 = 0;
  for (int r = 0; r < runs; ++r) {
    const Quat q = QuatFromRaDecRoll(rng.Uniform(0, 2 * kPi), rng.Uniform(-1.2, 1.2), rng.Uniform(0, 2 * kPi));
    const Mask m = DesignMask(s.cam, s.id->catalog().stars, q, MaskOptions{});
    StandSimOptions so;
    so.positions = 5;
    so.misalignment_arcmin = Vec3(rng.Uniform(-5, 5), rng.Uniform(-5, 5), rng.Uniform(-5, 5));
    const StandSimulation sim = SimulateStand(m, so, 1000 + r);
    std::vector<AttitudeSample> ref, est;
    SolveOptions solve;
    solve.identify.systematic_px = 0;
    for (const auto& p : sim.pictures) {
      const PictureSolve ps =
          SolveStandPicture(*s.id, p.frame.view(), m.camera, so.view.detector.gain_e_per_adu, p.t_s, solve);
      if (ps.status != SolveStatus::kSolved) continue;
      est.push_back(ps.sample);
      const PlatePoseEstimate pe =
          EstimatePlatePose(m, so.aux, p.photo.data(), so.aux.camera.width, so.aux.camera.height, "photo");
      const ReferenceSample rs = ReferenceFromStand(m, pe.q_c_from_m, pe.q_c_from_m_cov_rad2, p.enc_az_deg * kDegToRad,
                                                    p.enc_el_deg * kDegToRad, p.enc_rot_deg * kDegToRad,
                                                    so.encoder_sigma_arcsec * kArcsecToRad, p.t_s);
      AttitudeSample a;
      a.t_s = rs.t_s, a.q = rs.q_inertial_from_sensor, a.sigma_cross_rad = rs.sigma_cross_rad,
      a.sigma_roll_rad = rs.sigma_roll_rad;
      a.common_sigma_cross_rad = rs.common_sigma_cross_rad, a.common_sigma_roll_rad = rs.common_sigma_roll_rad;
      ref.push_back(a);
    }
    ASSERT_GE(est.size(), 4u) << "run " << r;
    const CompareResult c = CompareAttitudes(ref, est, CompareOptions{});
    const Vec3 truth = RotationVector(sim.q_mis);
    for (int k = 0; k < 3; ++k) {
      const double z = (c.misalignment_rad(k) - truth(k)) / c.misalignment_sigma_rad(k);
      within3 += std::abs(z) < 3, ++axes, z2 += z * z;
    }
    chi2 += c.chi2_per_dof / runs;
  }
  std::printf("misalignment: %d/%d axes within 3 sigma, z-score RMS %.2f, mean chi2/dof %.2f over %d stands\n", within3,
              axes, std::sqrt(z2 / axes), chi2, runs);
  EXPECT_GE(within3, axes - 2);
  EXPECT_LT(std::sqrt(z2 / axes), 1.6);
  EXPECT_GT(chi2, 0.5);
  EXPECT_LT(chi2, 1.6);
}

}  // namespace
}  // namespace ssiu
