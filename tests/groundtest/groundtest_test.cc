// Ground test: mask geometry, fiducial pose, comparison statistics and the virtual stand end to end.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/error.h"
#include "core/image.h"
#include "core/rng.h"
#include "groundtest/compare.h"
#include "groundtest/mask.h"
#include "groundtest/reference.h"
#include "groundtest/solve_pictures.h"
#include "groundtest/stand.h"
#include "groundtest/virtual_stand.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

const Camera& TrackerCamera() {
  static const Camera cam = MakeCamera(1024, 1024, 16.6);
  return cam;
}

const StarIdentifier& Identifier() {
  static const std::unique_ptr<StarIdentifier> id = [] {
    CatalogBuildOptions co;
    co.fov_deg = 16.6;
    return std::make_unique<StarIdentifier>(BuildSolverCatalog(LoadXplanetBsc(DefaultBscPath(), 7.0), co));
  }();
  return *id;
}

// Orion, roll 20 deg: a field with bright and faint stars.
const Quat kDesign = QuatFromRaDecRoll(83.8 * kDegToRad, -1.0 * kDegToRad, 20.0 * kDegToRad);

const Mask& OrionMask() {
  static const Mask m = [] {
    MaskOptions o;
    o.collimator_focal_mm = 500;
    return DesignMask(TrackerCamera(), Identifier().catalog().stars, kDesign, o);
  }();
  return m;
}

TEST(GroundtestMask, HolesAreTheSkyOfTheDesignAttitude) {
  const Mask& m = OrionMask();
  ASSERT_GT(m.holes.size(), 20u);
  // Independent truth: every catalog star inside the (pinhole) field + margin, by RA/Dec geometry.
  const double half = std::atan(m.field_half_x_mm / m.collimator_focal_mm);
  int expected = 0;
  for (const auto& s : Identifier().catalog().stars) {
    const Vec3 d = kDesign.conjugate() * s.unit;
    if (d.z() > 0 && std::abs(std::atan2(d.x(), d.z())) < half && std::abs(std::atan2(d.y(), d.z())) < half) ++expected;
  }
  EXPECT_EQ(static_cast<int>(m.holes.size()), expected);
  for (const auto& h : m.holes) {
    const CatalogStar* star = nullptr;
    for (const auto& s : Identifier().catalog().stars)
      if (s.id == h.star_id) star = &s;
    ASSERT_NE(star, nullptr);
    // The collimator turns the hole into a star at infinity in direction (x, y, F): through the
    // design attitude it must be the catalog star.
    const Vec3 u = kDesign * m.DirectionOf(h.x_mm, h.y_mm);
    EXPECT_LT(std::atan2(u.cross(star->unit).norm(), u.dot(star->unit)) * kRadToArcsec, 1e-6);
    // Area grading: d^2 ratio = flux ratio (unless clamped).
    if (h.diameter_mm < m.hole_max_diameter_mm) {
      EXPECT_NEAR(std::pow(h.diameter_mm / m.hole_min_diameter_mm, 2), std::pow(10.0, 0.4 * (m.mag_faint - h.mag)),
                  1e-9);
    }
  }
  // Boresight star at the centre: a star at the boresight maps to (0, 0).
  const Vec3 centre = kDesign * m.DirectionOf(0, 0);
  EXPECT_LT((centre - kDesign * Vec3::UnitZ()).norm(), 1e-12);
  // Fiducials outside the star field and inside the plate.
  ASSERT_EQ(m.tags.size(), 8u);
  for (const auto& t : m.tags) {
    EXPECT_TRUE(std::abs(t.x_mm) - t.size_mm / 2 > m.field_half_x_mm ||
                std::abs(t.y_mm) - t.size_mm / 2 > m.field_half_y_mm);
    EXPECT_LT(std::abs(t.x_mm) + t.size_mm * 0.625, m.plate_half_mm);
  }
  // JSON round trip.
  const Mask back = MaskFromJson(MaskToJson(m), "mask");
  ASSERT_EQ(back.holes.size(), m.holes.size());
  EXPECT_EQ(back.holes[3].star_id, m.holes[3].star_id);
  EXPECT_DOUBLE_EQ(back.holes[3].x_mm, m.holes[3].x_mm);
  EXPECT_THAT(back.q_design, QuaternionNear(m.q_design, 1e-6));
  // Ids out of the integer range (undefined behaviour when converted) or not whole are refused.
  for (const double bad : {1e300, -5.0, 2.5}) {
    Json j = MaskToJson(m);
    j["holes"][3]["star_id"] = bad;
    EXPECT_THROW(MaskFromJson(j, "mask"), InputError) << bad;
    j = MaskToJson(m);
    j["tags"][0]["id"] = bad;
    EXPECT_THROW(MaskFromJson(j, "mask"), InputError) << bad;
  }
}

