#include "stampscan/report/forming_limit.hpp"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

namespace stampscan::report {

namespace {
constexpr double kInfinity = std::numeric_limits<double>::infinity();
// The search along a strain path: steps of 0.005 true strain out to 2.5 (1100% engineering), then
// bisection. No sheet metal gets that far; a path that meets no limit by then never does.
constexpr double kPathStep = 0.005;
constexpr double kPathReach = 2.5;

// A point of the diagram (engineering %) at true strain s along the unit true-strain direction.
FldPoint alongPath(double s, double du, double dv) { return {engineeringPercent(s * du), engineeringPercent(s * dv)}; }
}  // namespace

double keelerBrazierFlc0(double thickness_mm, double n) {
  if (!(thickness_mm > 0) || !(n > 0))
    throw std::invalid_argument("Keeler-Brazier FLC0 needs a thickness and an n above zero (got t = " +
                                std::to_string(thickness_mm) + " mm, n = " + std::to_string(n) + ")");
  const double t = std::min(thickness_mm, kKeelerBrazierMaxThicknessMm);
  return (23.3 + 14.13 * t) * n / 0.21;
}

FormingLimitCurve FormingLimitCurve::keelerBrazier(double flc0_percent) {
  if (!(flc0_percent > 0)) throw std::invalid_argument("an FLC needs FLC0 above zero");
  FormingLimitCurve c;
  c.flc0_ = flc0_percent;
  return c;
}

FormingLimitCurve FormingLimitCurve::measured(std::vector<FldPoint> points) {
  if (points.size() < 2) throw std::invalid_argument("a measured FLC needs at least two points");
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!std::isfinite(points[i].minor) || !std::isfinite(points[i].major))
      throw std::invalid_argument("FLC point " + std::to_string(i + 1) + " is not a finite number");
    if (i > 0 && !(points[i].minor > points[i - 1].minor))
      throw std::invalid_argument("FLC points must have strictly increasing minor strain (point " +
                                  std::to_string(i + 1) + " does not)");
  }
  FormingLimitCurve c;
  c.points_ = std::move(points);
  c.flc0_ = c.majorAt(0.0);
  if (!(c.flc0_ > 0))
    throw std::invalid_argument("a measured FLC must lie above zero major strain at zero minor strain");
  return c;
}

double FormingLimitCurve::majorAt(double minor) const {
  if (points_.empty()) {
    if (minor >= 0) return flc0_ + kKeelerBrazierRightSlope * minor;
    if (minor <= -100.0) return kInfinity;
    // (1 + e1)(1 + e2) = 1 + FLC0, strains as fractions.
    return ((1.0 + flc0_ / 100.0) / (1.0 + minor / 100.0) - 1.0) * 100.0;
  }
  // Piecewise linear; outside the measured range along the end segments.
  std::size_t i = 1;
  while (i + 1 < points_.size() && minor > points_[i].minor) ++i;
  const FldPoint& a = points_[i - 1];
  const FldPoint& b = points_[i];
  return a.major + (minor - a.minor) * (b.major - a.major) / (b.minor - a.minor);
}

double FormingLimitCurve::crossingDistance(double du, double dv) const {
  // f(s) = the path's major true strain - the limit's at the same minor strain; negative at the
  // origin, where the limit is FLC0 > 0.
  const auto f = [&](double s) {
    const double limit = majorAt(engineeringPercent(s * du));
    if (!(limit > -100.0)) return std::numeric_limits<double>::infinity();  // a limit below -100%: passed already
    return s * dv - trueStrain(limit);
  };
  double lo = 0;
  for (double s = kPathStep; s <= kPathReach; s += kPathStep) {
    const double value = f(s);
    if (std::isnan(value) || value == -kInfinity) return kInfinity;  // past the end of the left branch
    if (value >= 0) {
      double hi = s;
      for (int it = 0; it < 50; ++it) {
        const double mid = 0.5 * (lo + hi);
        (f(mid) >= 0 ? hi : lo) = mid;
      }
      return hi;
    }
    lo = s;
  }
  return kInfinity;
}

double FormingLimitCurve::marginAlongPath(double minor, double major) const {
  const double eps2 = trueStrain(minor), eps1 = trueStrain(major);
  const double r = std::hypot(eps1, eps2);
  // The undeformed sheet has no path yet; measure it along plane strain, the path of the least limit.
  const double du = r < 1e-12 ? 0.0 : eps2 / r, dv = r < 1e-12 ? 1.0 : eps1 / r;
  const double s = crossingDistance(du, dv);
  if (!std::isfinite(s)) return kInfinity;
  const FldPoint at = alongPath(s, du, dv);
  const double distance = std::hypot(at.minor - minor, at.major - major);
  return s >= r ? distance : -distance;
}

std::vector<FldPoint> FormingLimitCurve::sample(double minor_from, double minor_to, int samples) const {
  std::vector<FldPoint> out;
  samples = std::max(samples, 2);
  out.reserve(static_cast<std::size_t>(samples));
  for (int i = 0; i < samples; ++i) {
    const double minor = minor_from + (minor_to - minor_from) * i / (samples - 1);
    out.push_back({minor, majorAt(minor)});
  }
  return out;
}

std::vector<FldPoint> FormingLimitCurve::marginCurve(double margin, double minor_from, double minor_to,
                                                     int samples) const {
  std::vector<FldPoint> out;
  for (const FldPoint& p : sample(minor_from, minor_to, samples)) {
    if (!(p.major > -100.0) || !std::isfinite(p.major)) continue;
    const double eps2 = trueStrain(p.minor), eps1 = trueStrain(p.major);
    const double r = std::hypot(eps1, eps2);
    if (r < 1e-12) continue;
    // Back along the path from the curve point: the distance to it grows monotonically, so bisect
    // for the point `margin` away; none when the whole path from the origin is closer.
    const double du = eps2 / r, dv = eps1 / r;
    const auto distance = [&](double s) {
      const FldPoint q = alongPath(s, du, dv);
      return std::hypot(q.minor - p.minor, q.major - p.major);
    };
    if (distance(0) < margin) continue;
    double lo = 0, hi = r;  // distance(lo) >= margin > distance(hi) = 0
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      (distance(mid) >= margin ? lo : hi) = mid;
    }
    out.push_back(alongPath(lo, du, dv));
  }
  return out;
}

std::string FormingLimitCurve::describe() const {
  char text[160];
  if (points_.empty())
    std::snprintf(text, sizeof text, "Keeler-Brazier, FLC0 %.1f%%", flc0_);
  else
    std::snprintf(text, sizeof text, "measured, %zu points, FLC0 %.1f%%", points_.size(), flc0_);
  return text;
}

}  // namespace stampscan::report
