// The FITS WCS header of a solution (TanWcsHeader) evaluated as a FITS reader would (Calabretta &
// Greisen 2002, TAN) against the camera model it was written from.
#include <cmath>
#include <cstdlib>
#include <map>
#include <string>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

double Angle(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

std::map<std::string, double> NumericCards(const std::string& header) {
  std::map<std::string, double> cards;
  for (size_t i = 0; i + 80 <= header.size(); i += 80) {
    const std::string card = header.substr(i, 80);
    if (card.compare(8, 2, "= ") != 0) continue;
    std::string key = card.substr(0, 8);
    key.erase(key.find_last_not_of(' ') + 1);
    char* end = nullptr;
    const std::string value = card.substr(10, 20);
    const double v = std::strtod(value.c_str(), &end);
    if (end != value.c_str()) cards[key] = v;
  }
  return cards;
}

// Sky direction of FITS pixel (1-based) (p1, p2): TAN with CD and, when present, SIP (A, B) terms.
Vec3 WcsDirection(const std::map<std::string, double>& c, double p1, double p2) {
  double u = p1 - c.at("CRPIX1"), v = p2 - c.at("CRPIX2");
  double du = 0, dv = 0;
  auto term = [&](const std::string& k) { return c.count(k) ? c.at(k) : 0.0; };
  const int ao = c.count("A_ORDER") ? static_cast<int>(c.at("A_ORDER")) : 0;
  for (int p = 0; p <= ao; ++p) {
    for (int q = 0; p + q <= ao; ++q) {
      du += term("A_" + std::to_string(p) + "_" + std::to_string(q)) * std::pow(u, p) * std::pow(v, q);
      dv += term("B_" + std::to_string(p) + "_" + std::to_string(q)) * std::pow(u, p) * std::pow(v, q);
    }
  }
  u += du, v += dv;
  const double xi = (c.at("CD1_1") * u + c.at("CD1_2") * v) * kDegToRad;
  const double eta = (c.at("CD2_1") * u + c.at("CD2_2") * v) * kDegToRad;
  const double ra0 = c.at("CRVAL1") * kDegToRad, dec0 = c.at("CRVAL2") * kDegToRad;
  const Vec3 bore = UnitFromRaDec(ra0, dec0);
  const Vec3 east(-std::sin(ra0), std::cos(ra0), 0);
  const Vec3 north = bore.cross(east);
  return (bore + xi * east + eta * north).normalized();
}

TEST(Wcs, CdMatrixCarriesNonSquarePixels) {
  Camera cam;
  cam.width = 752, cam.height = 290;
  cam.focal_length_px = 2325, cam.focal_length_y_px = 1190;
  cam.cx_px = 370.2, cam.cy_px = 150.7;
  const Quat q = QuatFromRaDecRoll(1.1, -0.4, 0.3);
  const auto cards = NumericCards(TanWcsHeader(q, cam));
  for (double x : {0.0, 200.0, 751.0}) {
    for (double y : {0.0, 145.0, 289.0}) {
      const Vec3 truth = q * cam.Unproject(Vec2(x, y));
      EXPECT_LT(Angle(WcsDirection(cards, x + 1, y + 1), truth) * kRadToArcsec, 1e-3) << x << "," << y;
    }
  }
}

}  // namespace
}  // namespace ssiu
