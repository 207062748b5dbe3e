#include "identify/star_catalog.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <memory>
#include <sstream>
#include <unordered_set>

#include "core/astrometry.h"
#include "core/attitude.h"
#include "core/error.h"
#include "core/json.h"
#include "core/output.h"
#include "identify/catalog_index.h"
#include "identify/sky_grid.h"

namespace ssiu {
namespace {

constexpr double kMasToRad = kArcsecToRad / 1000.0;
// 2: triangles as vertices only; 3: per-star proper motion (rad/yr) after the magnitude; 4: stars'
// unit vectors, triangles' features and the search index stored as used (nothing rebuilt at load);
// 5: every table from an 8-byte boundary, each star a record laid out as CatalogStar is in memory
// (id, 4 zero bytes, ra, dec, mag, unit vector, proper motion), so that a blob in ROM is searched
// where it lies (ParseSolverCatalog's in_place).
constexpr char kMagic[8] = {'S', 'S', 'I', 'U', 'C', 'A', 'T', '5'};
constexpr char kMagicV4[8] = {'S', 'S', 'I', 'U', 'C', 'A', 'T', '4'};
constexpr char kMagicV3[8] = {'S', 'S', 'I', 'U', 'C', 'A', 'T', '3'};
constexpr size_t kStarRecordBytes = 72;

// Whether this processor lays a CatalogStar out as format 5 stores it (little-endian, no other
// padding): then the stars are viewed in place, else read field by field.
bool StarRecordIsCatalogStar() {
  const uint32_t one = 1;
  unsigned char first = 0;
  std::memcpy(&first, &one, 1);
  const CatalogStar s;
  const char* b = reinterpret_cast<const char*>(&s);
  auto at = [&](const void* p) { return static_cast<const char*>(p) - b; };
  return first == 1 && sizeof(CatalogStar) == kStarRecordBytes && alignof(CatalogStar) <= 8 && at(&s.id) == 0 &&
         at(&s.ra_rad) == 8 && at(&s.dec_rad) == 16 && at(&s.mag) == 24 && at(s.unit.data()) == 32 &&
         at(s.unit.data() + 2) == 48 && at(&s.pm_ra_rad_per_yr) == 56 && at(&s.pm_dec_rad_per_yr) == 64;
}

bool FileExists(const std::string& p) {
  struct stat st;
  return ::stat(p.c_str(), &st) == 0;
}

void MakeDirs(const std::string& dir) {
  std::string cur;
  std::stringstream ss(dir);
  std::string part;
  if (!dir.empty() && dir[0] == '/') cur = "/";
  while (std::getline(ss, part, '/')) {
    if (part.empty()) continue;
    cur += part + "/";
    ::mkdir(cur.c_str(), 0755);
  }
  if (!FileExists(dir)) throw InputError(dir, "cannot create directory");
}

// Flux-weighted merge of b into a (positions as unit vectors; magnitudes combined in flux).
void MergeInto(CatalogStar* a, const CatalogStar& b) {
  const double fa = std::pow(10.0, -0.4 * a->mag), fb = std::pow(10.0, -0.4 * b.mag);
  a->unit = (fa * a->unit + fb * b.unit).normalized();
  RaDecFromUnit(a->unit, &a->ra_rad, &a->dec_rad);
  a->pm_ra_rad_per_yr = (fa * a->pm_ra_rad_per_yr + fb * b.pm_ra_rad_per_yr) / (fa + fb);
  a->pm_dec_rad_per_yr = (fa * a->pm_dec_rad_per_yr + fb * b.pm_dec_rad_per_yr) / (fa + fb);
  a->mag = -2.5 * std::log10(fa + fb);
}

bool LooksLikeBsc5(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  int32_t h[7];
  if (!in.read(reinterpret_cast<char*>(h), sizeof h)) return false;
  return h[0] == 0 && h[1] == 1 && h[6] == 32 && h[2] < 0 && h[2] > -100000;
}

bool LooksLikeKstars(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  for (int i = 0; i < 40 && std::getline(in, line); ++i) {
    if (line.find("Hipparcos") != std::string::npos) return true;
  }
  return false;
}

}  // namespace

void CatalogBuildOptions::Check() const {
  if (!(fov_deg > 0.5 && fov_deg < 90)) throw InputError("catalog options", "fov_deg must be in (0.5, 90)");
  if (!(mag_max >= 0 && mag_max < 20)) throw InputError("catalog options", "mag_max must be in [0, 20) (0 = auto)");
  if (!(epoch_year > 1800 && epoch_year < 2300))
    throw InputError("catalog options", "epoch_year must be in (1800, 2300)");
  // Infinite merged every star into a sky grid cell index that overflowed int.
  if (!(double_star_arcsec >= 0 && double_star_arcsec <= 3600))
    throw InputError("catalog options", "double_star_arcsec must be in [0, 3600]");
  if (pattern_stars_per_fov < 4 || pattern_stars_per_fov > 60)
    throw InputError("catalog options", "pattern_stars_per_fov must be in [4, 60]");
  if (!(stars_per_fov >= 5)) throw InputError("catalog options", "stars_per_fov must be >= 5");
  if (!(min_side_frac >= 0 && min_side_frac < 0.5))
    throw InputError("catalog options", "min_side_frac must be in [0, 0.5)");
  if (pattern_neighbours != 0 && (pattern_neighbours < 2 || pattern_neighbours > 100))
    throw InputError("catalog options", "pattern_neighbours must be 0 (all) or in [2, 100]");
  if (pattern_bright_neighbours < 0 || pattern_bright_neighbours > 100)
    throw InputError("catalog options", "pattern_bright_neighbours must be in [0, 100]");
  if (!(fov_min_deg == 0 || (fov_min_deg > 0.5 && fov_min_deg <= fov_deg)))
    throw InputError("catalog options", "fov_min_deg must be 0 (= fov_deg) or in (0.5, fov_deg]");
}

SourceCatalog LoadBsc5(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open BSC5 file");
  int32_t h[7];
  if (!in.read(reinterpret_cast<char*>(h), sizeof h)) throw InputError(path, "truncated BSC5 header");
  // Header: STAR0, STAR1, STARN (< 0: J2000), STNUM, MPROP, NMAG, NBENT (SAO TDC binary format).
  if (h[2] >= 0 || h[6] != 32 || h[3] != 1 || h[5] != 1) throw InputError(path, "not a J2000 BSC5 binary catalog");
  const int n = -h[2];
  SourceCatalog cat;
  cat.source = path;
  cat.kind = "bsc5";
  cat.has_proper_motion = true;
  for (int i = 0; i < n; ++i) {
    char e[32];
    if (!in.read(e, sizeof e)) throw InputError(path, "truncated at entry " + std::to_string(i + 1));
    float xno, rpm, dpm;
    double ra, dec;
    int16_t mag;
    std::memcpy(&xno, e, 4);
    std::memcpy(&ra, e + 4, 8);
    std::memcpy(&dec, e + 12, 8);
    std::memcpy(&mag, e + 22, 2);
    std::memcpy(&rpm, e + 24, 4);
    std::memcpy(&dpm, e + 28, 4);
    if (ra == 0 && dec == 0) continue;  // the few entries without a position (novae, non-stellar)
    SourceStar s;
    s.star.id = static_cast<StarId>(std::lround(xno));
    s.star.ra_rad = ra;
    s.star.dec_rad = dec;
    s.star.mag = mag / 100.0;
    s.star.unit = UnitFromRaDec(ra, dec);
    s.pm_ra_rad_per_yr = rpm;  // BSC5 pmRA is mu_alpha * cos(dec)
    s.pm_dec_rad_per_yr = dpm;
    cat.stars.push_back(s);
  }
  return cat;
}

SourceCatalog LoadKstarsStars(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot open KStars star catalog (apt-get install kstars-data)");
  SourceCatalog cat;
  cat.source = path;
  cat.kind = "kstars";
  cat.has_proper_motion = true;
  std::string line;
  int row = 0, line_no = 0;
  auto num = [&](size_t pos, size_t len, const char* field) {
    const std::string f = line.substr(pos, len);
    char* end = nullptr;
    const double v = std::strtod(f.c_str(), &end);
    if (end == f.c_str()) throw InputError(path, "line " + std::to_string(line_no) + ": bad " + field + " '" + f + "'");
    return v;
  };
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    ++row;
    if (line.size() < 56)
      throw InputError(path, "line " + std::to_string(line_no) + ": shorter than the fixed-width record");
    // RA hhmmss.ss [0,9), Dec sddmmss.s [10,19), pmRA [20,29), pmDec [29,38) mas/yr, mag [46,51).
    const double ra_h = num(0, 2, "RA") + num(2, 2, "RA") / 60.0 + num(4, 5, "RA") / 3600.0;
    const double dec_abs = num(11, 2, "Dec") + num(13, 2, "Dec") / 60.0 + num(15, 4, "Dec") / 3600.0;
    const double dec_deg = line[10] == '-' ? -dec_abs : dec_abs;
    SourceStar s;
    s.star.id = kKstarsIdOffset + row;
    s.star.ra_rad = ra_h * 15.0 * kDegToRad;
    s.star.dec_rad = dec_deg * kDegToRad;
    s.star.mag = num(46, 5, "mag");
    s.star.unit = UnitFromRaDec(s.star.ra_rad, s.star.dec_rad);
    s.pm_ra_rad_per_yr = num(20, 9, "pmRA") * kMasToRad;
    s.pm_dec_rad_per_yr = num(29, 9, "pmDec") * kMasToRad;
    cat.stars.push_back(s);
  }
  if (cat.stars.empty()) throw InputError(path, "no stars read");
  return cat;
}

