// gtest prints a failed EXPECT_EQ on a C enum of the flight interface by name (ADL finds PrintTo in
// the C enum's namespace, the global one): a result by ssiu_flight_result_name ("err_memory"), the
// other statuses by their enumerator ("SSIU_GYRO_PARTIAL"); a value outside the enum as "unknown (N)".
#pragma once
#include <ostream>

#include "flight/ssiu_flight.h"

inline void PrintTo(ssiu_result r, std::ostream* os) { *os << ssiu_flight_result_name(r); }

namespace ssiu::testing {
// names[v] for 0 <= v < n, else "unknown (v)".
inline void PrintEnumerator(int v, const char* const* names, int n, std::ostream* os) {
  if (v >= 0 && v < n) {
    *os << names[v];
  } else {
    *os << "unknown (" << v << ")";
  }
}
}  // namespace ssiu::testing

inline void PrintTo(ssiu_gyro_status s, std::ostream* os) {
  static const char* const kNames[] = {"SSIU_GYRO_ACCEPTED",
                                       "SSIU_GYRO_REJECTED_NON_FINITE",
                                       "SSIU_GYRO_REJECTED_OUT_OF_RANGE",
                                       "SSIU_GYRO_REJECTED_OUT_OF_ORDER",
                                       "SSIU_GYRO_REJECTED_REPEATED",
                                       "SSIU_GYRO_PARTIAL",
                                       "SSIU_GYRO_ACCEPTED_AFTER_GAP",
                                       "SSIU_GYRO_REJECTED_BAD_TIME",
                                       "SSIU_GYRO_REJECTED_WRONG_SIZE",
                                       "SSIU_GYRO_REJECTED_TIME_JUMP",
                                       "SSIU_GYRO_ACCEPTED_TIME_RESET"};
  ssiu::testing::PrintEnumerator(s, kNames, 11, os);
}

inline void PrintTo(ssiu_solve_status s, std::ostream* os) {
  static const char* const kNames[] = {"SSIU_SOLVE_SOLVED", "SSIU_SOLVE_NO_MATCH", "SSIU_SOLVE_TOO_FEW_STARS",
                                       "SSIU_SOLVE_NO_FRAME", "SSIU_SOLVE_BAD_FRAME"};
  ssiu::testing::PrintEnumerator(s, kNames, 5, os);
}

inline void PrintTo(ssiu_update_status s, std::ostream* os) {
  static const char* const kNames[] = {"SSIU_UPDATE_ACCEPTED",           "SSIU_UPDATE_INITIALISED",
                                       "SSIU_UPDATE_REJECTED_NIS",       "SSIU_UPDATE_REJECTED_LATE",
                                       "SSIU_UPDATE_REJECTED_REPEATED",  "SSIU_UPDATE_REJECTED_BAD_INPUT",
                                       "SSIU_UPDATE_REJECTED_TIME_JUMP", "SSIU_UPDATE_NONE"};
  ssiu::testing::PrintEnumerator(s, kNames, 8, os);
}

inline void PrintTo(ssiu_status s, std::ostream* os) {
  static const char* const kNames[] = {"SSIU_STATUS_OK", "SSIU_STATUS_DEGRADED", "SSIU_STATUS_FAILED"};
  ssiu::testing::PrintEnumerator(s, kNames, 3, os);
}

inline void PrintTo(ssiu_unit_cal_status s, std::ostream* os) {
  static const char* const kNames[] = {"SSIU_UNIT_CAL_OFF", "SSIU_UNIT_CAL_ACCUMULATING",
                                       "SSIU_UNIT_CAL_NOT_OBSERVABLE", "SSIU_UNIT_CAL_ESTIMATED",
                                       "SSIU_UNIT_CAL_APPLIED"};
  ssiu::testing::PrintEnumerator(s, kNames, 5, os);
}
