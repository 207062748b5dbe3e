// `thermal_lag` of `ssiu discover gyro` (docs/discrepancy.md): a drift that follows the logged
// temperature through a first-order lag, dw = K (T_lag - T0)/(T1 - T0) with tau dT_lag/dt = T - T_lag
// (a FOG's coil reaching the temperature of its case with the thermal time constant tau). K is linear;
// tau is located by a scan, as periodic_drift's frequency is, and common to all logs (a property of
// the gyro). Internal to the discover stage.
#pragma once

#include <vector>

namespace ssiu {

// One log's samples and the (compacted) bin of each sample, and its bin means of the drift.
struct LagLog {
  const std::vector<double>* t_s = nullptr;
  const std::vector<double>* temp_c = nullptr;
  const std::vector<int>* bin_of = nullptr;  // per sample: its bin (0..n_bins-1), or -1 when in none
  int n_bins = 0;
  const std::vector<double>* y_dph = nullptr;  // bin means of the drift (w - ref)
};

// Bin means of Z1 of the lagged temperature, (T_lag - 20 C)/10 C (eq. (1)'s normalisation), for time
// constant tau_s. The lag starts at the first logged temperature (the log begins in equilibrium) and
// is propagated exactly between samples for a temperature linear between them.
std::vector<double> LaggedTemperatureBins(const LagLog& log, double tau_s);

struct ThermalLagScan {
  bool ok = false;                                  // a scan was made (the temperature moves)
  double tau_s = 0;                                 // best time constant
  int positions = 0;                                // independent time constants tried (the scan's cost)
  std::vector<std::vector<double>> column;          // per log: LaggedTemperatureBins at tau_s
  std::vector<std::vector<double>> d_column_d_tau;  // per log: its derivative in tau (per second)
};

// Time constants from tau_min_s to tau_max_s on a logarithmic grid, then refined: the one whose lagged
// temperature best fits the drift by least squares with a bias per log and one K common to all logs.
ThermalLagScan ScanThermalLag(const std::vector<LagLog>& logs, double tau_min_s, double tau_max_s);

}  // namespace ssiu
