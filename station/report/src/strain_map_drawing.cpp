#include "strain_map_drawing.hpp"

#include <algorithm>
#include <cmath>

namespace stampscan::report {

const char* fileStem(MapQuantity q) {
  switch (q) {
    case MapQuantity::Thinning: return "thinning";
    case MapQuantity::MajorStrain: return "major-strain";
    case MapQuantity::SafetyMargin: return "safety-margin";
  }
  return "?";
}

const char* caption(MapQuantity q) {
  switch (q) {
    case MapQuantity::Thinning: return "Thinning";
    case MapQuantity::MajorStrain: return "Major strain";
    case MapQuantity::SafetyMargin: return "Safety margin";
  }
  return "?";
}

std::string strainMapFileName(MapQuantity q, const View& view) {
  return std::string(fileStem(q)) + "-" + view.name + ".png";
}

std::vector<double> quantityValues(const StrainAnalysis& a, MapQuantity q) {
  std::vector<double> values;
  values.reserve(a.elements.size());
  for (const ElementStrain& e : a.elements)
    values.push_back(q == MapQuantity::Thinning      ? e.thinning_percent
                     : q == MapQuantity::MajorStrain ? e.major_percent
                                                     : e.margin_percent);
  return values;
}

ColourScale scaleFor(MapQuantity q, const StrainAnalysis& a, const Material& material) {
  switch (q) {
    case MapQuantity::Thinning: return thinningScale(quantityValues(a, q));
    case MapQuantity::MajorStrain: return majorStrainScale(quantityValues(a, q));
    case MapQuantity::SafetyMargin: return safetyMarginScale(material.safety_margin_percent);
  }
  return safetyMarginScale(material.safety_margin_percent);
}

namespace draw {

Surface colourRaster(const RenderedView& r, const ColourScale& scale) {
  Surface surface = imageSurface(r.width, r.height, false);
  cairo_surface_flush(surface.get());
  unsigned char* data = cairo_image_surface_get_data(surface.get());
  const int stride = cairo_image_surface_get_stride(surface.get());
  for (int y = 0; y < r.height; ++y) {
    auto* row = reinterpret_cast<std::uint32_t*>(data + static_cast<std::ptrdiff_t>(y) * stride);
    for (int x = 0; x < r.width; ++x) {
      const std::size_t i = r.at(x, y);
      if (!r.covered[i]) {
        row[x] = 0;  // transparent
        continue;
      }
      const Rgb c = scale.colourOf(r.value[i]);
      const auto channel = [&](std::uint8_t v) {
        return static_cast<std::uint32_t>(std::lround(std::clamp(v * r.shade[i], 0.0f, 255.0f)));
      };
      // CAIRO_FORMAT_ARGB32: native-endian 32-bit words, alpha in the top byte (opaque here).
      row[x] = 0xff000000u | (channel(c[0]) << 16) | (channel(c[1]) << 8) | channel(c[2]);
    }
  }
  cairo_surface_mark_dirty(surface.get());
  return surface;
}

void placeMap(cairo_t* cr, const MapRaster& map, double x, double y, double w, double h, double marker_size) {
  const double rw = cairo_image_surface_get_width(map.raster.get());
  const double rh = cairo_image_surface_get_height(map.raster.get());
  const double k = std::min(w / rw, h / rh);
  const double ox = x + (w - rw * k) / 2, oy = y + (h - rh * k) / 2;
  cairo_save(cr);
  cairo_translate(cr, ox, oy);
  cairo_scale(cr, k, k);
  cairo_set_source_surface(cr, map.raster.get(), 0, 0);
  // One raster pixel to one image pixel on a PNG: nearest keeps the band colours exact.
  cairo_pattern_set_filter(cairo_get_source(cr), std::abs(k - 1.0) < 1e-9 ? CAIRO_FILTER_NEAREST : CAIRO_FILTER_GOOD);
  cairo_paint(cr);
  cairo_restore(cr);
  for (const MapRaster::Spot& s : map.spots) spotMarker(cr, ox + s.x * k, oy + s.y * k, s.number, marker_size);
  const double strip = y + h + marker_size * 1.9;
  scaleBar(cr, x + marker_size, strip, w * 0.3, map.pixels_per_mm * k, marker_size * 1.3);
  setGrey(cr, 0.35);
  text(cr, x + w - marker_size * 0.5, strip, map.view.name + " view", marker_size * 1.3, Align::Right);
}

std::string strainMapPng(const MapRaster& map, const ColourScale& scale, const std::string& title) {
  using L = StrainMapLayout;
  Surface surface = imageSurface(L::width, L::height, true);
  Context cr = contextFor(surface.get());
  setGrey(cr.get(), 0.1);
  text(cr.get(), 16, 36, title, 22, Align::Left, true);
  placeMap(cr.get(), map, L::map_x, L::map_y, L::map_width, L::map_height, 9);
  colourBar(cr.get(), L::bar_x, L::bar_y, L::bar_width, L::bar_height, scale);
  check(cr.get(), "drawing the strain map " + strainMapFileName(map.quantity, map.view));
  cairo_surface_flush(surface.get());
  return encodePng(surface.get());
}

}  // namespace draw
}  // namespace stampscan::report
