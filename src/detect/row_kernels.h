// Internal to detect: the per-row loops of the full-frame threshold pass, each compiled twice
// (AVX2 and the baseline instruction set) and picked at load time, so that a portable build still
// runs 8-wide on the machines that have it.
#pragma once

#include <cstdint>

namespace ssiu {

// Smallest value of the row.
uint16_t RowMin(const uint16_t* row, int n);

// cs[x] += add[x] - sub[x]: slides column sums of a box down by one row.
void SlideColumnSums(int32_t* cs, const uint16_t* add, const uint16_t* sub, int n);

// above[x] = box sum at x > t0[x] + ay * (t1[x] - t0[x]) for x in [half, n - half), where the box
// sum is cs[x - half] + ... + cs[x + half]; the threshold is linear in ay between two precomputed
// rows (bilinear background: rows at tile centres). Returns whether any pixel is above.
bool BoxAboveThreshold(const int32_t* cs, const float* t0, const float* t1, float ay, int half, int n, uint8_t* above);

}  // namespace ssiu
