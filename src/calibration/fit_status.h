// The outcome of a calibration fit (Allan noise terms, FOG thermal drift, magnetic sensitivity).
// Bad input throws InputError; a fit that ran says how it ended here (JSON: FitStatusName).
#pragma once

#include <ostream>

namespace ssiu {

enum class FitStatus {
  kFitted,        // "fitted"
  kTooFewPoints,  // "too_few_points": not enough independent points for any term
};

inline const char* FitStatusName(FitStatus s) { return s == FitStatus::kFitted ? "fitted" : "too_few_points"; }
inline std::ostream& operator<<(std::ostream& os, FitStatus v) { return os << FitStatusName(v); }

}  // namespace ssiu
