// How a solve ended (identification, attitude, a frame or a set of frames): expected failure is data,
// not an exception. The JSON/CSV spelling (conventions.md "status values of a solve") is
// SolveStatusName's, used only at the edges.
#pragma once

#include <ostream>

namespace ssiu {

enum class SolveStatus {
  kSolved,       // "solved"
  kNoMatch,      // "no_match": no hypothesis verified (or the heads disagree)
  kTooFewStars,  // "too_few_stars": fewer centroids or matches than a solution needs
  kNoFrame,      // "no_frame": the unit processor's head had no frame at that time
  kBadFrame,     // "bad_frame": the unit processor refused the frame (wrong size or stride, a bad time
                 // tag, not one view per head); nothing was solved from it
};

inline const char* SolveStatusName(SolveStatus s) {
  switch (s) {
    case SolveStatus::kSolved:
      return "solved";
    case SolveStatus::kNoMatch:
      return "no_match";
    case SolveStatus::kTooFewStars:
      return "too_few_stars";
    case SolveStatus::kNoFrame:
      return "no_frame";
    case SolveStatus::kBadFrame:
      return "bad_frame";
  }
  return "no_match";  // not reached
}
inline std::ostream& operator<<(std::ostream& os, SolveStatus v) { return os << SolveStatusName(v); }

}  // namespace ssiu
