#include "stampscan/jobs/colormap.hpp"

#include "stampscan/report/colour_scale.hpp"

#include <algorithm>
#include <cmath>

namespace stampscan::jobs {

Rgb temperatureColor(double t) {
  if (!std::isfinite(t)) return {128, 128, 128};
  t = std::clamp(t, 0.0, 1.0);
  // Piecewise-linear through blue, cyan, green, yellow, red.
  static constexpr double kStops[5][3] = {{0, 0, 255}, {0, 255, 255}, {0, 255, 0}, {255, 255, 0}, {255, 0, 0}};
  const double s = t * 4.0;
  const int i = std::min(3, static_cast<int>(s));
  const double f = s - i;
  Rgb c;
  for (int k = 0; k < 3; ++k)
    c[static_cast<std::size_t>(k)] = static_cast<std::uint8_t>(std::lround(kStops[i][k] + f * (kStops[i + 1][k] - kStops[i][k])));
  return c;
}

std::vector<Rgb> colorize(const std::vector<double>& values, double lo, double hi) {
  std::vector<Rgb> colors;
  colors.reserve(values.size());
  const double span = hi > lo ? hi - lo : 1.0;
  for (double v : values) colors.push_back(temperatureColor((v - lo) / span));
  return colors;
}

std::array<double, 2> displayRange(const std::vector<double>& values) {
  const auto [lo, hi] = report::robustRange(values);
  return {lo, hi > lo ? hi : lo + 1e-9};
}

}  // namespace stampscan::jobs
