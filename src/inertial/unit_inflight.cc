#include "inertial/unit_inflight.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "inertial/propagate.h"

namespace ssiu {

Json InflightCalResult::ToJson() const {
  Json gs = Json::array();
  for (const auto& g : gyros) {
    gs.push_back({{"scale_factor_ppm", g.scale_factor_ppm},
                  {"scale_factor_sigma_ppm", g.scale_factor_sigma_ppm},
                  {"misalignment_arcsec", {g.misalignment_arcsec[0], g.misalignment_arcsec[1]}},
                  {"misalignment_sigma_arcsec", {g.misalignment_sigma_arcsec[0], g.misalignment_sigma_arcsec[1]}},
                  {"axis", {g.axis.x(), g.axis.y(), g.axis.z()}}});
  }
  return {{"status", ok ? "fitted" : "not_observable"},
          {"message", message},
          {"gyros", gs},
          {"n_windows", n_windows},
          {"n_bias_blocks", n_bias_blocks},
          {"chi2_per_dof", chi2_per_dof},
          {"best_combination_sigma", best_combination_sigma},
          {"worst_combination_sigma", worst_combination_sigma},
          {"unit", GyroUnitToJson(unit)}};
}

namespace {

// One linearised solve about `nominal` (its processor axes and calibration): the corrections on top of
// it, by the recursive estimator fed the log in time order (each fix after the gyro samples up to it).
InflightCalResult SolveOnce(const GyroLog& gyro, const StarTrackerLog& st, const GyroUnit& nominal,
                            double st_sigma_cross_arcsec, double st_sigma_roll_arcsec, const InflightCalOptions& o) {
  const int n = nominal.size();
  InflightCalResult res;
  res.unit = nominal;
  InflightCalibrator cal(nominal, o);
  size_t k = 0;
  for (size_t j = 0; j < st.t_s.size(); ++j) {
    for (; k < gyro.t_s.size() && gyro.t_s[k] <= st.t_s[j] + 1e-9; ++k) {
      GyroVec g = gyro.rates_dph[k];
      nominal.RemoveCalibratedErrors(&g);
      cal.AddGyro(gyro.t_s[k], g);
    }
    // Cross-boresight about body x, y; roll about z.
    const double sc = (st.sigma_cross_arcsec.empty() ? st_sigma_cross_arcsec : st.sigma_cross_arcsec[j]) * kArcsecToRad;
    const double sr = (st.sigma_roll_arcsec.empty() ? st_sigma_roll_arcsec : st.sigma_roll_arcsec[j]) * kArcsecToRad;
    cal.AddFix(st.t_s[j], st.q_inertial_from_body[j], Mat3(Vec3(sc * sc, sc * sc, sr * sr).asDiagonal()));
  }
  const UnitCalState s = cal.Estimate();
  res.n_windows = s.n_windows;
  res.n_bias_blocks = s.n_bias_blocks;
  if (s.status == UnitCalStatus::kAccumulating) {
    res.message = "too few star windows (" + std::to_string(s.n_windows) + ") for " +
                  std::to_string(3 * n + n * s.n_bias_blocks) + " parameters";
    return res;
  }
  if (s.status != UnitCalStatus::kEstimated) {
    res.message = "scale factors and axes not observable: the body must turn about three independent axes";
    return res;
  }
  res.chi2_per_dof = s.chi2_per_dof;
  res.best_combination_sigma = s.best_combination_sigma;
  res.worst_combination_sigma = s.worst_combination_sigma;
  const GyroAxes h = nominal.ProcessorAxes();
  const double kAsToRad = kArcsecToRad;
  res.unit.calibrated = true;
  for (int i = 0; i < n; ++i) {
    InflightGyroCal gc;
    gc.scale_factor_ppm = s.scale_factor_ppm[i];
    gc.scale_factor_sigma_ppm = s.scale_factor_sigma_ppm[i];
    for (int c = 0; c < 2; ++c) {
      gc.misalignment_arcsec[c] = s.misalignment_arcsec[i][c];
      gc.misalignment_sigma_arcsec[c] = s.misalignment_sigma_arcsec[i][c];
    }
    const Vec3 a = h.row(i).transpose();
    Vec3 u, w;
    AxisNormals(a, &u, &w);
    const Vec3 m = a + kAsToRad * (gc.misalignment_arcsec[0] * u + gc.misalignment_arcsec[1] * w);
    gc.axis = m.normalized();
    // The model's (1 + S)(n + mu u + nu v) is (1 + S) |m| along the unit axis: the scale factor of
    // unit.json's convention (GyroErrorModel, a unit sensing axis).
    gc.scale_factor_ppm = 1e6 * ((1 + 1e-6 * gc.scale_factor_ppm) * m.norm() - 1);
    // On top of what the nominal unit already removes (a bench-calibrated one): the scale factors
    // compose, the fitted axis replaces the processor's.
    GyroErrorModel& e = res.unit.gyros[i];
    const double s0 = nominal.calibrated ? e.scale_factor_ppm : 0.0;
    e.scale_factor_ppm = s0 + gc.scale_factor_ppm + 1e-6 * s0 * gc.scale_factor_ppm;
    if (!nominal.calibrated) {
      e.bias_dph = 0, e.scale_factor_asymmetry_ppm = 0, e.scale_factor_nonlinearity_ppm_per_dps = 0;
    }
    e.misalignment_arcsec[0] = e.misalignment_arcsec[1] = 0;
    res.unit.axes_body[i] = gc.axis;
    res.gyros.push_back(gc);
  }
  res.ok = true;
  return res;
}

}  // namespace

InflightCalResult CalibrateUnitInFlight(const GyroLog& gyro, const StarTrackerLog& st, const GyroUnit& nominal,
                                        double st_sigma_cross_arcsec, double st_sigma_roll_arcsec,
                                        const InflightCalOptions& o) {
  o.Check();
  nominal.Check("unit");
  if (gyro.body_rates) throw InputError(gyro.file, "--calibrate-unit needs the gyros' outputs g1_dph..gN_dph");
  // Gauss-Newton: the model is linear in the errors about the unit it propagates with; the rates that
  // build its regressors carry the errors too (a tilt of 1e-3 rad times a rate error of 1e-3 is 1 ppm),
  // so it is solved again about the calibrated unit until the corrections are far below their sigmas.
  InflightCalResult res = SolveOnce(gyro, st, nominal, st_sigma_cross_arcsec, st_sigma_roll_arcsec, o);
  for (int it = 0; it < 3 && res.ok; ++it) {
    InflightCalResult next = SolveOnce(gyro, st, res.unit, st_sigma_cross_arcsec, st_sigma_roll_arcsec, o);
    if (!next.ok) break;
    res = next;
  }
  if (!res.ok) return res;
  // The estimates against the nominal unit's own processor axes and scale factors.
  const GyroAxes h0 = nominal.ProcessorAxes();
  for (int i = 0; i < nominal.size(); ++i) {
    const Vec3 n0 = h0.row(i).transpose(), a = res.unit.axes_body[i];
    Vec3 u, v;
    AxisNormals(n0, &u, &v);
    InflightGyroCal& g = res.gyros[i];
    g.axis = a;
    g.misalignment_arcsec[0] = a.dot(u) / a.dot(n0) * kRadToArcsec;
    g.misalignment_arcsec[1] = a.dot(v) / a.dot(n0) * kRadToArcsec;
    const double s0 = nominal.calibrated ? nominal.gyros[i].scale_factor_ppm : 0.0;
    g.scale_factor_ppm = 1e6 * ((1 + 1e-6 * res.unit.gyros[i].scale_factor_ppm) / (1 + 1e-6 * s0) - 1);
  }
  return res;
}

}  // namespace ssiu
