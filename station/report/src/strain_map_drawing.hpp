// Drawing of the strain maps (strain_map.hpp): the rendered view coloured by a scale into a
// raster, and the raster with its spot markers placed on a PNG or a PDF page.
#pragma once

#include "cairo_draw.hpp"
#include "stampscan/report/strain_map.hpp"

#include <string>
#include <vector>

namespace stampscan::report::draw {

// One view of one quantity, rendered: the raster of the map (transparent where there is no part)
// and where the worst spots fall in it.
struct MapRaster {
  MapQuantity quantity = MapQuantity::Thinning;
  View view;
  Surface raster;
  double pixels_per_mm = 1;
  struct Spot {
    double x, y;  // raster pixels
    int number;   // 1-based rank in the worst-spot list
  };
  std::vector<Spot> spots;  // the visible ones
};

Surface colourRaster(const RenderedView& rendered, const ColourScale& scale);

// The map raster placed into (x, y, w, h) of `cr`, scaled to fit, its spots marked; the scale bar
// and the view's name in a strip of 2.2 marker sizes below the rectangle.
void placeMap(cairo_t* cr, const MapRaster& map, double x, double y, double w, double h, double marker_size);

// The PNG of one map (StrainMapLayout) with its title line.
std::string strainMapPng(const MapRaster& map, const ColourScale& scale, const std::string& title);

}  // namespace stampscan::report::draw