TEST(GroundtestMask, PrintedPlateCarriesItsScaleAndFiducialsWhereMaskJsonSaysTheyAre) {
  const Mask& m = OrionMask();
  const std::string dir = testing::TempDir("mask_png");
  const double dpi = 40;
  WriteMaskPng(m, dir + "/mask.png", dpi);
  // The scale in the PNG's pHYs chunk: pixels per metre, unit metre.
  std::ifstream f(dir + "/mask.png", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const size_t at = bytes.find("pHYs");
  ASSERT_NE(at, std::string::npos);
  auto be32 = [&](size_t i) {
    uint32_t v = 0;
    for (int k = 0; k < 4; ++k) v = v << 8 | static_cast<uint8_t>(bytes[i + k]);
    return v;
  };
  EXPECT_EQ(be32(at + 4), static_cast<uint32_t>(std::lround(dpi / 0.0254)));
  EXPECT_EQ(be32(at + 8), be32(at + 4));
  EXPECT_EQ(bytes[at + 12], 1);
  const Frame png = ReadFrame(dir + "/mask.png");
  const int n = static_cast<int>(std::ceil(2 * m.plate_half_mm * dpi / 25.4));
  ASSERT_EQ(png.image.width, n);
  // libapriltag finds the eight tag36h11 fiducials on the printed plate, at the corners mask.json lists.
  std::vector<uint8_t> px(png.image.pixels.begin(), png.image.pixels.end());
  const auto dets = DetectFiducials(px.data(), png.image.width, png.image.height, "tag36h11", FiducialOptions{});
  ASSERT_EQ(dets.size(), 8u);
  for (const auto& d : dets) {
    ASSERT_GE(d.id, 0);
    ASSERT_LT(d.id, 8);
    const auto corners = m.tags[d.id].Corners();
    for (int k = 0; k < 4; ++k) {
      const Vec2 expected = (corners[k] + Vec2::Constant(m.plate_half_mm)) * (dpi / 25.4) - Vec2::Constant(0.5);
      EXPECT_LT((d.corners_px[k] - expected).norm(), 1.0) << "tag " << d.id << " corner " << k;
    }
  }
  // Every hole is white at its place, the plate black between.
  for (const auto& h : m.holes) {
    const int x = static_cast<int>(std::lround((h.x_mm + m.plate_half_mm) * dpi / 25.4 - 0.5));
    const int y = static_cast<int>(std::lround((h.y_mm + m.plate_half_mm) * dpi / 25.4 - 0.5));
    EXPECT_GT(png.image.at(x, y), 0) << "hole HR " << h.star_id;
  }
}

TEST(GroundtestMask, ResolvingASimulatedPictureGivesTheDesignAttitude) {
  // Perfect stand: plate nominal, tracker aligned with the collimator, no encoder motion.
  const Mask& m = OrionMask();
  TrackerViewOptions vo;
  std::vector<ViewStar> stars;
  const Image16 img = RenderTrackerView(m, PlatePose{}, Quat::Identity(), vo, 5, &stars);
  const PictureSolve p = SolveStandPicture(Identifier(), img.view(), m.camera, vo.detector.gain_e_per_adu, 0);
  ASSERT_EQ(p.status, SolveStatus::kSolved);
  const AttitudeErrorSplit e = SplitAttitudeError(p.sample.q, kDesign);
  std::printf("design re-solve: %d stars, cross %.2f arcsec (sigma %.2f), roll %.2f arcsec (sigma %.2f)\n", p.stars,
              e.cross_rad * kRadToArcsec, p.sample.sigma_cross_rad * kRadToArcsec, e.roll_rad * kRadToArcsec,
              p.sample.sigma_roll_rad * kRadToArcsec);
  EXPECT_LT(e.cross_rad, 3 * std::sqrt(2.0) * p.sample.sigma_cross_rad);
  EXPECT_LT(std::abs(e.roll_rad), 3 * p.sample.sigma_roll_rad);
}

TEST(GroundtestMask, DistortedTrackerNeedsNoCompensationOnThePlate) {
  // Holes are true directions; the tracker's distortion is in its camera model, so the picture
  // (rendered through the distorted camera) still solves to the design attitude.
  Camera cam = TrackerCamera();
  cam.distortion.k1 = -0.2;  // ~5 px barrel at the corners
  const Mask m = DesignMask(cam, Identifier().catalog().stars, kDesign, MaskOptions{});
  EXPECT_GT(m.field_half_x_mm, OrionMask().field_half_x_mm);  // barrel distortion widens the field
  TrackerViewOptions vo;
  const Image16 img = RenderTrackerView(m, PlatePose{}, Quat::Identity(), vo, 6);
  const PictureSolve p = SolveStandPicture(Identifier(), img.view(), cam, vo.detector.gain_e_per_adu, 0);
  ASSERT_EQ(p.status, SolveStatus::kSolved);
  const AttitudeErrorSplit e = SplitAttitudeError(p.sample.q, kDesign);
  EXPECT_LT(e.cross_rad, 3 * std::sqrt(2.0) * p.sample.sigma_cross_rad);
  EXPECT_LT(std::abs(e.roll_rad), 3 * p.sample.sigma_roll_rad);
}

TEST(GroundtestMask, PredistortedPlateShowsAPinholeSkyThroughTheDistortedLens) {
  // Asked for (--predistort), the holes compensate the tracker's lens: through the distorted lens
  // each star lands where a pinhole camera would put it, so a tracker that ignores its distortion
  // solves to the design attitude.
  Camera cam = TrackerCamera();
  cam.distortion.k1 = -0.2;
  Camera pinhole = cam;
  pinhole.distortion = Distortion{};
  MaskOptions mo;
  mo.compensate_distortion = true;
  const Mask m = DesignMask(cam, Identifier().catalog().stars, kDesign, mo);
  EXPECT_TRUE(MaskFromJson(MaskToJson(m), "mask").distortion_compensated);
  const Mask plain = DesignMask(cam, Identifier().catalog().stars, kDesign, MaskOptions{});
  TrackerViewOptions vo;
  std::vector<ViewStar> seen, seen_plain;
  const Image16 img = RenderTrackerView(m, PlatePose{}, Quat::Identity(), vo, 8, &seen);
  RenderTrackerView(plain, PlatePose{}, Quat::Identity(), vo, 8, &seen_plain);
  ASSERT_GT(seen.size(), 20u);
  double worst = 0, worst_plain = 0;
  auto pinhole_px = [&](StarId id) {
    for (const auto& s : Identifier().catalog().stars)
      if (s.id == id) return *pinhole.Project(kDesign.conjugate() * s.unit);
    return Vec2(-1e9, -1e9);
  };
  for (const auto& v : seen) worst = std::max(worst, (Vec2(v.x_px, v.y_px) - pinhole_px(v.star_id)).norm());
  for (const auto& v : seen_plain)
    worst_plain = std::max(worst_plain, (Vec2(v.x_px, v.y_px) - pinhole_px(v.star_id)).norm());
  std::printf("star image vs pinhole image: predistorted %.4f px, plain %.2f px (worst star)\n", worst, worst_plain);
  EXPECT_LT(worst, 1e-3);
  EXPECT_GT(worst_plain, 1.0);  // without it the lens moves the stars by pixels
  const PictureSolve p = SolveStandPicture(Identifier(), img.view(), pinhole, vo.detector.gain_e_per_adu, 0);
  ASSERT_EQ(p.status, SolveStatus::kSolved);
  const AttitudeErrorSplit e = SplitAttitudeError(p.sample.q, kDesign);
  EXPECT_LT(e.cross_rad, 3 * std::sqrt(2.0) * p.sample.sigma_cross_rad);
  EXPECT_LT(std::abs(e.roll_rad), 3 * p.sample.sigma_roll_rad);
}

TEST(GroundtestStand, PlateShiftIsARotationOfTheSky) {
  // A lateral shift t moves every star by t/F (small angle); an in-plane turn is a roll.
  const Mask& m = OrionMask();
  PlatePose p;
  p.t_c_mm = Vec3(0.1, -0.05, 0);
  p.r_c_from_p = Eigen::AngleAxisd(0.1 * kDegToRad, Vec3::UnitZ()).toRotationMatrix();
  const Vec3 r = RotationVector(MaskRotation(m, p));
  // +x shift = rotation about +y, +y shift = rotation about -x (here y = -0.05 mm). A shift moves a
  // star at field angle a by t cos^2(a) / F, so the field-wide fit is up to 2% below t / F.
  EXPECT_NEAR(r.y(), 0.1 / 500, 0.02 * 0.1 / 500);
  EXPECT_NEAR(r.x(), 0.05 / 500, 0.02 * 0.05 / 500);
  EXPECT_NEAR(r.z(), 0.1 * kDegToRad, 1e-6);
  // Stand rotation: positive azimuth moves the boresight towards +x.
  const Vec3 b = StandRotation(1 * kDegToRad, 0, 0) * Vec3::UnitZ();
  EXPECT_NEAR(std::atan2(b.x(), b.z()), 1 * kDegToRad, 1e-12);
  const Vec3 b2 = StandRotation(0, 1 * kDegToRad, 0) * Vec3::UnitZ();
  EXPECT_NEAR(std::atan2(-b2.y(), b2.z()), 1 * kDegToRad, 1e-12);
}

TEST(GroundtestReference, AprilTagPoseWithinItsPixelNoiseUncertainty) {
  const Mask& m = OrionMask();
  AuxCamera aux;
  PlatePose truth;
  truth.t_c_mm = Vec3(0.3, -0.2, 0.5);
  truth.r_c_from_p =
      (Eigen::AngleAxisd(0.3 * kDegToRad, Vec3::UnitZ()) * Eigen::AngleAxisd(0.2 * kDegToRad, Vec3::UnitX()))
          .toRotationMatrix();
  PhotoOptions po;
  po.noise_dn = 3.0;
  const std::vector<uint8_t> photo = RenderAuxPhoto(m, truth, aux, po, 7);
  // The expected accuracy is computed from the photo's pixel noise (3 DN, stated here).
  FiducialOptions fo;
  fo.pixel_noise_dn = po.noise_dn;
  const PlatePoseEstimate e = EstimatePlatePose(m, aux, photo.data(), aux.camera.width, aux.camera.height, "photo", fo);
  EXPECT_EQ(e.tag_ids.size(), 8u);
  EXPECT_EQ(e.refined_tags, 8);
  // The edge fits see the photo's noise: 3 DN plus 8-bit rounding (1/sqrt(12) DN).
  const double true_noise = std::sqrt(po.noise_dn * po.noise_dn + 1.0 / 12);
  EXPECT_NEAR(e.measured_pixel_noise_dn, true_noise, 0.1 * true_noise);
  // Independent estimate of the corner accuracy the pixel noise allows (Cramer-Rao): a step of
  // contrast C blurred to an edge width s (Gaussian 1.5 px with the 1 px pixel box), noise sigma_n,
  // seen over +/-R across the side. Fisher information per unit length of the side for its tilt:
  // I = C^2 / sigma_n^2 * erf(R/s) / (2 sqrt(pi) s); for its offset, the unknown dark and bright levels
  // take away the mean of the profile's slope over the band: I_off = I - C^2 / sigma_n^2 *
  // erf(R / (sqrt(2) s))^2 / (2R). A line fitted over length l (the side L minus the margins at the
  // corners) puts the corner, at D = L/2 from its centre, at 1 / (l I_off) + 12 D^2 / (l^3 I); averaged
  // over the sides of the detected tags (perspective makes them 55-70 px).
  const double contrast = 220 * (0.9 - 0.06), s_edge = std::sqrt(1.5 * 1.5 + 1.0 / 12);
  const double c2 = contrast * contrast / (true_noise * true_noise);
  double var_sum = 0;
  int sides = 0;
  for (const auto& d : DetectFiducials(photo.data(), aux.camera.width, aux.camera.height, "tag36h11", fo))
    for (int k = 0; k < 4; ++k) {
      const double L = (d.corners_px[(k + 1) % 4] - d.corners_px[k]).norm();
      const double R = std::min(0.45 * L / 8, 4.0), l = L - 2 * (R + 2), D = L / 2;
      const double I = c2 * std::erf(R / s_edge) / (2 * std::sqrt(kPi) * s_edge);
      const double I_off = I - c2 * std::pow(std::erf(R / (std::sqrt(2.0) * s_edge)), 2) / (2 * R);
      var_sum += 1 / (l * I_off) + 12 * D * D / (l * l * l * I), ++sides;
    }
  const double floor_px = std::sqrt(var_sum / sides);
  const Quat q_true = MaskRotation(m, truth);
  const Vec3 err = RotationVector(e.q_c_from_m * q_true.conjugate());
  const Vec3 sig = e.q_c_from_m_noise_cov_rad2.diagonal().cwiseSqrt();
  std::printf(
      "pixel noise %.2f DN (measured %.2f); corner sigma expected %.4f px (analytic %.4f px), PnP residuals %.4f px, "
      "chi2/dof %.2f\nmask rotation error %.2f %.2f %.2f arcsec, expected from the pixel noise %.2f %.2f %.2f arcsec\n",
      fo.pixel_noise_dn, e.measured_pixel_noise_dn, e.predicted_corner_sigma_px, floor_px, e.corner_sigma_px,
      e.corner_chi2_per_dof, err.x() * kRadToArcsec, err.y() * kRadToArcsec, err.z() * kRadToArcsec,
      sig.x() * kRadToArcsec, sig.y() * kRadToArcsec, sig.z() * kRadToArcsec);
  EXPECT_NEAR(e.predicted_corner_sigma_px, floor_px, 0.1 * floor_px);
  // The PnP residuals agree with the predicted corner noise (chi2(58)/58 within its 99.9% range).
  EXPECT_GT(e.corner_chi2_per_dof, 0.55);
  EXPECT_LT(e.corner_chi2_per_dof, 1.6);
  // The pose agrees with the truth within the accuracy the pixel noise allows: 3 sigma per axis,
  // and the 3-vector's Mahalanobis distance below the chi-square(3) 99.9% point.
  for (int k = 0; k < 3; ++k) EXPECT_LT(std::abs(err(k)), 3 * sig(k)) << "axis " << k;
  EXPECT_LT(err.dot(e.q_c_from_m_noise_cov_rad2.inverse() * err), 16.3);
  // That accuracy is useful: about an arcsec across the boresight (the plate shift without the
  // fiducials would be an error of t/F ~ 0.36 mrad ~ 74 arcsec).
  EXPECT_LT(sig.head<2>().maxCoeff() * kRadToArcsec, 1.5);
  // The stated covariance never claims less than the pixel noise allows.
  for (int k = 0; k < 3; ++k) EXPECT_GE(e.q_c_from_m_cov_rad2(k, k), e.q_c_from_m_noise_cov_rad2(k, k) * (1 - 1e-9));
  // Plate translation in C against its covariance (aux frame covariance rotated to C).
  const Mat3 ct = aux.r_aux_from_c.transpose() * e.covariance.bottomRightCorner<3, 3>() * aux.r_aux_from_c;
  const Vec3 dt = e.pose.t_c_mm - truth.t_c_mm;
  for (int k = 0; k < 3; ++k) EXPECT_LT(std::abs(dt(k)), 3 * std::sqrt(ct(k, k))) << "t axis " << k;
}

TEST(GroundtestReference, BadPhotosAreInputErrors) {
  const Mask& m = OrionMask();
  AuxCamera aux;
  PhotoOptions none;
  none.hide_tags = true;
  const auto blank = RenderAuxPhoto(m, PlatePose{}, aux, none, 1);
  try {
    EstimatePlatePose(m, aux, blank.data(), aux.camera.width, aux.camera.height, "blank.png");
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("no tag36h11 fiducials visible"));
  }
  PhotoOptions wrong;
  wrong.tag_family = "tag25h9";
  const auto other = RenderAuxPhoto(m, PlatePose{}, aux, wrong, 1);
  try {
    EstimatePlatePose(m, aux, other.data(), aux.camera.width, aux.camera.height, "other.png");
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("tag25h9"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("wrong tag family"));
  }
  // The fiducials of another plate (other tag ids): not this mask's.
  MaskOptions other_ids;
  other_ids.first_tag_id = 100;
  const Mask m2 = DesignMask(TrackerCamera(), Identifier().catalog().stars, kDesign, other_ids);
  const auto foreign = RenderAuxPhoto(m2, PlatePose{}, aux, PhotoOptions{}, 1);
  try {
    EstimatePlatePose(m, aux, foreign.data(), aux.camera.width, aux.camera.height, "foreign.png");
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("0 of this mask's tag36h11 fiducials visible"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("tags 100,101,102,103,104,105,106,107 belong to another mask"));
  }
  Camera c2 = TrackerCamera();
  c2.focal_length_px *= 1.1;
  EXPECT_THROW(CheckMaskCamera(m, c2, "mask.json"), InputError);
  EXPECT_NO_THROW(CheckMaskCamera(m, TrackerCamera(), "mask.json"));
}

