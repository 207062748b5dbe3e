// gtest prints a failed EXPECT_EQ(..., SSIU_OK) by the result's name (ADL finds PrintTo in the C
// enum's namespace, the global one).
#pragma once
#include <ostream>

#include "flight/ssiu_flight.h"

inline void PrintTo(ssiu_result r, std::ostream* os) { *os << ssiu_flight_result_name(r); }
