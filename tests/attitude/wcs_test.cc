// The FITS WCS header of a solution (TanWcsHeader) evaluated as a FITS reader would (Calabretta &
// Greisen 2002, TAN) against the camera model it was written from.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
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

TEST(Wcs, SipTermsReproduceTheDistortedCamera) {
  Camera cam;
  cam.width = 1024, cam.height = 768;
  cam.focal_length_px = 2400, cam.focal_length_y_px = 2300;
  cam.cx_px = 520.3, cam.cy_px = 380.1;
  cam.distortion = {-0.45, 0.8, 0.0, 4e-4, -6e-4};  // ~20 px of radial distortion at the corners
  const Quat q = QuatFromRaDecRoll(4.0, 0.7, 2.1);
  const std::string header = TanWcsHeader(q, cam);
  EXPECT_NE(header.find("'RA---TAN-SIP'"), std::string::npos);
  const auto cards = NumericCards(header);
  ASSERT_TRUE(cards.count("A_ORDER") && cards.count("B_ORDER") && cards.count("AP_ORDER") && cards.count("BP_ORDER"));
  const double arcsec_per_px = kRadToArcsec / 2300;
  double worst = 0, worst_tan = 0;
  auto strip_sip = cards;
  for (auto it = strip_sip.begin(); it != strip_sip.end();)
    it = it->first.rfind("A_", 0) == 0 || it->first.rfind("B_", 0) == 0 ? strip_sip.erase(it) : std::next(it);
  for (double x = 0; x <= 1023; x += 93) {
    for (double y = 0; y <= 767; y += 69) {
      const Vec3 truth = q * cam.Unproject(Vec2(x, y));
      worst = std::max(worst, Angle(WcsDirection(cards, x + 1, y + 1), truth) * kRadToArcsec);
      worst_tan = std::max(worst_tan, Angle(WcsDirection(strip_sip, x + 1, y + 1), truth) * kRadToArcsec);
      // The inverse polynomial: pinhole offsets (u', v') back to the distorted pixel.
      const auto p = cam.Project(cam.Unproject(Vec2(x, y)));
      const Vec3 d = cam.Unproject(Vec2(x, y));
      const double up = cam.focal_length_px * d.x() / d.z(), vp = cam.FocalYPx() * d.y() / d.z();
      double u = up, v = vp;
      const int order = static_cast<int>(cards.at("AP_ORDER"));
      for (int i = 0; i <= order; ++i) {
        for (int k = 0; i + k <= order; ++k) {
          const std::string s = std::to_string(i) + "_" + std::to_string(k);
          if (cards.count("AP_" + s)) u += cards.at("AP_" + s) * std::pow(up, i) * std::pow(vp, k);
          if (cards.count("BP_" + s)) v += cards.at("BP_" + s) * std::pow(up, i) * std::pow(vp, k);
        }
      }
      EXPECT_NEAR(u + cam.cx_px, p->x(), 0.01);
      EXPECT_NEAR(v + cam.cy_px, p->y(), 0.01);
    }
  }
  std::printf("SIP: worst %.4f arcsec (%.4f px); TAN alone %.2f arcsec\n", worst, worst / arcsec_per_px, worst_tan);
  EXPECT_LT(worst, 0.01 * arcsec_per_px);
  EXPECT_GT(worst_tan, 1.0 * arcsec_per_px);  // the distortion is there to be modelled
}

}  // namespace
}  // namespace ssiu