TEST(GroundtestCompare, RecoversAKnownMisalignmentAndDrift) {
  // Synthetic truth: q_est = q_ref * exp(mis + drift * t + noise), noise at the stated sigmas.
  Rng rng(3);
  const Vec3 mis(40, -25, 90);  // arcsec
  const double drift_x_per_h = 6.0;
  std::vector<AttitudeSample> ref, est;
  const int n = 40;
  const double sc = 2.0, sr = 15.0;
  for (int i = 0; i < n; ++i) {
    AttitudeSample r;
    r.t_s = i * 90.0;
    r.q = RandomAttitude(100 + i);
    AttitudeSample e = r;
    Vec3 d =
        mis + Vec3(drift_x_per_h * r.t_s / 3600, 0, 0) + Vec3(sc * rng.Normal(), sc * rng.Normal(), sr * rng.Normal());
    e.q = r.q * QuatFromRotationVector(d * kArcsecToRad);
    e.sigma_cross_rad = sc * kArcsecToRad, e.sigma_roll_rad = sr * kArcsecToRad;
    ref.push_back(r), est.push_back(e);
  }
  CompareOptions o;
  o.requirement_arcsec = 5;
  const CompareResult c = CompareAttitudes(ref, est, o);
  EXPECT_EQ(c.pictures, n);
  const double mean_drift_x = drift_x_per_h * (n - 1) * 90.0 / 2 / 3600;  // the drift's mean enters the bias
  EXPECT_NEAR(c.misalignment_rad.x() * kRadToArcsec, mis.x() + mean_drift_x,
              3 * c.misalignment_sigma_rad.x() * kRadToArcsec);
  EXPECT_NEAR(c.misalignment_rad.y() * kRadToArcsec, mis.y(), 3 * c.misalignment_sigma_rad.y() * kRadToArcsec);
  EXPECT_NEAR(c.misalignment_rad.z() * kRadToArcsec, mis.z(), 3 * c.misalignment_sigma_rad.z() * kRadToArcsec);
  EXPECT_NEAR(c.x.drift_per_h * kRadToArcsec, drift_x_per_h, 3 * c.x.drift_sigma_per_h * kRadToArcsec);
  EXPECT_LT(std::abs(c.y.drift_per_h), 3 * c.y.drift_sigma_per_h);
  EXPECT_NEAR(c.roll.rms * kRadToArcsec, sr, 0.35 * sr);
  EXPECT_TRUE(c.pass) << c.verdict;
  o.requirement_arcsec = 1.0;
  EXPECT_FALSE(CompareAttitudes(ref, est, o).pass);
  // Two tracker rows far from every reference time: too few matched pictures.
  for (auto& e : est) e.t_s += 1000.5;
  EXPECT_THROW(CompareAttitudes(ref, est, CompareOptions{}), InputError);
}

