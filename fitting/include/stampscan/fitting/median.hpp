// The median as every robust step of the station takes it (scales of residuals, typical spacings,
// levels): one definition, one behaviour on no values.
#pragma once

#include <algorithm>
#include <cstddef>
#include <limits>
#include <vector>

namespace stampscan::fitting {

// The upper middle value (index n/2 once sorted), found by partial sorting: `values` is reordered.
// NaN for no values.
template <class T>
double medianInPlace(std::vector<T>& values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return static_cast<double>(*mid);
}

// The same of a copy.
template <class T>
double median(std::vector<T> values) {
  return medianInPlace(values);
}

// The median, or `if_none` for no values: for a caller to whom "no values" has a meaning.
template <class T>
double medianOr(std::vector<T> values, double if_none) {
  return values.empty() ? if_none : medianInPlace(values);
}

}  // namespace stampscan::fitting
