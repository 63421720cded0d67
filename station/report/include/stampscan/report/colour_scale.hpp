// Banded colour scales for the strain maps. Strain-analysis software colours strain in bands, not
// as a continuous ramp: the operator reads a value off the colour bar, and the band edges trace
// contour lines over the part. Every map in a report carries its scale as a colour bar.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace stampscan::report {

using Rgb = std::array<std::uint8_t, 3>;

// The colour of what has no value (a mesh vertex with no measured element near it).
inline constexpr Rgb kNoValueColour{170, 170, 170};

class ColourScale {
 public:
  // `edges` strictly increasing, one more than `colours`. Values below the first edge take the first
  // colour, above the last the last colour; NaN takes kNoValueColour.
  ColourScale(std::string title, std::string unit, std::vector<double> edges, std::vector<Rgb> colours);

  Rgb colourOf(double value) const;
  const std::string& title() const { return title_; }
  const std::string& unit() const { return unit_; }
  const std::vector<double>& edges() const { return edges_; }
  const std::vector<Rgb>& colours() const { return colours_; }
  // Labels on the colour bar: an edge label every `labelStep()` bands.
  std::size_t labelStep() const;

 private:
  std::string title_, unit_;
  std::vector<double> edges_;
  std::vector<Rgb> colours_;
};

// Blue (least) through cyan, green and yellow to red (most), in `bands` steps.
std::vector<Rgb> temperatureBands(std::size_t bands);

// A scale over [lo, hi] with a round band width (1, 2, 2.5 or 5 times a power of ten), about
// `target_bands` bands, temperature colours.
ColourScale roundedScale(std::string title, std::string unit, double lo, double hi, std::size_t target_bands = 12);

// Thinning in %, over the values' range (from 0, or below when the part thickened).
ColourScale thinningScale(const std::vector<double>& thinning_percent);
// The 1st and 99th percentiles of the finite values ({0, 1} when there are none): a few outliers
// then take the end colours instead of washing out the map.
std::array<double, 2> robustRange(const std::vector<double>& values);
// Major engineering strain in %, over the values' range (from 0, or below).
ColourScale majorStrainScale(const std::vector<double>& major_percent);
// The safety margin in engineering strain %, fixed to the material's marginal band: red at and
// below zero (failure), orange and yellow within the marginal band, greens to blue above it.
ColourScale safetyMarginScale(double safety_margin_percent);

}  // namespace stampscan::report
