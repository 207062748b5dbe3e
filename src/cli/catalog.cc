// `ssiu catalog build`: source catalog -> epoch, merged doubles, triangle index for a FOV -> DIR.
#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/json.h"
#include "identify/star_catalog.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string source, out;
  CatalogBuildOptions build;
};

SSIU_REGISTER_COMMAND(catalog, [](CLI::App& root) {
  auto* cat = GetOrAddSubcommand(root, "catalog", "Star catalogs for the star tracker");
  auto* cmd = cat->add_subcommand("build", "Build the solver catalog (stars at an epoch + triangle index) for a FOV");
  auto o = std::make_shared<Opts>();
  cmd->add_option(
      "--source", o->source,
      "Source catalog: xplanet BSC text, binary BSC5, or KStars stars.dat (default: by FOV, BSC above 10 deg)");
  cmd->add_option("--mag-max", o->build.mag_max, "Faintest magnitude kept (0 = chosen from the FOV)");
  cmd->add_option("--epoch", o->build.epoch_year, "Epoch (year) for proper motion")->capture_default_str();
  cmd->add_option("--fov-deg", o->build.fov_deg, "Horizontal field of view (deg); with --fov-min-deg the largest")
      ->required();
  cmd->add_option(
      "--fov-min-deg", o->build.fov_min_deg,
      "Unknown FOV (solve --fov-range-deg MIN,MAX): the smallest FOV served (stars for it, triangles up to --fov-deg)");
  cmd->add_option("--double-arcsec", o->build.double_star_arcsec,
                  "Merge stars closer than this (0 = 3 px of a 1024-px sensor)");
  cmd->add_option("--pattern-stars", o->build.pattern_stars_per_fov, "Pattern stars per half-FOV cap")
      ->capture_default_str();
  cmd->add_option("--neighbours", o->build.pattern_neighbours,
                  "Triangles per pattern star: among its K nearest pattern neighbours (0 = all in the FOV)")
      ->capture_default_str();
  cmd->add_option("--bright-neighbours", o->build.pattern_bright_neighbours,
                  "And among its B brightest pattern neighbours in the FOV beyond those K")
      ->capture_default_str();
  cmd->add_option("--out", o->out, "Output directory")->required();
  cmd->callback([o] {
    const std::string src = o->source.empty() ? DefaultSourceFor(o->build.FovMinDeg()) : o->source;
    const SolverCatalog c = BuildSolverCatalog(LoadSourceCatalog(src), o->build);
    SaveSolverCatalog(c, o->out);
    std::cerr << "catalog: " << c.stars.size() << " stars to V " << c.mag_max << " from " << src << ", "
              << c.num_pattern_stars << " pattern stars, " << c.triangles.size() << " triangles ("
              << c.IndexBytes() / 1e6 << " MB index), " << c.build_time_s << " s -> " << o->out << "\n";
  });
});

}  // namespace
}  // namespace ssiu::cli
