// `ssiu groundtest reference`: reference quaternions per picture from fiducial photos (AprilTag + PnP)
// and/or stand encoder angles (groundtest/reference.h).
#include <cmath>
#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/csv.h"
#include "core/error.h"
#include "groundtest/reference.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string mask, encoders, aux, camera, out, json;
  std::vector<std::string> photos;
  double encoder_sigma_arcsec = 2.0;
  FiducialOptions fid;
};

Json PoseJson(const std::string& photo, const PlatePoseEstimate& e) {
  const Vec3 cm = RotationVector(e.q_c_from_m) * kRadToArcsec;
  return {
      {"photo", photo},
      {"tags", e.tag_ids},
      {"plate_t_c_mm", {e.pose.t_c_mm.x(), e.pose.t_c_mm.y(), e.pose.t_c_mm.z()}},
      {"mask_rotation_arcsec", {cm.x(), cm.y(), cm.z()}},
      {"mask_rotation_sigma_arcsec",
       {std::sqrt(e.q_c_from_m_cov_rad2(0, 0)) * kRadToArcsec, std::sqrt(e.q_c_from_m_cov_rad2(1, 1)) * kRadToArcsec,
        std::sqrt(e.q_c_from_m_cov_rad2(2, 2)) * kRadToArcsec}},
      {"mask_rotation_noise_sigma_arcsec",
       {std::sqrt(e.q_c_from_m_noise_cov_rad2(0, 0)) * kRadToArcsec,
        std::sqrt(e.q_c_from_m_noise_cov_rad2(1, 1)) * kRadToArcsec,
        std::sqrt(e.q_c_from_m_noise_cov_rad2(2, 2)) * kRadToArcsec}},
      {"refined_tags", e.refined_tags},
      {"pixel_noise_dn", e.pixel_noise_dn},
      {"measured_pixel_noise_dn", e.measured_pixel_noise_dn},
      {"predicted_corner_sigma_px", e.predicted_corner_sigma_px},
      {"corner_sigma_px", e.corner_sigma_px},
      {"corner_chi2_per_dof", e.corner_chi2_per_dof},
      {"rms_reprojection_px", e.rms_reprojection_px}};
}

SSIU_REGISTER_COMMAND(groundtest_reference, [](CLI::App& root) {
  auto* gt = GetOrAddSubcommand(root, "groundtest", "Star-tracker ground test: mask, reference, compare, simulate");
  auto* cmd =
      gt->add_subcommand("reference", "Reference quaternion per picture from fiducial photos and/or stand encoders");
  auto o = std::make_shared<Opts>();
  cmd->add_option("--mask", o->mask, "mask.json")->required();
  cmd->add_option("--encoders", o->encoders, "Stand encoder CSV t_s,az_deg,el_deg,rot_deg");
  cmd->add_option("--encoder-sigma-arcsec", o->encoder_sigma_arcsec, "Encoder noise per axis")->capture_default_str();
  cmd->add_option("--photos", o->photos, "Aux-camera photos of the plate: one, or one per encoder row");
  cmd->add_option("--aux-camera", o->aux, "Aux camera JSON (camera + pose in the collimator frame)");
  cmd->add_option("--camera", o->camera, "Tracker camera.json: checked against the mask's");
  cmd->add_option("--min-tags", o->fid.min_tags, "Fewest fiducials for a pose")->capture_default_str();
  cmd->add_option("--pixel-noise-dn", o->fid.pixel_noise_dn,
                  "Photo pixel noise (8-bit counts); 0 = measured from the tag edge fits")
      ->capture_default_str();
  cmd->add_option("--out", o->out, "Reference CSV t_s,qw,qx,qy,qz,sigma_cross_arcsec,sigma_roll_arcsec")->required();
  cmd->add_option("--json", o->json, "Per-photo plate poses (JSON, - for stdout)");
  cmd->callback([o] {
    const Mask m = LoadMask(o->mask);
    if (!o->camera.empty()) CheckMaskCamera(m, LoadCamera(o->camera), o->mask);
    if (o->encoders.empty() && o->photos.empty())
      throw InputError("groundtest reference", "give --encoders and/or --photos");
    if (!(o->encoder_sigma_arcsec >= 0) || !std::isfinite(o->encoder_sigma_arcsec))
      throw InputError("--encoder-sigma-arcsec", "must be a finite number >= 0");
    std::vector<double> t, az, el, rot;
    if (!o->encoders.empty()) {
      const CsvTable c = ReadCsv(o->encoders);
      if (c.rows() < 1) throw InputError(o->encoders, "no data rows");
      c.CheckIncreasing("t_s");
      t = c.Column("t_s"), az = c.Column("az_deg"), el = c.Column("el_deg"), rot = c.Column("rot_deg");
      // A stand turns within a turn either way; 1e300 deg gave finite but meaningless references.
      for (const auto* col : {&az, &el, &rot})
        for (size_t i = 0; i < col->size(); ++i)
          if (std::abs((*col)[i]) > 360)
            throw InputError(o->encoders, "row " + std::to_string(i + 1) + ": encoder angle beyond +-360 deg");
    } else {
      for (size_t i = 0; i < o->photos.size(); ++i)
        t.push_back(static_cast<double>(i)), az.push_back(0), el.push_back(0), rot.push_back(0);
    }
    const size_t n = t.size();
    if (!o->photos.empty() && o->photos.size() != 1 && o->photos.size() != n)
      throw InputError("--photos", std::to_string(o->photos.size()) + " photos for " + std::to_string(n) +
                                       " encoder rows (give 1 or " + std::to_string(n) + ")");
    if (!o->photos.empty() && o->aux.empty()) throw InputError("--aux-camera", "required with --photos");
    std::vector<PlatePoseEstimate> poses;
    Json pj = Json::array();
    if (!o->photos.empty()) {
      const AuxCamera aux = LoadAuxCamera(o->aux);
      for (const auto& p : o->photos) {
        poses.push_back(EstimatePlatePoseFromFile(m, aux, p, o->fid));
        pj.push_back(PoseJson(p, poses.back()));
      }
    }
    std::vector<ReferenceSample> ref;
    for (size_t i = 0; i < n; ++i) {
      Quat q_cm = Quat::Identity();
      Mat3 cov = Mat3::Zero();
      if (!poses.empty()) {
        const PlatePoseEstimate& e = poses[poses.size() == 1 ? 0 : i];
        q_cm = e.q_c_from_m, cov = e.q_c_from_m_cov_rad2;
      }
      const double enc = o->encoders.empty() ? 0.0 : o->encoder_sigma_arcsec * kArcsecToRad;
      ref.push_back(
          ReferenceFromStand(m, q_cm, cov, az[i] * kDegToRad, el[i] * kDegToRad, rot[i] * kDegToRad, enc, t[i]));
    }
    WriteReferenceCsv(o->out, ref);
    if (!o->json.empty()) WriteJsonFile(o->json, Json{{"plate_poses", pj}, {"pictures", n}});
    std::cerr << n << " reference quaternions ("
              << (o->photos.empty()     ? "encoders, nominal plate"
                  : o->encoders.empty() ? "photos, stand at zero"
                                        : "photos + encoders")
              << ") -> " << o->out << "\n";
  });
});

}  // namespace
}  // namespace ssiu::cli
