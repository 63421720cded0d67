// Temperature colour map for strain: blue (least thinning) through green and yellow to red (most).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace stampscan::jobs {

using Rgb = std::array<std::uint8_t, 3>;

// t in [0, 1] (clamped; NaN maps to grey).
Rgb temperatureColor(double t);
// Colours for values mapped linearly from [lo, hi] onto the map.
std::vector<Rgb> colorize(const std::vector<double>& values, double lo, double hi);
// A robust display range: the 1st and 99th percentiles, so a few outliers do not wash out the map.
std::array<double, 2> displayRange(const std::vector<double>& values);

}  // namespace stampscan::jobs