TEST(GroundtestVirtualStand, RecoversTheHiddenMisalignment) {
  const Mask& m = OrionMask();
  StandSimOptions so;
  so.positions = 6;
  so.misalignment_arcmin = Vec3(3.0, -2.5, 4.0);
  const StandSimulation s = SimulateStand(m, so, 11);
  std::vector<AttitudeSample> computed;
  std::vector<AttitudeSample> reference;
  for (const auto& p : s.pictures) {
    // No distortion and an exact catalog on the stand: the solver's allowance for unmodelled
    // position errors (systematic_px, 0.5 px by default) would make its stated sigma 3-4x too large.
    SolveOptions solve;
    solve.identify.systematic_px = 0;
    const PictureSolve ps =
        SolveStandPicture(Identifier(), p.frame.view(), m.camera, so.view.detector.gain_e_per_adu, p.t_s, solve);
    ASSERT_EQ(ps.status, SolveStatus::kSolved) << "t " << p.t_s;
    computed.push_back(ps.sample);
    const PlatePoseEstimate pe =
        EstimatePlatePose(m, so.aux, p.photo.data(), so.aux.camera.width, so.aux.camera.height, "photo");
    const ReferenceSample r =
        ReferenceFromStand(m, pe.q_c_from_m, pe.q_c_from_m_cov_rad2, p.enc_az_deg * kDegToRad, p.enc_el_deg * kDegToRad,
                           p.enc_rot_deg * kDegToRad, so.encoder_sigma_arcsec * kArcsecToRad, p.t_s);
    AttitudeSample a;
    a.t_s = r.t_s, a.q = r.q_inertial_from_sensor, a.sigma_cross_rad = r.sigma_cross_rad,
    a.sigma_roll_rad = r.sigma_roll_rad;
    a.common_sigma_cross_rad = r.common_sigma_cross_rad, a.common_sigma_roll_rad = r.common_sigma_roll_rad;
    reference.push_back(a);
  }
  CompareOptions co;
  co.requirement_arcsec = 10;
  const CompareResult c = CompareAttitudes(reference, computed, co);
  const Vec3 truth = RotationVector(s.q_mis);
  std::printf(
      "misalignment truth %.1f %.1f %.1f arcsec, estimate %.1f %.1f %.1f +/- %.1f %.1f %.1f; residual RMS cross %.2f "
      "roll %.2f arcsec; stated sigma cross %.2f roll %.2f; chi2/dof %.2f\n",
      truth.x() * kRadToArcsec, truth.y() * kRadToArcsec, truth.z() * kRadToArcsec,
      c.misalignment_rad.x() * kRadToArcsec, c.misalignment_rad.y() * kRadToArcsec,
      c.misalignment_rad.z() * kRadToArcsec, c.misalignment_sigma_rad.x() * kRadToArcsec,
      c.misalignment_sigma_rad.y() * kRadToArcsec, c.misalignment_sigma_rad.z() * kRadToArcsec,
      c.rms_cross_rad * kRadToArcsec, c.roll.rms * kRadToArcsec, c.mean_sigma_cross_rad * kRadToArcsec,
      c.mean_sigma_roll_rad * kRadToArcsec, c.chi2_per_dof);
  for (int k = 0; k < 3; ++k)
    EXPECT_LT(std::abs(c.misalignment_rad(k) - truth(k)), 3 * c.misalignment_sigma_rad(k)) << "axis " << k;
  // The uncertainty is meaningful: well below the misalignment itself (a few arcmin).
  EXPECT_LT(c.misalignment_sigma_rad.head<2>().maxCoeff() * kRadToArcsec, 10.0);
  // Residuals consistent with the stated (tracker + reference) accuracy: chi-square(15)/15 within its
  // 99.9% range [0.25, 2.5].
  EXPECT_GT(c.chi2_per_dof, 0.25);
  EXPECT_LT(c.chi2_per_dof, 2.5);
  EXPECT_TRUE(c.pass) << c.verdict;
}

}  // namespace
}  // namespace ssiu
