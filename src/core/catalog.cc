#include "core/catalog.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "core/attitude.h"
#include "core/error.h"

namespace ssiu {

std::string DefaultBscPath() {
  const char* env = std::getenv("SSIU_BSC");
  return env && *env ? env : "/usr/share/xplanet/stars/BSC";
}

StarCatalog LoadXplanetBsc(const std::string& path, double mag_max) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot open star catalog (install xplanet: apt-get install xplanet)");
  StarCatalog cat;
  cat.source = path;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    // Name is quoted and may contain spaces: take the numbers before and after it.
    const auto q1 = line.find('"'), q2 = line.rfind('"');
    if (q1 == std::string::npos || q2 == q1)
      throw InputError(path, "line " + std::to_string(line_no) + ": no quoted name");
    std::istringstream head(line.substr(0, q1)), tail(line.substr(q2 + 1));
    double dec_deg = 0, ra_h = 0, mag = 0;
    long hr = 0;
    if (!(head >> dec_deg >> ra_h >> mag) || !(tail >> hr)) {
      throw InputError(path, "line " + std::to_string(line_no) + ": expected Dec RA Mag \"Name\" HR");
    }
    if (mag > mag_max) continue;
    CatalogStar s;
    s.id = static_cast<StarId>(hr);
    s.ra_rad = ra_h * 15.0 * kDegToRad;
    s.dec_rad = dec_deg * kDegToRad;
    s.mag = mag;
    s.unit = UnitFromRaDec(s.ra_rad, s.dec_rad);
    cat.stars.push_back(s);
  }
  if (cat.stars.empty()) throw InputError(path, "no stars read");
  std::stable_sort(cat.stars.begin(), cat.stars.end(),
                   [](const CatalogStar& a, const CatalogStar& b) { return a.mag < b.mag; });
  return cat;
}

}  // namespace ssiu
