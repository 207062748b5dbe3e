// ADM epochs (504.0-B-2 sec. 6.5.9: "YYYY-MM-DDThh:mm:ss[.d...d][Z]" or day of year "YYYY-DDDThh:mm:ss")
// in a message's time system, to seconds after a UTC instant, through ERFA's time scales (leap seconds).
#include <erfa.h>

#include <cstdio>
#include <regex>

#include "ccsds/adm.h"
#include "core/error.h"

namespace ssiu {
namespace {

constexpr double kDayS = 86400.0;

struct Tt {
  double jd1 = 0, jd2 = 0;
};

// TT of an epoch given in `time_system`.
Tt ParseEpoch(const std::string& text, const std::string& time_system, const std::string& where) {
  static const std::regex re(R"(^\s*(\d{4})-(?:(\d{2})-(\d{2})|(\d{3}))T(\d{2}):(\d{2}):(\d{2}(?:\.\d*)?)Z?\s*$)");
  std::smatch m;
  if (!std::regex_match(text, m, re))
    throw InputError(where, "'" + text + "' is not a CCSDS epoch (YYYY-MM-DDThh:mm:ss[.f] or YYYY-DDDThh:mm:ss[.f])");
  const int iy = std::stoi(m[1]);
  int im = 1, id = 1;
  double extra_days = 0;
  if (m[2].matched) {
    im = std::stoi(m[2]);
    id = std::stoi(m[3]);
  } else {
    const int doy = std::stoi(m[4]);
    if (doy < 1 || doy > 366) throw InputError(where, "'" + text + "': day of year outside 1-366");
    extra_days = doy - 1;
  }
  const int ihr = std::stoi(m[5]), imn = std::stoi(m[6]);
  const double sec = std::stod(m[7]);
  const bool utc = time_system == "UTC";
  double d1, d2;
  if (eraDtf2d(utc ? "UTC" : "", iy, im, id, ihr, imn, sec, &d1, &d2) < 0)
    throw InputError(where, "'" + text + "': bad date or time of day");
  d2 += extra_days;  // a day-of-year epoch: days after 1 January (a UTC leap second inside is ignored)
  Tt t;
  double a1, a2;
  if (utc) {
    if (eraUtctai(d1, d2, &a1, &a2) < 0) throw InputError(where, "'" + text + "': not a UTC time");
    eraTaitt(a1, a2, &t.jd1, &t.jd2);
  } else if (time_system == "TAI") {
    eraTaitt(d1, d2, &t.jd1, &t.jd2);
  } else if (time_system == "TT") {
    t = {d1, d2};
  } else if (time_system == "GPS") {  // TAI = GPS + 19 s
    eraTaitt(d1, d2 + 19.0 / kDayS, &t.jd1, &t.jd2);
  } else {
    throw InputError(where, "TIME_SYSTEM " + time_system + " is not read (UTC, TAI, TT, GPS are)");
  }
  return t;
}

}  // namespace

double AdmSecondsSince(const std::string& text, const std::string& time_system, const std::string& from_utc,
                       const std::string& where) {
  const Tt a = ParseEpoch(text, time_system, where);
  const Tt b = ParseEpoch(from_utc, "UTC", where);
  return ((a.jd1 - b.jd1) + (a.jd2 - b.jd2)) * kDayS;
}

std::string AdmEpoch(const std::string& epoch_utc, double t_s) {
  Tt t = ParseEpoch(epoch_utc, "UTC", "epoch");
  t.jd2 += t_s / kDayS;  // TT runs in SI seconds
  double a1, a2, u1, u2;
  int iy, im, id, ihmsf[4];
  eraTttai(t.jd1, t.jd2, &a1, &a2);
  if (eraTaiutc(a1, a2, &u1, &u2) < 0 || eraD2dtf("UTC", 6, u1, u2, &iy, &im, &id, ihmsf) < 0)
    throw InputError("epoch", "cannot format the epoch " + epoch_utc + " + " + std::to_string(t_s) + " s");
  char b[48];
  std::snprintf(b, sizeof b, "%04d-%02d-%02dT%02d:%02d:%02d.%06d", iy, im, id, ihmsf[0], ihmsf[1], ihmsf[2], ihmsf[3]);
  return b;
}

}  // namespace ssiu
