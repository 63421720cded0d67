// The trend image, drawn with cairo: two panels over the parts of a program (oldest left), the min
// safety margin above (marginal band shaded, the fitted drift line dashed) and the max thinning below.
// The report's drawing helpers are private to station/report/, and these plots need little of them.
#include "stampscan/results/trend.hpp"

#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <system_error>

namespace stampscan::results {

namespace {

struct SurfaceRelease {
  void operator()(cairo_surface_t* s) const { cairo_surface_destroy(s); }
};
struct ContextRelease {
  void operator()(cairo_t* c) const { cairo_destroy(c); }
};

struct Rgb {
  double r, g, b;
};
Rgb verdictColour(const std::string& verdict) {
  if (verdict == "good") return {0.16, 0.58, 0.24};
  if (verdict == "marginal") return {0.95, 0.60, 0.07};
  if (verdict == "failed") return {0.84, 0.11, 0.11};
  return {0.5, 0.5, 0.5};
}

void text(cairo_t* cr, double x, double y, const std::string& s, double size, bool right = false) {
  cairo_set_font_size(cr, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  cairo_move_to(cr, right ? x - e.x_advance : x, y);
  cairo_show_text(cr, s.c_str());
}

// A panel: the frame, y ticks, and a mapping from (part index, value) to pixels.
struct Panel {
  double x0, y0, w, h;  // plot area in pixels
  double lo, hi;        // value range
  std::size_t count;    // parts
  double px(double k) const { return x0 + (count <= 1 ? w / 2 : w * k / static_cast<double>(count - 1)); }
  double py(double v) const { return y0 + h * (1.0 - (v - lo) / (hi - lo)); }
};

Panel makePanel(cairo_t* cr, double x0, double y0, double w, double h, double lo, double hi, std::size_t count,
                const std::string& title) {
  if (!(hi > lo)) hi = lo + 1;
  const double pad = 0.08 * (hi - lo);
  Panel p{x0, y0, w, h, lo - pad, hi + pad, count};
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_width(cr, 1);
  cairo_rectangle(cr, x0, y0, w, h);
  cairo_stroke(cr);
  text(cr, x0, y0 - 8, title, 14);
  // Five y ticks at round-ish values.
  for (int i = 0; i <= 4; ++i) {
    const double v = p.lo + (p.hi - p.lo) * i / 4.0;
    char label[32];
    std::snprintf(label, sizeof label, "%.1f", v);
    cairo_set_source_rgb(cr, 0.85, 0.85, 0.85);
    cairo_move_to(cr, x0, p.py(v));
    cairo_line_to(cr, x0 + w, p.py(v));
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(cr, x0 - 6, p.py(v) + 4, label, 11, true);
  }
  return p;
}

void points(cairo_t* cr, const Panel& p, const TrendAnalysis& t, bool margin) {
  for (std::size_t k = 0; k < t.points.size(); ++k) {
    const auto& v = margin ? t.points[k].min_margin_percent : t.points[k].max_thinning_percent;
    if (!v) continue;
    const Rgb c = verdictColour(t.points[k].verdict);
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_arc(cr, p.px(static_cast<double>(k)), p.py(*v), 4.5, 0, 2 * M_PI);
    cairo_fill(cr);
  }
}

}  // namespace

void writeTrendImage(const TrendAnalysis& t, const std::string& program, const std::filesystem::path& png) {
  constexpr int kWidth = 960, kHeight = 640;
  std::unique_ptr<cairo_surface_t, SurfaceRelease> surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, kWidth, kHeight));
  std::unique_ptr<cairo_t, ContextRelease> context(cairo_create(surface.get()));
  cairo_t* cr = context.get();
  if (cairo_status(cr) != CAIRO_STATUS_SUCCESS) throw std::runtime_error(png.string() + ": cannot draw the trend image");
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  cairo_select_font_face(cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_source_rgb(cr, 0, 0, 0);
  text(cr, 20, 28, "Trend of program " + program + ": " + std::to_string(t.points.size()) + " parts", 18);
  if (t.drifting) cairo_set_source_rgb(cr, 0.84, 0.11, 0.11);
  // The message on up to two lines, broken after a "; ".
  const std::size_t split = t.message.size() > 120 ? t.message.rfind("; ", 120) : std::string::npos;
  text(cr, 20, 48, t.message.substr(0, split), 11);
  if (split != std::string::npos) text(cr, 20, 63, t.message.substr(split + 2, 140), 11);

  double m_lo = t.band_percent, m_hi = t.band_percent, th_lo = 0, th_hi = 1;
  bool first_thinning = true;
  for (const TrendPoint& p : t.points) {
    if (p.min_margin_percent) m_lo = std::min(m_lo, *p.min_margin_percent), m_hi = std::max(m_hi, *p.min_margin_percent);
    if (p.max_thinning_percent) {
      th_lo = first_thinning ? *p.max_thinning_percent : std::min(th_lo, *p.max_thinning_percent);
      th_hi = first_thinning ? *p.max_thinning_percent : std::max(th_hi, *p.max_thinning_percent);
      first_thinning = false;
    }
  }
  if (t.projected_margin) m_lo = std::min(m_lo, *t.projected_margin);
  m_lo = std::min(m_lo, 0.0);
  const std::size_t count = std::max<std::size_t>(t.points.size(), 1);

  const Panel margin = makePanel(cr, 80, 90, 840, 250, m_lo, m_hi, count, "min safety margin (engineering strain %)");
  // The marginal band: from the FLC (0) up to the material's safety margin.
  cairo_set_source_rgba(cr, 0.95, 0.60, 0.07, 0.25);
  const double band_top = margin.py(std::min(t.band_percent, margin.hi)), band_bottom = margin.py(std::max(0.0, margin.lo));
  cairo_rectangle(cr, margin.x0, band_top, margin.w, band_bottom - band_top);
  cairo_fill(cr);
  cairo_set_source_rgba(cr, 0.84, 0.11, 0.11, 0.15);  // below the FLC: failure
  cairo_rectangle(cr, margin.x0, band_bottom, margin.w, margin.y0 + margin.h - band_bottom);
  cairo_fill(cr);
  if (t.slope_per_part && t.intercept && t.points.size() > 1) {
    // The fitted line over its window, as far as the plot reaches (the projection is in the message).
    const double k0 = static_cast<double>(t.fit_first), k1 = static_cast<double>(t.points.size() - 1);
    cairo_set_source_rgb(cr, 0.2, 0.2, 0.7);
    const double dash[] = {6, 4};
    cairo_set_dash(cr, dash, 2, 0);
    cairo_set_line_width(cr, 2);
    cairo_move_to(cr, margin.px(k0), margin.py(*t.intercept + *t.slope_per_part * k0));
    cairo_line_to(cr, margin.px(k1), margin.py(*t.intercept + *t.slope_per_part * k1));
    cairo_stroke(cr);
    cairo_set_dash(cr, nullptr, 0, 0);
    cairo_set_line_width(cr, 1);
  }
  points(cr, margin, t, true);

  const Panel thinning = makePanel(cr, 80, 390, 840, 200, th_lo, th_hi, count, "max thinning %");
  points(cr, thinning, t, false);
  cairo_set_source_rgb(cr, 0, 0, 0);
  text(cr, thinning.x0, thinning.y0 + thinning.h + 22, "part 1", 11);
  text(cr, thinning.x0 + thinning.w, thinning.y0 + thinning.h + 22, "part " + std::to_string(t.points.size()), 11, true);
  const char* legend[] = {"good", "marginal", "failed"};
  for (int i = 0; i < 3; ++i) {
    const Rgb c = verdictColour(legend[i]);
    const double x = 400 + 110 * i, y = thinning.y0 + thinning.h + 22;
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_arc(cr, x, y - 4, 4.5, 0, 2 * M_PI);
    cairo_fill(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(cr, x + 9, y, legend[i], 11);
  }

  cairo_surface_flush(surface.get());
  // Written beside the target and renamed: a reader never sees half an image.
  const std::filesystem::path temporary = png.string() + ".tmp-trend";
  if (cairo_surface_write_to_png(surface.get(), temporary.c_str()) != CAIRO_STATUS_SUCCESS) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    throw std::runtime_error(png.string() + ": cannot be written");
  }
  std::error_code error;
  std::filesystem::rename(temporary, png, error);
  if (error) {
    std::filesystem::remove(temporary, error);
    throw std::runtime_error(png.string() + ": cannot be written (" + error.message() + ")");
  }
}

}  // namespace stampscan::results
