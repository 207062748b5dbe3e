// Time and motion for star positions: a frame's UTC time, proper motion to that date and stellar
// aberration (annual from the Earth's barycentric velocity, plus a spacecraft's velocity), so that a
// solved attitude is in ICRS at the frame's time (docs/conventions.md). Behind ssiu's own small types,
// the IAU SOFA algorithms as packaged by Debian's liberfa (ERFA): eraDtf2d/eraUtctai/eraTaitt for the
// time scales (leap seconds), eraEpv00 for the Earth's velocity, eraAb for the aberration.
//
//   const UtcTime t = ParseUtcIso8601("2025-03-20T09:01:00Z", "--time");
//   const Vec3 v = EarthBarycentricVelocityMS(t) + v_spacecraft_rel_earth_m_s;
//   const Vec3 apparent = AberrateDirection(PropagateProperMotion(star, epoch, JulianYearTt(t)), v);
//
// Precision: aberration changes by at most ~0.01 arcsec per minute (the Earth's acceleration), so a
// time to the second is plenty; the Earth's velocity from eraEpv00 is good to a few mm/s (Bretagnon's
// VSOP2000 fit in SOFA), i.e. microarcseconds in aberration.
#pragma once

#include <string>

#include "core/catalog.h"
#include "core/types.h"

namespace ssiu {

constexpr double kSpeedOfLightMS = 299792458.0;

// An instant, held as Terrestrial Time in ERFA's two-part Julian date (jd1 + jd2), with the UTC text
// it was given as (or formatted to).
struct UtcTime {
  double tt_jd1 = 0, tt_jd2 = 0;
  bool valid() const { return tt_jd1 != 0 || tt_jd2 != 0; }
};

// ISO 8601 UTC: "YYYY-MM-DD", "YYYY-MM-DDThh:mm[:ss[.fff]]" with an optional "Z" or "+hh:mm"/"-hh:mm"
// offset (a space may stand for the T; no zone means UTC, as FITS DATE-OBS). Years 1800-2300.
// Throws InputError "where: ..." on anything else (one line).
UtcTime ParseUtcIso8601(const std::string& text, const std::string& where);
// "YYYY-MM-DDThh:mm:ss.sssZ".
std::string FormatUtcIso8601(const UtcTime& t);
// t + seconds (SI seconds: a leap second inside counts).
UtcTime AddSeconds(const UtcTime& t, double seconds);
// Julian epoch (TT), e.g. 2025.4697; J2000.0 = 2000.0.
double JulianYearTt(const UtcTime& t);
// TT - UTC in seconds at t (32.184 s + leap seconds).
double TtMinusUtcS(const UtcTime& t);

// The Earth's velocity relative to the solar-system barycentre (BCRS, ICRS axes), m/s. TDB is taken
// as TT (they differ by < 2 ms).
Vec3 EarthBarycentricVelocityMS(const UtcTime& t);

// Apparent direction of a star whose direction (unit vector, BCRS) is u, seen by an observer moving
// at v_m_s relative to the barycentre: special-relativistic aberration (eraAb, Explanatory Supplement
// 3rd ed. eq. 7.40; the Sun's light-deflection term in it is taken at 1 au and is < 1e-11 rad).
// The star moves towards the apex by about (v/c) sin(theta).
Vec3 AberrateDirection(const Vec3& u, const Vec3& v_m_s);

// The star's direction at to_year, its catalog position being at from_year (Julian years): linear
// motion in the tangent plane, pm_ra carries cos(dec). Parallax and radial velocity are neglected
// (below 0.1 arcsec over decades for catalog stars of a star tracker).
Vec3 PropagateProperMotion(const CatalogStar& star, double from_year, double to_year);

// What brings catalog directions to the apparent directions of a frame (docs/identify.md, "Time and
// motion"): without a time, nothing (positions at the catalog epoch, no aberration).
struct SkyCorrections {
  UtcTime time;                      // frame time (mid-exposure); !valid() = unknown
  bool proper_motion = true;         // propagate catalog positions to the frame's date
  bool annual_aberration = true;     // the Earth's barycentric velocity
  bool have_velocity = false;        // spacecraft velocity relative to the Earth given
  Vec3 velocity_m_s = Vec3::Zero();  // ICRS axes
  bool active() const { return time.valid(); }
  // Observer velocity relative to the barycentre (m/s): Earth's (when annual_aberration) + spacecraft's.
  Vec3 ObserverVelocityMS() const;
  // Apparent direction of a catalog star whose position is at catalog_epoch_year.
  Vec3 Apparent(const CatalogStar& star, double catalog_epoch_year) const;
  // The same with v_observer_m_s = ObserverVelocityMS(), computed once for many stars.
  Vec3 Apparent(const CatalogStar& star, double catalog_epoch_year, const Vec3& v_observer_m_s) const;
  void Check() const;  // InputError: velocity above 100 km/s or not finite, velocity without a time
};

// "X,Y,Z" in km/s (ICRS) -> m/s; InputError naming `where` otherwise.
Vec3 ParseVelocityKms(const std::string& text, const std::string& where);

}  // namespace ssiu
