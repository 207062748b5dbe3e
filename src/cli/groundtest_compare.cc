// `ssiu groundtest compare`: reference vs tracker quaternions (groundtest/compare.h).
#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/types.h"
#include "groundtest/compare.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string reference, computed, json = "-", plot;
  CompareOptions compare;
  bool keep = false;
};

SSIU_REGISTER_COMMAND(groundtest_compare, [](CLI::App& root) {
  auto* gt = GetOrAddSubcommand(root, "groundtest", "Star-tracker ground test: mask, reference, compare, simulate");
  auto* cmd =
      gt->add_subcommand("compare", "Compare reference and tracker quaternions: misalignment, RMS, drift, verdict");
  auto o = std::make_shared<Opts>();
  cmd->add_option("--reference", o->reference,
                  "Reference CSV t_s,qw,qx,qy,qz[,sigma_cross_arcsec,sigma_roll_arcsec], or a CCSDS AEM/ACM")
      ->required();
  cmd->add_option("--computed", o->computed,
                  "Tracker CSV t_s,qw,qx,qy,qz[,sigma_cross_arcsec,sigma_roll_arcsec], or a CCSDS AEM/ACM")
      ->required();
  cmd->add_option("--json", o->json, "Output JSON, - for stdout")->capture_default_str();
  cmd->add_option("--plot", o->plot, "Directory for errors.png and residuals.png");
  cmd->add_option("--requirement-arcsec", o->compare.requirement_arcsec, "Cross-boresight RMS requirement")
      ->capture_default_str();
  cmd->add_option("--roll-requirement-arcsec", o->compare.roll_requirement_arcsec,
                  "Roll RMS requirement (0 = 8x cross)");
  cmd->add_option("--time-tolerance-s", o->compare.time_tolerance_s, "Pairing tolerance")->capture_default_str();
  cmd->add_flag("--keep-misalignment", o->keep, "Do not estimate and remove a fixed misalignment");
  cmd->callback([o] {
    CompareOptions co = o->compare;
    co.remove_misalignment = !o->keep;
    std::string epoch_utc;  // CCSDS messages: both on the reference's time axis
    const std::vector<AttitudeSample> reference = ReadAttitudeSeries(o->reference, &epoch_utc);
    const CompareResult r = CompareAttitudes(reference, ReadAttitudeSeries(o->computed, &epoch_utc), co, o->computed);
    WriteJsonFile(o->json, CompareResultToJson(r));
    if (!o->plot.empty()) WriteComparePlots(r, o->plot);
    std::cerr << r.pictures << " pictures; misalignment " << r.misalignment_rad.x() * kRadToArcsec << ", "
              << r.misalignment_rad.y() * kRadToArcsec << ", " << r.misalignment_rad.z() * kRadToArcsec << " arcsec; "
              << r.verdict << "\n";
  });
});

}  // namespace
}  // namespace ssiu::cli
