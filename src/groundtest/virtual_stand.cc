#include "groundtest/virtual_stand.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/attitude.h"
#include "core/error.h"
#include "core/rng.h"

namespace ssiu {

void TrackerViewOptions::Check() const {
  detector.Check();
  if (!(stray_gradient >= 0 && stray_gradient < 1))
    throw InputError("tracker view", "stray_gradient must be in [0, 1)");
  if (!(stray_glow_e_per_s >= 0)) throw InputError("tracker view", "stray_glow_e_per_s must be >= 0");
}

void PhotoOptions::Check() const {
  if (!(noise_dn >= 0) || !(blur_px >= 0) || supersample < 1 || supersample > 4)
    throw InputError("photo options", "noise_dn, blur_px >= 0 and supersample in 1..4");
}

void StandSimOptions::Check() const {
  if (positions < 1 || positions > 10000) throw InputError("stand options", "positions must be in 1..10000");
  if (!(step_s > 0)) throw InputError("stand options", "step_s must be > 0");
  if (!(max_angle_deg >= 0 && max_angle_deg < 10))
    throw InputError("stand options", "max_angle_deg must be in [0, 10)");
  if (!misalignment_arcmin.allFinite() || misalignment_arcmin.norm() > 600)
    throw InputError("stand options", "misalignment_arcmin must be finite and below 10 deg");
  if (!(encoder_sigma_arcsec >= 0)) throw InputError("stand options", "encoder_sigma_arcsec must be >= 0");
  // The plate sits in a holder: a shift of 10 mm or a turn of 10 deg is a setup error (and NaN gave
  // a NaN plate pose and pictures of nothing, exit 0).
  if (!(std::abs(plate_shift_mm) <= 10)) throw InputError("stand options", "plate_shift_mm must be within +-10 mm");
  if (!(std::abs(plate_turn_deg) <= 10)) throw InputError("stand options", "plate_turn_deg must be within +-10 deg");
  view.Check();
  photo.Check();
}

Json AuxCameraToJson(const AuxCamera& a) {
  Json r = Json::array();
  for (int i = 0; i < 3; ++i) r.push_back({a.r_aux_from_c(i, 0), a.r_aux_from_c(i, 1), a.r_aux_from_c(i, 2)});
  return {{"camera", CameraToJson(a.camera)},
          {"r_aux_from_c", r},
          {"t_aux_mm", {a.t_aux_mm.x(), a.t_aux_mm.y(), a.t_aux_mm.z()}}};
}

AuxCamera AuxCameraFromJson(const Json& j, const std::string& src) {
  AuxCamera a;
  if (!j.is_object() || !j.contains("camera")) throw InputError(src, "camera: missing (aux camera file)");
  CheckKeys(j, {"camera", "r_aux_from_c", "t_aux_mm"}, src);
  a.camera = CameraFromJson(j["camera"], src + ": camera");
  if (!j.contains("r_aux_from_c") || !j["r_aux_from_c"].is_array() || j["r_aux_from_c"].size() != 3)
    throw InputError(src, "r_aux_from_c: missing or not a 3x3 matrix");
  for (int i = 0; i < 3; ++i) {
    const Json& row = j["r_aux_from_c"][i];
    if (!row.is_array() || row.size() != 3) throw InputError(src, "r_aux_from_c: not a 3x3 matrix");
    for (int k = 0; k < 3; ++k) {
      if (!row[k].is_number()) throw InputError(src, "r_aux_from_c: must hold numbers");
      a.r_aux_from_c(i, k) = row[k];
    }
  }
  if ((a.r_aux_from_c * a.r_aux_from_c.transpose() - Mat3::Identity()).norm() > 1e-6 ||
      a.r_aux_from_c.determinant() < 0)
    throw InputError(src, "r_aux_from_c: not a rotation matrix");
  if (!j.contains("t_aux_mm") || !j["t_aux_mm"].is_array() || j["t_aux_mm"].size() != 3)
    throw InputError(src, "t_aux_mm: missing or not [x,y,z]");
  for (int k = 0; k < 3; ++k) {
    if (!j["t_aux_mm"][k].is_number()) throw InputError(src, "t_aux_mm: must hold numbers");
    a.t_aux_mm(k) = j["t_aux_mm"][k];
  }
  return a;
}

AuxCamera LoadAuxCamera(const std::string& path) { return AuxCameraFromJson(ReadJsonFile(path), path); }

StandSimulation SimulateStand(const Mask& m, const StandSimOptions& o, uint64_t seed) {
  o.Check();
  Rng rng(seed * 1000003 + 11);
  StandSimulation s;
  s.q_mis = QuatFromRotationVector(o.misalignment_arcmin * (kDegToRad / 60.0));
  s.plate.t_c_mm = Vec3(o.plate_shift_mm, -0.6 * o.plate_shift_mm, 0);
  s.plate.r_c_from_p = Eigen::AngleAxisd(o.plate_turn_deg * kDegToRad, Vec3::UnitZ()).toRotationMatrix();
  s.q_c_from_m = MaskRotation(m, s.plate);
  const double enc = o.encoder_sigma_arcsec / 3600.0;
  // The plate does not move in the camera: one scene, each picture's noise of its own.
  const std::vector<float> scene = RenderAuxScene(m, s.plate, o.aux, o.photo, seed * 104729);
  for (int i = 0; i < o.positions; ++i) {
    StandPicture p;
    p.t_s = i * o.step_s;
    if (o.slew) {
      const double f = o.positions > 1 ? 2.0 * i / (o.positions - 1) - 1 : 0.0;  // -1 .. 1
      p.az_deg = f * o.max_angle_deg;
      p.el_deg = 0.5 * f * o.max_angle_deg;
    } else if (i > 0) {  // the first picture at the stand's zero
      p.az_deg = rng.Uniform(-o.max_angle_deg, o.max_angle_deg);
      p.el_deg = rng.Uniform(-o.max_angle_deg, o.max_angle_deg);
      p.rot_deg = rng.Uniform(-3 * o.max_angle_deg, 3 * o.max_angle_deg);
    }
    p.enc_az_deg = p.az_deg + enc * rng.Normal();
    p.enc_el_deg = p.el_deg + enc * rng.Normal();
    p.enc_rot_deg = p.rot_deg + enc * rng.Normal();
    p.q_c_from_s = StandRotation(p.az_deg * kDegToRad, p.el_deg * kDegToRad, p.rot_deg * kDegToRad) * s.q_mis;
    p.q_true = (m.q_design * s.q_c_from_m.conjugate() * p.q_c_from_s).normalized();
    p.frame = RenderTrackerView(m, s.plate, p.q_c_from_s, o.view, seed * 7919 + i, &p.stars);
    p.photo = AddPhotoNoise(scene, o.photo, seed * 104729 + i);
    s.pictures.push_back(std::move(p));
  }
  return s;
}

std::vector<uint8_t> AddPhotoNoise(const std::vector<float>& scene, const PhotoOptions& o, uint64_t seed) {
  o.Check();
  Rng rng(seed * 6364136223846793005ULL + 3);
  std::vector<uint8_t> out(scene.size());
  for (size_t i = 0; i < scene.size(); ++i)
    out[i] = static_cast<uint8_t>(std::clamp(std::round(scene[i] + o.noise_dn * rng.Normal()), 0.0, 255.0));
  return out;
}

std::vector<uint8_t> RenderAuxPhoto(const Mask& m, const PlatePose& pose, const AuxCamera& aux, const PhotoOptions& o,
                                    uint64_t seed) {
  return AddPhotoNoise(RenderAuxScene(m, pose, aux, o, seed), o, seed);
}

Json StandSimulation::TruthJson(const Mask& m) const {
  Json j;
  const Vec3 mis = RotationVector(q_mis) * (kRadToDeg * 60.0);
  j["misalignment_arcmin"] = {mis.x(), mis.y(), mis.z()};
  const auto qm = ToWxyz(q_mis);
  j["q_mis"] = {qm[0], qm[1], qm[2], qm[3]};
  j["plate_t_c_mm"] = {plate.t_c_mm.x(), plate.t_c_mm.y(), plate.t_c_mm.z()};
  const Vec3 pr = RotationVector(Quat(plate.r_c_from_p)) * kRadToDeg;
  j["plate_rotation_deg"] = {pr.x(), pr.y(), pr.z()};
  const Vec3 cm = RotationVector(q_c_from_m) * kRadToArcsec;
  j["mask_rotation_arcsec"] = {cm.x(), cm.y(), cm.z()};
  Json pics = Json::array();
  for (const auto& p : pictures) {
    const auto q = ToWxyz(p.q_true);
    pics.push_back({{"t_s", p.t_s},
                    {"az_deg", p.az_deg},
                    {"el_deg", p.el_deg},
                    {"rot_deg", p.rot_deg},
                    {"q_true", {q[0], q[1], q[2], q[3]}},
                    {"stars_in_view", p.stars.size()}});
  }
  j["pictures"] = pics;
  j["design"] = {{"ra_deg", m.ra_deg}, {"dec_deg", m.dec_deg}, {"roll_deg", m.roll_deg}};
  return j;
}

}  // namespace ssiu
