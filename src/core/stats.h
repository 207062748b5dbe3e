// Small order statistics shared by the stages.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace ssiu {

// The upper median (element n/2 of the sorted values; 0 for none): by value, so the caller's order
// is kept.
inline double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// 1.4826 x median absolute deviation: the Gaussian sigma of a sample with outliers.
inline double RobustSigma(const std::vector<double>& v) {
  const double m = Median(v);
  std::vector<double> a;
  a.reserve(v.size());
  for (double x : v) a.push_back(std::abs(x - m));
  return 1.4826 * Median(a);
}

}  // namespace ssiu
