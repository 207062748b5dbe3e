#include "core/astrometry.h"

#include <cmath>

#include "core/attitude.h"
#include "core/error.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

constexpr double kAuPerDayToMS = 149597870700.0 / 86400.0;

double SecondsBetween(const UtcTime& a, const UtcTime& b) {
  return ((b.tt_jd1 - a.tt_jd1) + (b.tt_jd2 - a.tt_jd2)) * 86400.0;
}

TEST(UtcTime, J2000IsNoonOfJanuaryFirst2000InTt) {
  // J2000.0 = 2000-01-01T12:00:00 TT = 11:58:55.816 UTC (TT - UTC = 32.184 s + 32 leap seconds).
  const UtcTime t = ParseUtcIso8601("2000-01-01T11:58:55.816Z", "t");
  EXPECT_NEAR((t.tt_jd1 - 2451545.0) + t.tt_jd2, 0.0, 1e-3 / 86400);
  EXPECT_NEAR(JulianYearTt(t), 2000.0, 1e-10);
  EXPECT_NEAR(TtMinusUtcS(t), 64.184, 1e-6);
  EXPECT_NEAR(TtMinusUtcS(ParseUtcIso8601("2017-06-01", "t")), 69.184, 1e-6);
}

TEST(UtcTime, FormsAndOffsetsGiveTheSameInstant) {
  const UtcTime z = ParseUtcIso8601("2025-03-20T09:01:00Z", "t");
  for (const char* s : {"2025-03-20T09:01:00", "2025-03-20 09:01", "2025-03-20T09:01:00.000Z",
                        "2025-03-20T10:01:00+01:00", "2025-03-20T04:31:00-0430"}) {
    EXPECT_NEAR(SecondsBetween(z, ParseUtcIso8601(s, "t")), 0.0, 1e-4) << s;
  }
  EXPECT_NEAR(SecondsBetween(ParseUtcIso8601("2025-03-20", "t"), z), 9 * 3600 + 60, 1e-4);
  EXPECT_EQ(FormatUtcIso8601(ParseUtcIso8601("2024-02-29T23:59:59.25Z", "t")), "2024-02-29T23:59:59.250Z");
}

TEST(UtcTime, AddingSecondsCountsTheLeapSecond) {
  // 2016-12-31T23:59:60 was a leap second: two SI seconds after 23:59:59 is midnight.
  const UtcTime t = ParseUtcIso8601("2016-12-31T23:59:59Z", "t");
  EXPECT_EQ(FormatUtcIso8601(AddSeconds(t, 2.0)), "2017-01-01T00:00:00.000Z");
}

TEST(UtcTime, BadTextIsAOneLineErrorNamingTheSource) {
  for (const char* s : {"", "yesterday", "2025-13-01", "2025-02-30", "2025-01-01T25:00", "2025-01-01T12:61",
                        "1700-01-01", "2025-1-1", "2025-01-01T12:00:00+25:00", "2025-01-01T12:00:00 junk"}) {
    try {
      ParseUtcIso8601(s, "--time");
      ADD_FAILURE() << "accepted '" << s << "'";
    } catch (const InputError& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.rfind("--time: ", 0), 0u) << m;
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    }
  }
}

TEST(EarthVelocity, MatchesThePublishedSofaValue) {
  // SOFA's published check of its Earth ephemeris (t_sofa_c.c, t_epv00): barycentric velocity at
  // TDB 2400000.5 + 53411.52501161 (2005-02-11), au/day.
  UtcTime t;
  t.tt_jd1 = 2400000.5;
  t.tt_jd2 = 53411.52501161;
  const Vec3 v = EarthBarycentricVelocityMS(t) / kAuPerDayToMS;
  EXPECT_NEAR(v.x(), -0.1091874268116823295e-1, 1e-14);
  EXPECT_NEAR(v.y(), -0.1246525461732861538e-1, 1e-14);
  EXPECT_NEAR(v.z(), -0.5404773180966231279e-2, 1e-14);
}

// The Sun's geocentric position from the Astronomical Almanac's low-precision formulas (section C,
// "Sun: low precision", ~0.01 deg), brought from the equinox of date to J2000 by the general
// precession in longitude (5029.1"/century); the Earth's heliocentric velocity is minus its
// derivative.
Vec3 AlmanacSunAu(double jd_tt) {
  const double n = jd_tt - 2451545.0;
  const double g = (357.528 + 0.9856003 * n) * kDegToRad;
  const double lambda =
      (280.460 + 0.9856474 * n + 1.915 * std::sin(g) + 0.020 * std::sin(2 * g) - 5029.1 / 3600.0 * n / 36525.0) *
      kDegToRad;
  const double eps = 23.4393 * kDegToRad;  // J2000 obliquity
  const double r = 1.00014 - 0.01671 * std::cos(g) - 0.00014 * std::cos(2 * g);
  return r * Vec3(std::cos(lambda), std::cos(eps) * std::sin(lambda), std::sin(eps) * std::sin(lambda));
}

