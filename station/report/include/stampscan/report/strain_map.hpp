// Strain maps: the fitted surface seen from a standard view, coloured by one quantity in bands,
// with its colour bar and the worst spots marked. The layout of the PNG files is fixed and public,
// so that a pixel of a map can be traced back to the place on the part it shows.
#pragma once

#include "stampscan/report/colour_scale.hpp"
#include "stampscan/report/strain_analysis.hpp"
#include "stampscan/report/surface_render.hpp"

#include <string>
#include <vector>

namespace stampscan::report {

enum class MapQuantity { Thinning, MajorStrain, SafetyMargin };
inline constexpr MapQuantity kMapQuantities[] = {MapQuantity::Thinning, MapQuantity::MajorStrain,
                                                 MapQuantity::SafetyMargin};
// "thinning", "major-strain", "safety-margin": the file name stem.
const char* fileStem(MapQuantity quantity);
// "Thinning", "Major strain", "Safety margin": for captions.
const char* caption(MapQuantity quantity);
// "thinning-top.png"
std::string strainMapFileName(MapQuantity quantity, const View& view);

// The element values of a quantity (thinning %, major engineering strain %, safety margin %).
std::vector<double> quantityValues(const StrainAnalysis& analysis, MapQuantity quantity);
// The scale a report uses for a quantity.
ColourScale scaleFor(MapQuantity quantity, const StrainAnalysis& analysis, const Material& material);

// A strain-map PNG: title on top, the map at (map_x, map_y) of map_width x map_height pixels, drawn
// one rendered pixel to one image pixel, scale bar and view name below it, the colour bar on the right.
struct StrainMapLayout {
  static constexpr int width = 1040, height = 740;
  static constexpr int map_x = 10, map_y = 52, map_width = 800, map_height = 654;
  static constexpr int bar_x = 830, bar_y = 70, bar_width = 200, bar_height = 560;
};

}  // namespace stampscan::report
