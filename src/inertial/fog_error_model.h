// Deterministic FOG error terms shared by the gyro simulator (sim), the bench calibration (analysis)
// and on-board compensation: the zero-signal temperature drift polynomial and the magnetic
// sensitivity of a single-axis FOG.
#pragma once

#include <array>
#include <string>

namespace ssiu {

// Zero-signal drift of one FOG (SSIU paper, eq. (1)):
//   dw = sum_{i+j<=3} K_ij * Z1^i * Z2^j,  Z1 = (T - T0)/(T1 - T0),  Z2 = G / G0,
// with T0 = 20 C, T1 = 30 C, G = dT/dt in C/min and G0 = 0.25 C/min. Terms in the fixed order
// K00, K10, K01, K20, K11, K02, K30, K21, K12, K03 (index k <-> (i, j) via ThermalTermPowers).
struct ThermalDriftModel {
  static constexpr int kNumTerms = 10;
  double t0_c = 20.0;
  double t1_c = 30.0;
  double g0_c_per_min = 0.25;
  std::array<double, kNumTerms> k_dph{};  // coefficients, deg/h; 0 = term absent

  double Z1(double temp_c) const { return (temp_c - t0_c) / (t1_c - t0_c); }
  double Z2(double rate_c_per_min) const { return rate_c_per_min / g0_c_per_min; }
  // Drift (deg/h) at temperature T (C) and temperature rate G (C/min).
  double DriftDph(double temp_c, double rate_c_per_min) const {
    const double z1 = Z1(temp_c), z2 = Z2(rate_c_per_min);
    double sum = 0;
    for (int k = 0; k < kNumTerms; ++k) {
      if (k_dph[k] == 0) continue;
      sum += k_dph[k] * Monomial(k, z1, z2);
    }
    return sum;
  }
  // The regressor Z1^i Z2^j of term k.
  static double Monomial(int k, double z1, double z2) {
    const auto [i, j] = ThermalTermPowers(k);
    double m = 1;
    for (int a = 0; a < i; ++a) m *= z1;
    for (int b = 0; b < j; ++b) m *= z2;
    return m;
  }
  static std::array<int, 2> ThermalTermPowers(int k) {
    static constexpr int kPowers[kNumTerms][2] = {{0, 0}, {1, 0}, {0, 1}, {2, 0}, {1, 1},
                                                  {0, 2}, {3, 0}, {2, 1}, {1, 2}, {0, 3}};
    return {kPowers[k][0], kPowers[k][1]};
  }
  // "K00" .. "K03".
  static std::string TermName(int k) {
    const auto p = ThermalTermPowers(k);
    return "K" + std::to_string(p[0]) + std::to_string(p[1]);
  }
};

// Sensitivity of a single-axis FOG to a magnetic field (deg/h per microtesla), for the field
// components along its sensing axis and across it (in the plane of the coil, radial).
struct MagneticSensitivity {
  double along_dph_per_ut = 0.0;
  double across_dph_per_ut = 0.0;
  double vertical_dph_per_ut = 0.0;
};

}  // namespace ssiu
