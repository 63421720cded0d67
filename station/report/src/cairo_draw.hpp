// Cairo helpers shared by the report's images and documents: owning handles, PNG bytes in memory,
// text, the colour bar, spot markers and the scale bar. The same drawing code paints a PNG (image
// surface) and a PDF page (vector surface); units are pixels on the one, points on the other.
#pragma once

#include "stampscan/report/colour_scale.hpp"

#include <cairo.h>

#include <memory>
#include <string>

namespace stampscan::report::draw {

struct SurfaceRelease {
  void operator()(cairo_surface_t* s) const { cairo_surface_destroy(s); }
};
struct ContextRelease {
  void operator()(cairo_t* c) const { cairo_destroy(c); }
};
using Surface = std::unique_ptr<cairo_surface_t, SurfaceRelease>;
using Context = std::unique_ptr<cairo_t, ContextRelease>;

// Throws std::runtime_error naming `what` when the surface or context is in an error state.
void check(cairo_surface_t* surface, const std::string& what);
void check(cairo_t* cr, const std::string& what);

// An ARGB32 image surface, cleared to white (opaque) or transparent.
Surface imageSurface(int width, int height, bool opaque_white);
Context contextFor(cairo_surface_t* surface);
// The surface encoded as PNG.
std::string encodePng(cairo_surface_t* surface);

void setColour(cairo_t* cr, const Rgb& c, double alpha = 1.0);
void setGrey(cairo_t* cr, double level);

enum class Align { Left, Centre, Right };
// Text with its baseline at y; `bold` selects the bold face. Returns the text's width.
double text(cairo_t* cr, double x, double y, const std::string& s, double size, Align align = Align::Left,
            bool bold = false);

// A vertical colour bar: the bands from the lowest (bottom) to the highest (top), edge labels to
// the right, title and unit above. The rectangle is the whole bar with its labels.
void colourBar(cairo_t* cr, double x, double y, double w, double h, const ColourScale& scale);
// A numbered marker for a worst spot: a ring with the number beside it.
void spotMarker(cairo_t* cr, double x, double y, int number, double size);
// A scale bar of a round length in mm that fits in `max_width`, its left end at (x, y).
void scaleBar(cairo_t* cr, double x, double y, double max_width, double units_per_mm, double size);

}  // namespace stampscan::report::draw
