#include "stampscan/report/colour_scale.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampscan::report {

ColourScale::ColourScale(std::string title, std::string unit, std::vector<double> edges, std::vector<Rgb> colours)
    : title_(std::move(title)), unit_(std::move(unit)), edges_(std::move(edges)), colours_(std::move(colours)) {
  if (colours_.empty() || edges_.size() != colours_.size() + 1)
    throw std::invalid_argument("a colour scale needs one more edge than colours");
  for (std::size_t i = 1; i < edges_.size(); ++i)
    if (!(edges_[i] > edges_[i - 1])) throw std::invalid_argument("colour scale edges must increase");
}

Rgb ColourScale::colourOf(double value) const {
  if (std::isnan(value)) return kNoValueColour;
  // The band whose [lower, upper) holds the value; the end bands take everything beyond.
  const auto upper = std::upper_bound(edges_.begin() + 1, edges_.end() - 1, value);
  return colours_[static_cast<std::size_t>(upper - (edges_.begin() + 1))];
}

std::size_t ColourScale::labelStep() const { return colours_.size() > 14 ? 2 : 1; }

std::vector<Rgb> temperatureBands(std::size_t bands) {
  static constexpr double kStops[5][3] = {{0, 40, 255}, {0, 220, 255}, {40, 200, 40}, {255, 230, 0}, {230, 0, 0}};
  std::vector<Rgb> out;
  for (std::size_t b = 0; b < bands; ++b) {
    const double t = bands > 1 ? static_cast<double>(b) / static_cast<double>(bands - 1) : 0.5;
    const double s = t * 4.0;
    const int i = std::min(3, static_cast<int>(s));
    const double f = s - i;
    Rgb c;
    for (int k = 0; k < 3; ++k)
      c[static_cast<std::size_t>(k)] =
          static_cast<std::uint8_t>(std::lround(kStops[i][k] + f * (kStops[i + 1][k] - kStops[i][k])));
    out.push_back(c);
  }
  return out;
}

ColourScale roundedScale(std::string title, std::string unit, double lo, double hi, std::size_t target_bands) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) {
    lo = 0;
    hi = 1;
  }
  if (hi - lo < 1e-6) hi = lo + 1.0;
  const double raw = (hi - lo) / static_cast<double>(std::max<std::size_t>(target_bands, 2));
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  double step = 10 * power;
  for (const double m : {1.0, 2.0, 2.5, 5.0})
    if (m * power >= raw) {
      step = m * power;
      break;
    }
  const double first = std::floor(lo / step + 1e-9) * step;
  const double last = std::ceil(hi / step - 1e-9) * step;
  std::vector<double> edges;
  for (double e = first; e <= last + step * 0.5; e += step) edges.push_back(std::abs(e) < step * 1e-9 ? 0.0 : e);
  if (edges.size() < 2) edges.push_back(edges.back() + step);
  return ColourScale(std::move(title), std::move(unit), edges, temperatureBands(edges.size() - 1));
}

std::array<double, 2> robustRange(const std::vector<double>& values) {
  std::vector<double> finite;
  finite.reserve(values.size());
  for (const double v : values)
    if (std::isfinite(v)) finite.push_back(v);
  if (finite.empty()) return {0.0, 1.0};
  const auto at = [&](double q) {
    auto it = finite.begin() + static_cast<std::ptrdiff_t>(q * static_cast<double>(finite.size() - 1));
    std::nth_element(finite.begin(), it, finite.end());
    return *it;
  };
  return {at(0.01), at(0.99)};
}

ColourScale thinningScale(const std::vector<double>& thinning) {
  const auto [lo, hi] = robustRange(thinning);
  return roundedScale("Thinning", "%", std::min(lo, 0.0), std::max(hi, 1.0));
}

ColourScale majorStrainScale(const std::vector<double>& major) {
  const auto [lo, hi] = robustRange(major);
  return roundedScale("Major strain", "engineering %", std::min(lo, 0.0), std::max(hi, 1.0));
}

ColourScale safetyMarginScale(double margin) {
  // Failure below 0, the marginal band split in two, then safe bands of the same width.
  const double half = margin / 2;
  std::vector<double> edges{
      -2 * margin, 0.0, half, margin, margin + half * 2, margin + half * 4, margin + half * 6, margin + half * 8};
  std::vector<Rgb> colours{{230, 0, 0},   {255, 140, 0}, {255, 220, 0}, {150, 215, 60},
                           {40, 170, 60}, {0, 150, 150}, {0, 90, 220}};
  return ColourScale("Safety margin", "engineering %", edges, colours);
}

}  // namespace stampscan::report
