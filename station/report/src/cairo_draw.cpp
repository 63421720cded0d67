#include "cairo_draw.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace stampscan::report::draw {

namespace {
constexpr const char* kFont = "DejaVu Sans";

std::string formatEdge(double v) {
  char text[32];
  if (std::abs(v - std::round(v)) < 1e-6)
    std::snprintf(text, sizeof text, "%.0f", v);
  else if (std::abs(v * 10 - std::round(v * 10)) < 1e-6)
    std::snprintf(text, sizeof text, "%.1f", v);
  else
    std::snprintf(text, sizeof text, "%.2f", v);
  return text;
}

cairo_status_t appendBytes(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}
}  // namespace

void check(cairo_surface_t* surface, const std::string& what) {
  const cairo_status_t status = cairo_surface_status(surface);
  if (status != CAIRO_STATUS_SUCCESS) throw std::runtime_error(what + ": " + cairo_status_to_string(status));
}

void check(cairo_t* cr, const std::string& what) {
  const cairo_status_t status = cairo_status(cr);
  if (status != CAIRO_STATUS_SUCCESS) throw std::runtime_error(what + ": " + cairo_status_to_string(status));
}

Surface imageSurface(int width, int height, bool opaque_white) {
  Surface s(cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height));
  check(s.get(), "an image of " + std::to_string(width) + " x " + std::to_string(height) + " pixels");
  if (opaque_white) {
    Context cr = contextFor(s.get());
    cairo_set_source_rgb(cr.get(), 1, 1, 1);
    cairo_paint(cr.get());
  }
  return s;
}

Context contextFor(cairo_surface_t* surface) {
  Context cr(cairo_create(surface));
  check(cr.get(), "a drawing context");
  return cr;
}

std::string encodePng(cairo_surface_t* surface) {
  std::string bytes;
  const cairo_status_t status = cairo_surface_write_to_png_stream(surface, appendBytes, &bytes);
  if (status != CAIRO_STATUS_SUCCESS)
    throw std::runtime_error(std::string("PNG encoding: ") + cairo_status_to_string(status));
  return bytes;
}

void setColour(cairo_t* cr, const Rgb& c, double alpha) {
  cairo_set_source_rgba(cr, c[0] / 255.0, c[1] / 255.0, c[2] / 255.0, alpha);
}

void setGrey(cairo_t* cr, double level) { cairo_set_source_rgb(cr, level, level, level); }

double text(cairo_t* cr, double x, double y, const std::string& s, double size, Align align, bool bold) {
  cairo_select_font_face(cr, kFont, CAIRO_FONT_SLANT_NORMAL, bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  const double left = align == Align::Left ? x : align == Align::Centre ? x - e.x_advance / 2 : x - e.x_advance;
  cairo_move_to(cr, left, y);
  cairo_show_text(cr, s.c_str());
  return e.x_advance;
}

void colourBar(cairo_t* cr, double x, double y, double w, double h, const ColourScale& scale) {
  const double title_size = std::max(8.0, w * 0.085);
  const double label_size = title_size * 0.9;
  setGrey(cr, 0.1);
  text(cr, x, y + title_size, scale.title(), title_size, Align::Left, true);
  text(cr, x, y + 2.3 * title_size, "(" + scale.unit() + ")", label_size);
  const double bar_x = x, bar_w = std::min(w * 0.22, 3.0 * title_size);
  const double bar_top = y + 3.2 * title_size, bar_bottom = y + h - label_size;
  const std::size_t bands = scale.colours().size();
  const double band_h = (bar_bottom - bar_top) / static_cast<double>(bands);
  for (std::size_t b = 0; b < bands; ++b) {
    setColour(cr, scale.colours()[b]);
    const double top = bar_bottom - static_cast<double>(b + 1) * band_h;
    cairo_rectangle(cr, bar_x, top, bar_w, band_h + 0.3);  // the overlap hides seams between bands
    cairo_fill(cr);
  }
  setGrey(cr, 0.2);
  cairo_set_line_width(cr, std::max(0.5, w * 0.006));
  cairo_rectangle(cr, bar_x, bar_top, bar_w, bar_bottom - bar_top);
  cairo_stroke(cr);
  const std::size_t step = scale.labelStep();
  for (std::size_t e = 0; e < scale.edges().size(); e += step) {
    const double at = bar_bottom - static_cast<double>(e) * band_h;
    cairo_move_to(cr, bar_x + bar_w, at);
    cairo_line_to(cr, bar_x + bar_w + label_size * 0.4, at);
    cairo_stroke(cr);
    std::string label = formatEdge(scale.edges()[e]);
    // The end bands take everything beyond their edge.
    if (e == 0) label = "\u2264 " + label;
    if (e + 1 == scale.edges().size()) label = "\u2265 " + label;
    text(cr, bar_x + bar_w + label_size * 0.6, at + label_size * 0.35, label, label_size);
  }
}

void spotMarker(cairo_t* cr, double x, double y, int number, double size) {
  cairo_new_path(cr);  // the ring must not join whatever was drawn last
  cairo_set_line_width(cr, size * 0.22);
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_arc(cr, x, y, size, 0, 2 * M_PI);
  cairo_stroke(cr);
  cairo_set_line_width(cr, size * 0.12);
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_new_sub_path(cr);
  cairo_arc(cr, x, y, size, 0, 2 * M_PI);
  cairo_stroke(cr);
  // The number on a white patch beside the ring, readable over any colour.
  const std::string label = std::to_string(number);
  cairo_select_font_face(cr, kFont, CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_BOLD);
  cairo_set_font_size(cr, size * 1.5);
  cairo_text_extents_t e;
  cairo_text_extents(cr, label.c_str(), &e);
  const double lx = x + size * 1.2, ly = y - size * 1.2;
  cairo_set_source_rgba(cr, 1, 1, 1, 0.85);
  cairo_rectangle(cr, lx - size * 0.2, ly - e.height - size * 0.2, e.x_advance + size * 0.4, e.height + size * 0.4);
  cairo_fill(cr);
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_move_to(cr, lx, ly);
  cairo_show_text(cr, label.c_str());
}

void scaleBar(cairo_t* cr, double x, double y, double max_width, double units_per_mm, double size) {
  if (!(units_per_mm > 0)) return;
  double length = 1;
  for (const double candidate : {1.0, 2.0, 5.0, 10.0, 20.0, 25.0, 50.0, 100.0, 200.0, 250.0, 500.0, 1000.0})
    if (candidate * units_per_mm <= max_width) length = candidate;
  const double w = length * units_per_mm;
  setGrey(cr, 0.15);
  cairo_set_line_width(cr, size * 0.15);
  cairo_move_to(cr, x, y - size * 0.4);
  cairo_line_to(cr, x, y);
  cairo_line_to(cr, x + w, y);
  cairo_line_to(cr, x + w, y - size * 0.4);
  cairo_stroke(cr);
  text(cr, x + w / 2, y - size * 0.3, formatEdge(length) + " mm", size, Align::Centre);
}

}  // namespace stampscan::report::draw
