// `--aem FILE` and `--acm FILE`, shared by the subcommands that produce an attitude history (`fuse`,
// `run`, `track`, batch `solve`): CCSDS ADM 2.0 outputs, KVN, or XML when the name ends in .xml.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "ccsds/adm.h"

namespace ssiu::cli {

struct AdmFlags {
  std::string aem, acm;
  bool given() const { return !aem.empty() || !acm.empty(); }
};

// `what` the history ("the fused attitude"), `acm_adds` what the ACM carries besides the attitude.
void AddAdmFlags(CLI::App* cmd, AdmFlags* f, const std::string& what, const std::string& acm_adds);

// Writes the messages asked for (nothing when neither flag is given).
void WriteAdmOutputs(const AdmFlags& f, const AttitudeHistory& h);

}  // namespace ssiu::cli
