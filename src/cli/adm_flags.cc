#include "cli/adm_flags.h"

namespace ssiu::cli {

void AddAdmFlags(CLI::App* cmd, AdmFlags* f, const std::string& what, const std::string& acm_adds) {
  cmd->add_option(
      "--aem", f->aem,
      "CCSDS attitude ephemeris message (ADM 2.0 AEM) of " + what + "; KVN, XML when the name ends in .xml");
  cmd->add_option("--acm", f->acm,
                  "CCSDS attitude comprehensive message (ADM 2.0 ACM) of " + what + " with " + acm_adds +
                      "; KVN, XML when the name ends in .xml");
}

void WriteAdmOutputs(const AdmFlags& f, const AttitudeHistory& h) {
  if (!f.aem.empty()) WriteAdmFile(f.aem, h, AdmMessage::kAem);
  if (!f.acm.empty()) WriteAdmFile(f.acm, h, AdmMessage::kAcm);
}

}  // namespace ssiu::cli
