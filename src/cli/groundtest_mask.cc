// `ssiu groundtest mask`: the star-sky mask for a collimator ground test (groundtest/mask.h).
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>

#include "attitude/star_solver.h"
#include "cli/command.h"
#include "core/attitude.h"
#include "core/error.h"
#include "groundtest/mask.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string camera, catalog, out, source;
  double ra_deg = 0, dec_deg = 0, roll_deg = 0, dpi = 600;
  MaskOptions mask;
};

SSIU_REGISTER_COMMAND(groundtest_mask, [](CLI::App& root) {
  auto* gt = GetOrAddSubcommand(root, "groundtest", "Star-tracker ground test: mask, reference, compare, simulate");
  auto* cmd =
      gt->add_subcommand("mask", "Design the star-sky mask plate for a collimator (mask.json, mask.svg, mask.png)");
  auto o = std::make_shared<Opts>();
  cmd->add_option("--camera", o->camera, "Tracker camera.json")->required();
  cmd->add_option("--collimator-focal-mm", o->mask.collimator_focal_mm, "Collimator focal length (mm)")->required();
  cmd->add_option("--ra-deg", o->ra_deg, "Design boresight right ascension")->required();
  cmd->add_option("--dec-deg", o->dec_deg, "Design boresight declination")->required();
  cmd->add_option("--roll-deg", o->roll_deg, "Design roll")->capture_default_str();
  cmd->add_option("--mag-max", o->mask.mag_max, "Faintest star drilled (0 = the solver catalog's limit)");
  cmd->add_option("--margin-deg", o->mask.margin_deg, "Star field beyond the FOV on each side")->capture_default_str();
  cmd->add_option("--hole-min-mm", o->mask.hole_min_diameter_mm,
                  "Hole diameter of the faintest star (0 = 0.2 pixel footprint)");
  cmd->add_option("--hole-max-mm", o->mask.hole_max_diameter_mm, "Largest hole (0 = 2 pixel footprints)");
  cmd->add_option("--tag-size-mm", o->mask.tag_size_mm, "Fiducial black-square side (0 = 12% of the field)");
  cmd->add_option("--first-tag-id", o->mask.first_tag_id, "tag36h11 ids first..first+7")->capture_default_str();
  cmd->add_flag("--predistort", o->mask.compensate_distortion,
                "Pre-distort the holes for a tracker that does not model its lens distortion (camera.json's)");
  cmd->add_option("--dpi", o->dpi, "Resolution of mask.png")->capture_default_str();
  cmd->add_option("--catalog", o->catalog, "Solver catalog directory (default: cache)");
  cmd->add_option("--source", o->source, "Source catalog when it is built (default: by FOV)");
  cmd->add_option("--out", o->out, "Output directory")->required();
  cmd->callback([o] {
    if (!std::isfinite(o->ra_deg) || !std::isfinite(o->roll_deg) || !(std::abs(o->dec_deg) <= 90))
      throw InputError("groundtest mask", "--ra-deg and --roll-deg must be finite, --dec-deg in [-90, 90]");
    const Camera cam = LoadCamera(o->camera);
    const StarIdentifier id = MakeIdentifierForCamera(o->catalog, cam, 0.0, 0.0, o->source);
    const Quat q = QuatFromRaDecRoll(o->ra_deg * kDegToRad, o->dec_deg * kDegToRad, o->roll_deg * kDegToRad);
    const Mask m = DesignMask(cam, id.catalog().stars, q, o->mask);
    std::error_code ec;
    std::filesystem::create_directories(o->out, ec);
    if (ec) throw InputError(o->out, "cannot create the output directory");
    WriteMaskPng(m, o->out + "/mask.png", o->dpi);  // first: it is the one that can refuse (--dpi)
    Json j = MaskToJson(m);
    j["png_dpi"] = o->dpi;  // mask.png's scale (PNG carries no DPI tag here)
    WriteJsonFile(o->out + "/mask.json", j);
    WriteMaskSvg(m, o->out + "/mask.svg");
    std::cerr << "mask: " << m.holes.size() << " holes (" << m.clamped_holes << " clamped at " << m.hole_max_diameter_mm
              << " mm), " << m.tags.size() << " " << m.tag_family << " fiducials, plate " << 2 * m.plate_half_mm
              << " mm square; mask.png at " << o->dpi << " dpi\n";
  });
});

}  // namespace
}  // namespace ssiu::cli