TEST(EarthVelocity, AgreesWithTheAlmanacLowPrecisionSunThroughTheYear) {
  // Independent of SOFA: within 0.05 km/s (0.35 arcsec of aberration; the almanac's own precision and
  // the Sun's barycentric motion, ~0.013 km/s, set the tolerance). |v| stays in 29.2-30.4 km/s.
  for (int day = 0; day < 365 * 3; day += 37) {
    UtcTime t;
    t.tt_jd1 = 2451545.0;
    t.tt_jd2 = day;
    const double h = 0.5;
    const Vec3 v_almanac =
        -(AlmanacSunAu(t.tt_jd1 + day + h) - AlmanacSunAu(t.tt_jd1 + day - h)) / (2 * h) * kAuPerDayToMS;
    const Vec3 v = EarthBarycentricVelocityMS(t);
    EXPECT_LT((v - v_almanac).norm(), 50.0) << "day " << day;
    EXPECT_GT(v.norm(), 29.2e3);
    EXPECT_LT(v.norm(), 30.4e3);
  }
}

TEST(Aberration, DisplacesTowardTheApexByBetaSinTheta) {
  const Vec3 v(12e3, -25e3, 7.5e3);  // m/s
  const Vec3 apex = v.normalized();
  const double beta = v.norm() / kSpeedOfLightMS;
  for (double theta_deg : {0.0, 10.0, 45.0, 90.0, 135.0, 170.0}) {
    const Vec3 perp = apex.cross(Vec3::UnitZ()).normalized();
    const double th = theta_deg * kDegToRad;
    const Vec3 u = std::cos(th) * apex + std::sin(th) * perp;
    const Vec3 a = AberrateDirection(u, v);
    const double moved = std::atan2(u.cross(a).norm(), u.dot(a));
    // First order: beta sin(theta); the second-order term is below beta^2 (~0.02 arcsec here).
    EXPECT_NEAR(moved * kRadToArcsec, beta * std::sin(th) * kRadToArcsec, 0.03) << theta_deg;
    if (theta_deg > 0) {
      EXPECT_LT(std::acos(a.dot(apex)), th);  // towards the apex
    }
  }
}

TEST(ProperMotion, MovesAlongRaAndDecByRateTimesYears) {
  CatalogStar s;
  s.ra_rad = 1.0;
  s.dec_rad = 0.5;
  s.unit = UnitFromRaDec(s.ra_rad, s.dec_rad);
  s.pm_ra_rad_per_yr = 2.0 * kArcsecToRad;  // mu_alpha cos(dec)
  s.pm_dec_rad_per_yr = -1.0 * kArcsecToRad;
  double ra, dec;
  RaDecFromUnit(PropagateProperMotion(s, 2025.0, 2035.0), &ra, &dec);
  EXPECT_NEAR((ra - s.ra_rad) * std::cos(s.dec_rad) * kRadToArcsec, 20.0, 1e-3);
  EXPECT_NEAR((dec - s.dec_rad) * kRadToArcsec, -10.0, 1e-3);
  EXPECT_EQ(PropagateProperMotion(s, 2025.0, 2025.0), s.unit);
}

TEST(SkyCorrections, AppliesNothingWithoutATimeAndRefusesVelocityAlone) {
  CatalogStar s;
  s.unit = UnitFromRaDec(0.3, 0.2);
  SkyCorrections c;
  EXPECT_EQ(c.Apparent(s, 2025.0), s.unit);
  c.have_velocity = true;
  c.velocity_m_s = Vec3(7.5e3, 0, 0);
  EXPECT_THROW(c.Check(), InputError);
  c.time = ParseUtcIso8601("2025-06-21T00:00:00Z", "t");
  EXPECT_NO_THROW(c.Check());
  EXPECT_LT((c.ObserverVelocityMS() - EarthBarycentricVelocityMS(c.time) - c.velocity_m_s).norm(), 1e-9);
  EXPECT_EQ(ParseVelocityKms("1,-2.5,7", "v"), Vec3(1000, -2500, 7000));
  for (const char* bad : {"1,2", "1,2,3,4", "a,b,c", "1;2;3", "200,0,0", "nan,0,0"})
    EXPECT_THROW(ParseVelocityKms(bad, "--velocity-kms"), InputError) << bad;
}

}  // namespace
}  // namespace ssiu