SourceCatalog LoadSourceCatalog(const std::string& path) {
  if (!FileExists(path)) throw InputError(path, "star catalog not found");
  if (LooksLikeBsc5(path)) return LoadBsc5(path);
  if (LooksLikeKstars(path)) {
    SourceCatalog k = LoadKstarsStars(path);
    if (FileExists(DefaultBscPath())) AssignHrNumbers(&k, LoadXplanetBsc(DefaultBscPath()));
    return k;
  }
  const StarCatalog bsc = LoadXplanetBsc(path);
  SourceCatalog cat;
  cat.source = path;
  cat.kind = "xplanet_bsc";
  for (const auto& s : bsc.stars) cat.stars.push_back({s, 0, 0});
  return cat;
}

void AssignHrNumbers(SourceCatalog* kstars, const StarCatalog& bsc, double radius_arcsec) {
  const double r = radius_arcsec * kArcsecToRad;
  internal::SkyGrid grid(std::max(r, 1e-4));
  for (size_t i = 0; i < kstars->stars.size(); ++i) grid.Insert(static_cast<int>(i), kstars->stars[i].star.unit);
  for (const auto& b : bsc.stars) {
    int best = -1;
    double best_dm = 1.0;
    grid.ForEachWithin(b.unit, r, [&](int id, const Vec3&) {
      const double dm = std::abs(kstars->stars[id].star.mag - b.mag);
      if (dm < best_dm) best_dm = dm, best = id;
    });
    if (best >= 0 && kstars->stars[best].star.id >= kKstarsIdOffset) kstars->stars[best].star.id = b.id;
  }
}

