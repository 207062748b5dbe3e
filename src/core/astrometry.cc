#include "core/astrometry.h"

#include <erfa.h>

#include <cmath>
#include <cstdio>
#include <regex>
#include <sstream>

#include "core/attitude.h"
#include "core/error.h"

namespace ssiu {
namespace {

constexpr double kAuM = 149597870700.0;  // IAU 2012 Resolution B2
constexpr double kDayS = 86400.0;

}  // namespace

UtcTime ParseUtcIso8601(const std::string& text, const std::string& where) {
  static const std::regex re(
      R"(^(\d{4})-(\d{2})-(\d{2})(?:[T ](\d{2}):(\d{2})(?::(\d{2}(?:\.\d+)?))?)?(Z|[+-]\d{2}:?\d{2})?$)");
  std::smatch m;
  const std::string bad = "'" + text + "' is not an ISO 8601 UTC time (YYYY-MM-DDThh:mm:ss[.fff][Z])";
  if (!std::regex_match(text, m, re)) throw InputError(where, bad);
  const int iy = std::stoi(m[1]), im = std::stoi(m[2]), id = std::stoi(m[3]);
  const int ihr = m[4].matched ? std::stoi(m[4]) : 0, imn = m[5].matched ? std::stoi(m[5]) : 0;
  const double sec = m[6].matched ? std::stod(m[6]) : 0.0;
  if (iy < 1800 || iy > 2300) throw InputError(where, "'" + text + "': year outside 1800-2300");
  double offset_min = 0;
  if (m[7].matched && m[7].str() != "Z") {
    const std::string z = m[7].str();
    const int oh = std::stoi(z.substr(1, 2)), om = std::stoi(z.substr(z.size() - 2));
    if (oh > 23 || om > 59) throw InputError(where, bad);
    offset_min = (z[0] == '-' ? -1 : 1) * (oh * 60.0 + om);
  }
  double u1, u2;
  const int s = eraDtf2d("UTC", iy, im, id, ihr, imn, sec, &u1, &u2);
  if (s < 0) {
    static const char* what[] = {"", "year", "month", "day", "hour", "minute", "second"};
    throw InputError(where, "'" + text + "': bad " + what[-s]);
  }
  u2 -= offset_min / 1440.0;  // local time - offset = UTC (a leap second inside the offset is ignored)
  double a1, a2;
  UtcTime t;
  if (eraUtctai(u1, u2, &a1, &a2) < 0 || eraTaitt(a1, a2, &t.tt_jd1, &t.tt_jd2) != 0) throw InputError(where, bad);
  return t;
}

std::string FormatUtcIso8601(const UtcTime& t) {
  double a1, a2, u1, u2;
  int ihmsf[4], iy, im, id;
  if (!t.valid() || eraTttai(t.tt_jd1, t.tt_jd2, &a1, &a2) != 0 || eraTaiutc(a1, a2, &u1, &u2) < 0 ||
      eraD2dtf("UTC", 3, u1, u2, &iy, &im, &id, ihmsf) < 0)
    return "";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", iy, im, id, ihmsf[0], ihmsf[1], ihmsf[2],
                ihmsf[3]);
  return buf;
}

UtcTime AddSeconds(const UtcTime& t, double seconds) {
  UtcTime r = t;
  r.tt_jd2 += seconds / kDayS;  // TT runs in SI seconds
  return r;
}

double JulianYearTt(const UtcTime& t) { return eraEpj(t.tt_jd1, t.tt_jd2); }

double TtMinusUtcS(const UtcTime& t) {
  double a1, a2, u1, u2;
  eraTttai(t.tt_jd1, t.tt_jd2, &a1, &a2);
  eraTaiutc(a1, a2, &u1, &u2);
  return ((t.tt_jd1 - u1) + (t.tt_jd2 - u2)) * kDayS;
}

Vec3 EarthBarycentricVelocityMS(const UtcTime& t) {
  double pvh[2][3], pvb[2][3];
  eraEpv00(t.tt_jd1, t.tt_jd2, pvh, pvb);  // status 1 = outside 1900-2100: still the best estimate
  return Vec3(pvb[1][0], pvb[1][1], pvb[1][2]) * (kAuM / kDayS);
}

Vec3 AberrateDirection(const Vec3& u, const Vec3& v_m_s) {
  double pnat[3] = {u.x(), u.y(), u.z()};
  const Vec3 b = v_m_s / kSpeedOfLightMS;
  double v[3] = {b.x(), b.y(), b.z()};
  double ppr[3];
  eraAb(pnat, v, 1.0, std::sqrt(1.0 - b.squaredNorm()), ppr);
  return Vec3(ppr[0], ppr[1], ppr[2]).normalized();
}

Vec3 PropagateProperMotion(const CatalogStar& s, double from_year, double to_year) {
  const double dt = to_year - from_year;
  if (dt == 0 || (s.pm_ra_rad_per_yr == 0 && s.pm_dec_rad_per_yr == 0)) return s.unit;
  const Vec3 east(-std::sin(s.ra_rad), std::cos(s.ra_rad), 0);
  const Vec3 north(-std::sin(s.dec_rad) * std::cos(s.ra_rad), -std::sin(s.dec_rad) * std::sin(s.ra_rad),
                   std::cos(s.dec_rad));
  return (s.unit + dt * (s.pm_ra_rad_per_yr * east + s.pm_dec_rad_per_yr * north)).normalized();
}

Vec3 SkyCorrections::ObserverVelocityMS() const {
  Vec3 v = have_velocity ? velocity_m_s : Vec3::Zero();
  if (annual_aberration && time.valid()) v += EarthBarycentricVelocityMS(time);
  return v;
}

Vec3 SkyCorrections::Apparent(const CatalogStar& star, double catalog_epoch_year) const {
  return active() ? Apparent(star, catalog_epoch_year, ObserverVelocityMS()) : star.unit;
}

Vec3 SkyCorrections::Apparent(const CatalogStar& star, double catalog_epoch_year, const Vec3& v) const {
  if (!active()) return star.unit;
  const Vec3 u = proper_motion ? PropagateProperMotion(star, catalog_epoch_year, JulianYearTt(time)) : star.unit;
  return v.squaredNorm() > 0 ? AberrateDirection(u, v) : u;
}

void SkyCorrections::Check() const {
  if (!velocity_m_s.allFinite() || velocity_m_s.norm() > 1e5)
    throw InputError("velocity", "spacecraft velocity must be finite and below 100 km/s");
  if (have_velocity && !time.valid())
    throw InputError("velocity",
                     "a spacecraft velocity needs the frame time (--time or FITS DATE-OBS): the annual "
                     "aberration is the larger part");
}

Vec3 ParseVelocityKms(const std::string& text, const std::string& where) {
  std::stringstream ss(text);
  Vec3 v;
  char c1 = 0, c2 = 0;
  std::string rest;
  if (!(ss >> v.x() >> c1 >> v.y() >> c2 >> v.z()) || c1 != ',' || c2 != ',' || (ss >> rest) || !v.allFinite())
    throw InputError(where, "'" + text + "' must be X,Y,Z in km/s (ICRS)");
  if (v.norm() > 100) throw InputError(where, "'" + text + "': above 100 km/s");
  return v * 1000.0;
}

}  // namespace ssiu