std::string DefaultSourceFor(double fov_deg) {
  const char* env = std::getenv("SSIU_CATALOG");
  if (env && *env) return env;
  const std::string kstars = "/usr/share/kstars/stars.dat";
  // The BSC holds about 40 stars per field down to ~10 deg; narrower fields need Hipparcos/Tycho.
  if (fov_deg < 10.0 && FileExists(kstars)) return kstars;
  return DefaultBscPath();
}

namespace {

// One level of the pattern index, for a field of fov (rad). Pattern stars: brightest first, at most
// pattern_stars_per_fov in any cap of radius fov/2, so that the sky is covered evenly (tetra3's idea)
// and faint stars fill sparse regions. Triangles of pattern stars whose sides all fit in the FOV:
// with pattern_neighbours = K, those of each pattern star with two of its K nearest pattern
// neighbours, else all (each once: p < j < k); the ones in `seen` (another level, another star's
// neighbours) are skipped, and null = no deduplication needed (all triangles, one level).
void AddPatternLevel(double fov, const CatalogBuildOptions& o, SolverCatalog* cat, std::unordered_set<uint64_t>* seen,
                     std::vector<char>* is_pattern) {
  std::vector<int> pattern;
  {
    internal::SkyGrid grid(fov / 2);
    for (size_t i = 0; i < cat->stars.size(); ++i) {
      int count = 0;
      grid.ForEachWithin(cat->stars[i].unit, fov / 2, [&](int, const Vec3&) { ++count; });
      if (count < o.pattern_stars_per_fov) {
        grid.Insert(static_cast<int>(i), cat->stars[i].unit);
        pattern.push_back(static_cast<int>(i));
        (*is_pattern)[i] = 1;
      }
    }
  }
  internal::SkyGrid grid(fov);
  for (size_t p = 0; p < pattern.size(); ++p) grid.Insert(static_cast<int>(p), cat->stars[pattern[p]].unit);
  const double min_side = o.min_side_frac * fov;
  const double cos_fov = std::cos(fov), cos_min = std::cos(min_side);
  const int k_nb = o.pattern_neighbours;
  std::vector<std::pair<double, int>> nb;
  for (size_t p = 0; p < pattern.size(); ++p) {
    const Vec3& u0 = cat->stars[pattern[p]].unit;
    nb.clear();
    grid.ForEachWithin(u0, fov, [&](int id, const Vec3& u) {
      const double c = u.dot(u0);
      if (id == static_cast<int>(p) || c > cos_min) return;
      if (k_nb > 0 || id > static_cast<int>(p)) nb.push_back({-c, id});
    });
    if (k_nb > 0 && static_cast<int>(nb.size()) > k_nb) {
      std::partial_sort(nb.begin(), nb.begin() + k_nb, nb.end());  // nearest first (largest cosine)
      // Then the brightest of the rest (pattern indices are in brightness order).
      const auto rest = nb.begin() + k_nb;
      const auto n_bright = std::min<ptrdiff_t>(o.pattern_bright_neighbours, nb.end() - rest);
      std::partial_sort(rest, rest + n_bright, nb.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
      nb.resize(static_cast<size_t>(k_nb + n_bright));
    }
    std::sort(nb.begin(), nb.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
    for (size_t j = 0; j < nb.size(); ++j) {
      for (size_t k = j + 1; k < nb.size(); ++k) {
        int idx[3] = {pattern[p], pattern[nb[j].second], pattern[nb[k].second]};
        const Vec3& a = cat->stars[idx[0]].unit;
        const Vec3& b = cat->stars[idx[1]].unit;
        const Vec3& c = cat->stars[idx[2]].unit;
        if (b.dot(c) < cos_fov) continue;
        // Side opposite each vertex.
        const double side[3] = {std::acos(std::min(1.0, b.dot(c))), std::acos(std::min(1.0, a.dot(c))),
                                std::acos(std::min(1.0, a.dot(b)))};
        int ord[3] = {0, 1, 2};
        std::sort(ord, ord + 3, [&](int x, int y) { return side[x] < side[y]; });
        if (side[ord[0]] < min_side) continue;
        if (seen) {
          int key3[3] = {idx[0], idx[1], idx[2]};
          std::sort(key3, key3 + 3);
          const uint64_t key = (static_cast<uint64_t>(key3[0]) << 42) | (static_cast<uint64_t>(key3[1]) << 21) |
                               static_cast<uint64_t>(key3[2]);
          if (!seen->insert(key).second) continue;
        }
        CatalogTriangle t;
        for (int m = 0; m < 3; ++m) t.v[m] = idx[ord[m]];
        t.longest_rad = static_cast<float>(side[ord[2]]);
        t.ratio_a = static_cast<float>(side[ord[0]] / side[ord[2]]);
        t.ratio_b = static_cast<float>(side[ord[1]] / side[ord[2]]);
        cat->triangles.push_back(t);
      }
    }
  }
}

SolverCatalog BuildFromStars(std::vector<CatalogStar> stars, const std::string& source, double epoch,
                             const CatalogBuildOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  o.Check();
  std::stable_sort(stars.begin(), stars.end(),
                   [](const CatalogStar& a, const CatalogStar& b) { return a.mag < b.mag; });
  // Star density (magnitude limit, double separation) for the smallest FOV served.
  const double fov = o.FovMinDeg() * kDegToRad;
  // Magnitude limit: the star count that gives `stars_per_fov` per cap of diameter fov on average.
  double mag_max = o.mag_max;
  if (mag_max <= 0) {
    const double cap_sr = 2 * kPi * (1 - std::cos(fov / 2));
    const size_t n = static_cast<size_t>(o.stars_per_fov * 4 * kPi / cap_sr);
    mag_max = stars.empty() ? 6.0 : stars[std::min(n, stars.size() - 1)].mag;
  }
  // Close doubles: merge (flux-weighted) every fainter star within the separation a tracker cannot
  // resolve into the brighter one; companions down to 2 mag below the limit are merged before the cut.
  const double dbl =
      (o.double_star_arcsec > 0 ? o.double_star_arcsec : o.FovMinDeg() * 3600.0 / 1024.0 * 3.0) * kArcsecToRad;
  {
    std::vector<CatalogStar> kept;
    internal::SkyGrid grid(dbl);
    for (const auto& s : stars) {
      if (s.mag > mag_max + 2.0) break;
      int into = -1;
      grid.ForEachWithin(s.unit, dbl, [&](int id, const Vec3&) {
        if (into < 0) into = id;
      });
      if (into >= 0) {
        MergeInto(&kept[into], s);  // the grid keeps the first position; fine at this separation
      } else {
        grid.Insert(static_cast<int>(kept.size()), s.unit);
        kept.push_back(s);
      }
    }
    stars.clear();
    // Each unit vector made anew from (ra, dec), as they are stored: a loaded catalog is then the
    // built one bit for bit (merging and proper motion leave it a few ulp off).
    for (auto& s : kept) {
      if (s.mag > mag_max) continue;
      s.unit = UnitFromRaDec(s.ra_rad, s.dec_rad);
      stars.push_back(s);
    }
    std::stable_sort(stars.begin(), stars.end(),
                     [](const CatalogStar& a, const CatalogStar& b) { return a.mag < b.mag; });
  }
  SolverCatalog cat;
  cat.source = source;
  cat.epoch_year = epoch;
  cat.fov_deg = o.fov_deg;
  cat.mag_max = mag_max;
  cat.double_star_arcsec = dbl * kRadToArcsec;
  cat.stars = std::move(stars);

  cat.fov_min_deg = o.FovMinDeg();
  cat.pattern_neighbours = o.pattern_neighbours;
  if (cat.stars.size() >= (size_t{1} << 21)) throw InputError(source, "too many stars for the pattern index (2^21)");
  // One level per field of view from fov_min_deg to fov_deg in steps of sqrt(2) (one level for a
  // fixed FOV): a frame of any FOV in the range finds triangles of bright stars spaced for it.
  std::vector<double> levels;
  for (double f = o.FovMinDeg(); f < o.fov_deg * (1 - 1e-9); f *= std::sqrt(2.0)) levels.push_back(f);
  levels.push_back(o.fov_deg);
  std::unordered_set<uint64_t> seen;  // triangles (sorted star indices) already indexed
  std::vector<char> is_pattern(cat.stars.size(), 0);
  const bool dedup = o.pattern_neighbours > 0 || levels.size() > 1;
  for (const double level_deg : levels)
    AddPatternLevel(level_deg * kDegToRad, o, &cat, dedup ? &seen : nullptr, &is_pattern);
  cat.num_pattern_stars = static_cast<int>(std::count(is_pattern.begin(), is_pattern.end(), 1));
  cat.index = std::make_shared<const CatalogIndex>(cat);
  cat.build_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return cat;
}

}  // namespace

SolverCatalog BuildSolverCatalog(const SourceCatalog& source, const CatalogBuildOptions& o) {
  o.Check();
  std::vector<CatalogStar> stars;
  stars.reserve(source.stars.size());
  for (const auto& s : source.stars) {
    CatalogStar c = s.star;
    if (source.has_proper_motion) {
      // Positions brought from J2000.0 to the catalog epoch; the proper motion is kept so that a
      // solve can bring them on to the frame's date (core/astrometry.h).
      c.pm_ra_rad_per_yr = s.pm_ra_rad_per_yr;
      c.pm_dec_rad_per_yr = s.pm_dec_rad_per_yr;
      c.unit = PropagateProperMotion(c, 2000.0, o.epoch_year);
      RaDecFromUnit(c.unit, &c.ra_rad, &c.dec_rad);
    }
    stars.push_back(c);
  }
  return BuildFromStars(std::move(stars), source.source, source.has_proper_motion ? o.epoch_year : 2000.0, o);
}

SolverCatalog BuildSolverCatalog(const StarCatalog& stars, const CatalogBuildOptions& o) {
  return BuildFromStars(stars.stars, stars.source, stars.epoch_year, o);
}

std::string SolverCatalogBytes(const SolverCatalog& cat) {
  std::ostringstream out(std::ios::binary);
  auto put = [&](const void* p, size_t n) { out.write(static_cast<const char*>(p), static_cast<std::streamsize>(n)); };
  put(kMagic, 8);
  const double hdr[5] = {cat.epoch_year, cat.fov_deg, cat.mag_max, cat.double_star_arcsec, cat.build_time_s};
  put(hdr, sizeof hdr);
  const int64_t counts[4] = {static_cast<int64_t>(cat.stars.size()), static_cast<int64_t>(cat.triangles.size()),
                             cat.num_pattern_stars, cat.pattern_neighbours};
  put(counts, sizeof counts);
  const int64_t slen = static_cast<int64_t>(cat.source.size());
  put(&slen, 8);
  put(cat.source.data(), cat.source.size());
  const char zeros[8] = {0};
  put(zeros, (8 - cat.source.size() % 8) % 8);
  for (const auto& s : cat.stars) {
    const double d[8] = {s.ra_rad,   s.dec_rad,  s.mag,           s.unit[0],
                         s.unit[1], s.unit[2], s.pm_ra_rad_per_yr, s.pm_dec_rad_per_yr};
    put(&s.id, sizeof s.id);
    put(zeros, 4);
    put(d, sizeof d);
  }
  for (const auto& t : cat.triangles) {
    const float f[3] = {t.longest_rad, t.ratio_a, t.ratio_b};
    put(t.v.data(), sizeof t.v);
    put(f, sizeof f);
  }
  std::string index;
  const auto ix = cat.index && cat.index->Fits(cat) ? cat.index : std::make_shared<const CatalogIndex>(cat);
  ix->Write(&index);
  put(index.data(), index.size());
  return out.str();
}

void SaveSolverCatalog(const SolverCatalog& cat, const std::string& dir) {
  MakeDirs(dir);
  // meta.json goes first and comes back last: a directory without it is a build in progress (or
  // killed), never a catalog, and its checksum ties it to this very catalog.bin.
  std::remove((dir + "/meta.json").c_str());
  const std::string bin = SolverCatalogBytes(cat);
  WriteFileAtomic(dir + "/catalog.bin", bin);
  WriteFileAtomic(dir + "/stars.csv", [&](std::ostream& csv) {
    csv << "star_id,ra_deg,dec_deg,mag,pm_ra_mas_per_yr,pm_dec_mas_per_yr\n" << std::setprecision(10);
    for (const auto& s : cat.stars)
      csv << s.id << ',' << s.ra_rad * kRadToDeg << ',' << s.dec_rad * kRadToDeg << ',' << s.mag << ','
          << s.pm_ra_rad_per_yr * kRadToArcsec * 1000 << ',' << s.pm_dec_rad_per_yr * kRadToArcsec * 1000 << '\n';
  });
  Json meta = {{"source", cat.source},
               {"epoch_year", cat.epoch_year},
               {"fov_deg", cat.fov_deg},
               {"fov_min_deg", cat.fov_min_deg > 0 ? cat.fov_min_deg : cat.fov_deg},
               {"mag_max", cat.mag_max},
               {"double_star_arcsec", cat.double_star_arcsec},
               {"stars", cat.stars.size()},
               {"pattern_stars", cat.num_pattern_stars},
               {"triangles", cat.triangles.size()},
               {"pattern_neighbours", cat.pattern_neighbours},
               {"index_bytes", cat.IndexBytes()},
               {"build_time_s", cat.build_time_s},
               {"catalog_bin_bytes", bin.size()},
               {"catalog_bin_crc32", Crc32(bin.data(), bin.size())}};
  WriteJsonFile(dir + "/meta.json", meta);
}

namespace {

// catalog.bin mapped read-only: the CRC and the parse read the page cache itself (no zeroed buffer,
// no copy: ~1 ms of a 3 MB catalog's load). A writer replaces the file by rename (core/output.h), so the
// mapped bytes cannot change under us.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw InputError(path, "missing");
    struct stat st;
    if (::fstat(fd, &st) != 0) {
      ::close(fd);
      throw InputError(path, "cannot stat");
    }
    size_ = static_cast<size_t>(st.st_size);
    if (size_ > 0) map_ = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    ::close(fd);
    if (map_ == MAP_FAILED) throw InputError(path, "cannot map");
  }
  ~MappedFile() {
    if (map_ && map_ != MAP_FAILED) ::munmap(map_, size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  const char* data() const { return static_cast<const char*>(map_); }
  size_t size() const { return size_; }

 private:
  void* map_ = nullptr;
  size_t size_ = 0;
};

// CheckCatalogDir, keeping what it read: catalog.bin's bytes and meta.json (when kOk).
CatalogDirState CheckCatalogDirKeep(const std::string& dir, std::string* why, std::unique_ptr<MappedFile>* bin,
                                    Json* meta) {
  const std::string bin_path = dir + "/catalog.bin", meta_path = dir + "/meta.json";
  if (!FileExists(meta_path)) {
    if (why) *why = FileExists(bin_path) ? "no meta.json (a build that did not finish)" : "no catalog";
    return FileExists(bin_path) ? CatalogDirState::kIncomplete : CatalogDirState::kAbsent;
  }
  try {
    *meta = ReadJsonFile(meta_path);
    const int64_t bytes = JsonInt(*meta, "catalog_bin_bytes", 0, int64_t{1} << 40, meta_path);
    const int64_t crc = JsonInt(*meta, "catalog_bin_crc32", 0, 0xffffffffLL, meta_path);
    *bin = std::make_unique<MappedFile>(bin_path);
    const MappedFile& f = **bin;
    if (static_cast<int64_t>(f.size()) != bytes) {
      throw InputError(bin_path,
                       "damaged: " + std::to_string(f.size()) + " bytes, meta.json records " + std::to_string(bytes));
    }
    if (Crc32(f.data(), f.size()) != static_cast<uint32_t>(crc)) {
      throw InputError(bin_path, "damaged: its CRC-32 differs from the one meta.json records");
    }
  } catch (const InputError& e) {
    if (why) *why = e.what();
    return CatalogDirState::kDamaged;
  }
  return CatalogDirState::kOk;
}

// Parses catalog.bin's bytes (format 5 or 4, or 3 whose features and index are recomputed) as a
// fixed-FOV catalog (the smallest FOV of a range catalog is in meta.json). With `in_place` the tables
// of a format-5 blob are viewed where they lie (the bytes must outlive the catalog), else copied.
SolverCatalog ParseCatalogBytes(const char* data, size_t size, const std::string& path, bool star_tree = true,
                                bool in_place = false) {
  size_t pos = 0;
  auto get = [&](void* p, size_t n) {
    if (pos > size || n > size - pos) throw InputError(path, "truncated catalog file");
    std::memcpy(p, data + pos, n);
    pos += n;
  };
  char magic[8];
  get(magic, 8);
  const bool v3 = std::memcmp(magic, kMagicV3, 8) == 0, v4 = std::memcmp(magic, kMagicV4, 8) == 0;
  if (!v3 && !v4 && std::memcmp(magic, kMagic, 8) != 0) throw InputError(path, "not an ssiu catalog (bad magic)");
  const bool v5 = !v3 && !v4;
  SolverCatalog cat;
  double hdr[5];
  get(hdr, sizeof hdr);
  cat.epoch_year = hdr[0], cat.fov_deg = hdr[1], cat.mag_max = hdr[2], cat.double_star_arcsec = hdr[3],
  cat.build_time_s = hdr[4];
  if (!(cat.fov_deg > 0 && cat.fov_deg < 180)) throw InputError(path, "corrupt catalog header (fov_deg)");
  cat.fov_min_deg = cat.fov_deg;
  int64_t counts[4], slen;
  get(counts, sizeof counts);
  get(&slen, 8);
  if (counts[0] < 0 || counts[0] > 10000000 || counts[1] < 0 || counts[1] > 200000000 || slen < 0 || slen > 4096)
    throw InputError(path, "corrupt catalog header");
  cat.source.resize(static_cast<size_t>(slen));
  get(cat.source.data(), cat.source.size());
  cat.num_pattern_stars = static_cast<int>(counts[2]);
  cat.pattern_neighbours = static_cast<int>(counts[3]);
  const size_t n_stars = static_cast<size_t>(counts[0]), n_triangles = static_cast<size_t>(counts[1]);
  if (v5) pos = (pos + 7) / 8 * 8;
  if (v5 && StarRecordIsCatalogStar()) {
    ReadCatalogTable(data, size, &pos, n_stars, in_place, &cat.stars, path);
  } else {
    std::vector<CatalogStar>& stars = cat.stars.Own();
    stars.resize(n_stars);
    for (auto& s : stars) {
      double d[8];
      get(&s.id, sizeof s.id);
      if (v5) get(d, 4);  // the record's padding
      get(d, (v3 ? 5 : 8) * sizeof(double));
      s.ra_rad = d[0], s.dec_rad = d[1], s.mag = d[2];
      if (v5) {
        s.unit = Vec3(d[3], d[4], d[5]), s.pm_ra_rad_per_yr = d[6], s.pm_dec_rad_per_yr = d[7];
      } else {
        s.pm_ra_rad_per_yr = d[3], s.pm_dec_rad_per_yr = d[4];
        s.unit = v3 ? UnitFromRaDec(s.ra_rad, s.dec_rad) : Vec3(d[5], d[6], d[7]);
      }
    }
  }
  const int n = static_cast<int>(n_stars);
  if (!v3) {
    ReadCatalogTable(data, size, &pos, n_triangles, in_place, &cat.triangles, path);
    for (const CatalogTriangle& t : cat.triangles) {
      for (int k = 0; k < 3; ++k)
        if (t.v[k] < 0 || t.v[k] >= n) throw InputError(path, "corrupt triangle index");
      if (!(t.longest_rad > 0)) throw InputError(path, "corrupt triangle index (degenerate triangle)");
    }
  } else {
    // Format 3: features from the stars (vertices are stored ordered by the side opposite them).
    std::vector<CatalogTriangle>& triangles = cat.triangles.Own();
    triangles.resize(n_triangles);
    for (auto& t : triangles) {
      get(t.v.data(), sizeof t.v);
      for (int k = 0; k < 3; ++k)
        if (t.v[k] < 0 || t.v[k] >= n) throw InputError(path, "corrupt triangle index");
      const Vec3 &a = cat.stars[t.v[0]].unit, &b = cat.stars[t.v[1]].unit, &c = cat.stars[t.v[2]].unit;
      const double s0 = std::acos(std::min(1.0, b.dot(c))), s1 = std::acos(std::min(1.0, a.dot(c))),
                   s2 = std::acos(std::min(1.0, a.dot(b)));
      if (!(s2 > 0)) throw InputError(path, "corrupt triangle index (degenerate triangle)");
      t.longest_rad = static_cast<float>(s2);
      t.ratio_a = static_cast<float>(s0 / s2);
      t.ratio_b = static_cast<float>(s1 / s2);
    }
  }
  cat.index = v3 ? std::make_shared<const CatalogIndex>(cat)
                 : std::make_shared<const CatalogIndex>(cat, data + pos, size - pos, path, star_tree, in_place);
  return cat;
}

// Parses catalog.bin checked by CheckCatalogDirKeep, with the smallest FOV of a range catalog from
// meta.json (catalogs written before it have one FOV).
SolverCatalog ParseCatalog(const MappedFile& bin, const Json& meta, const std::string& dir) {
  const std::string meta_path = dir + "/meta.json";
  const double fov_min_deg = JsonNumberOr(meta, "fov_min_deg", 0.0, meta_path);
  SolverCatalog cat = ParseCatalogBytes(bin.data(), bin.size(), dir + "/catalog.bin");
  if (meta.contains("fov_min_deg")) {
    if (!(fov_min_deg > 0 && fov_min_deg <= cat.fov_deg))
      throw InputError(meta_path, "field 'fov_min_deg' must be in (0, fov_deg]");
    cat.fov_min_deg = fov_min_deg;
  }
  return cat;
}

[[noreturn]] void ThrowDamaged(const std::string& dir, const std::string& why) {
  throw InputError(dir, "damaged catalog: " + why + "; delete it or rebuild it with `ssiu catalog build --out DIR`");
}

}  // namespace

const char* CatalogDirStateName(CatalogDirState s) {
  switch (s) {
    case CatalogDirState::kAbsent:
      return "absent";
    case CatalogDirState::kIncomplete:
      return "incomplete";
    case CatalogDirState::kDamaged:
      return "damaged";
    case CatalogDirState::kOk:
      return "ok";
  }
  return "absent";
}

CatalogDirState CheckCatalogDir(const std::string& dir, std::string* why) {
  std::unique_ptr<MappedFile> bin;
  Json meta;
  return CheckCatalogDirKeep(dir, why, &bin, &meta);
}

SolverCatalog ParseSolverCatalog(const void* data, size_t bytes, const std::string& name, bool star_tree,
                                 bool in_place) {
  if (data == nullptr) throw InputError(name, "no catalog data");
  return ParseCatalogBytes(static_cast<const char*>(data), bytes, name, star_tree, in_place);
}

SolverCatalog LoadSolverCatalog(const std::string& dir) {
  std::string why;
  std::unique_ptr<MappedFile> bin;
  Json meta;
  switch (CheckCatalogDirKeep(dir, &why, &bin, &meta)) {
    case CatalogDirState::kAbsent:
      throw InputError(dir + "/catalog.bin", "cannot open built catalog (run `ssiu catalog build`)");
    case CatalogDirState::kIncomplete:
    case CatalogDirState::kDamaged:
      ThrowDamaged(dir, why);
    case CatalogDirState::kOk:
      break;
  }
  return ParseCatalog(*bin, meta, dir);
}

std::string CatalogCacheDir() {
  if (const char* d = std::getenv("SSIU_CATALOG_DIR"); d && *d) return d;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return std::string(x) + "/ssiu/catalog";
  const char* home = std::getenv("HOME");
  return std::string(home && *home ? home : "/tmp") + "/.cache/ssiu/catalog";
}

SolverCatalog LoadOrBuildCatalog(const std::string& source_path, const CatalogBuildOptions& o) {
  o.Check();
  std::string base = source_path.substr(source_path.find_last_of('/') + 1);
  for (char& c : base)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  char key[256];
  std::snprintf(key, sizeof key, "%s_fov%.2f_mag%.2f_ep%.1f_dbl%.1f_p%d_s%.0f_k%d_b%d_v6", base.c_str(), o.fov_deg,
                o.mag_max, o.epoch_year, o.double_star_arcsec, o.pattern_stars_per_fov, o.stars_per_fov,
                o.pattern_neighbours, o.pattern_bright_neighbours);
  std::string dir_key = key;
  if (o.FovMinDeg() < o.fov_deg) {
    std::snprintf(key, sizeof key, "_min%.2f", o.fov_min_deg);
    dir_key += key;
  }
  const std::string dir = CatalogCacheDir() + "/" + dir_key;
  try {
    return LoadOrBuildCatalogIn(dir, source_path, o, /*rebuild_damaged=*/true);
  } catch (const InputError&) {
    // Read-only or unusable cache location: use the catalog without caching it.
    return BuildSolverCatalog(LoadSourceCatalog(source_path), o);
  }
}

SolverCatalog LoadOrBuildCatalogIn(const std::string& dir, const std::string& source_path, const CatalogBuildOptions& o,
                                   bool rebuild_damaged) {
  o.Check();
  MakeDirs(dir);
  // One builder at a time per directory: the others wait here, then find its catalog complete.
  const std::string lock_path = dir + "/.lock";
  const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0 || ::flock(fd, LOCK_EX) != 0) {
    if (fd >= 0) ::close(fd);
    throw InputError(lock_path, "cannot lock the catalog directory");
  }
  struct Unlock {
    int fd;
    ~Unlock() { ::close(fd); }  // closing releases the flock
  } unlock{fd};
  std::string why;
  std::unique_ptr<MappedFile> bin;
  Json meta;
  const CatalogDirState state = CheckCatalogDirKeep(dir, &why, &bin, &meta);
  if (state == CatalogDirState::kOk) {
    SolverCatalog cat = ParseCatalog(*bin, meta, dir);
    // A pattern index for another field of view finds few or wrong triangles (issue 16).
    if (!(std::abs(cat.fov_deg / o.fov_deg - 1) <= kCatalogFovTolerance)) {
      char msg[256];
      std::snprintf(msg, sizeof msg,
                    "catalog built for a %.2f deg field of view, this camera needs %.2f deg "
                    "(more than %.0f%% apart): give another --catalog or delete this one to rebuild it",
                    cat.fov_deg, o.fov_deg, 100 * kCatalogFovTolerance);
      throw InputError(dir, msg);
    }
    // And the smallest FOV of a range (unknown-FOV solving): its star density is what small fields need.
    if (!(std::abs(cat.fov_min_deg / o.FovMinDeg() - 1) <= kCatalogFovTolerance)) {
      char msg[256];
      std::snprintf(msg, sizeof msg,
                    "catalog built for fields of view %.2f-%.2f deg, this solve needs %.2f-%.2f deg "
                    "(more than %.0f%% apart): give another --catalog or delete this one to rebuild it",
                    cat.fov_min_deg, cat.fov_deg, o.FovMinDeg(), o.fov_deg, 100 * kCatalogFovTolerance);
      throw InputError(dir, msg);
    }
    return cat;
  }
  if (state == CatalogDirState::kDamaged && !rebuild_damaged) ThrowDamaged(dir, why);
  SolverCatalog cat = BuildSolverCatalog(LoadSourceCatalog(source_path), o);
  SaveSolverCatalog(cat, dir);
  return cat;
}

}  // namespace ssiu
