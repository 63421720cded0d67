#include "stampscan/sim/scene.hpp"

#include "stampscan/sim/height_field.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace stampscan::sim {

namespace {

std::optional<Hit> hitTable(const Ray& ray, const Table& table) {
  if (ray.direction.z() >= -1e-12) return std::nullopt;
  const double t = (table.z - ray.origin.z()) / ray.direction.z();
  if (t <= 0) return std::nullopt;
  Hit hit;
  hit.t = t;
  hit.point = ray.origin + t * ray.direction;
  hit.normal = Vec3::UnitZ();
  hit.albedo = table.albedo;
  return hit;
}

// Box-filtered coverage of a filled disc of radius r seen at distance d from its centre.
double discCoverage(double d, double r, double f) {
  if (f <= 1e-12) return d <= r ? 1.0 : 0.0;
  return std::clamp((r - d) / f + 0.5, 0.0, 1.0);
}

// A stable hash of a material cell: where the sheet's coating happens to be polished.
bool shinyCell(const Vec2& m) {
  const auto i = static_cast<std::int64_t>(std::floor(m.x() / 9.0));
  const auto j = static_cast<std::int64_t>(std::floor(m.y() / 9.0));
  std::uint64_t h = static_cast<std::uint64_t>(i) * 0x9E3779B97F4A7C15ull ^ static_cast<std::uint64_t>(j) * 0xC2B2AE3D27D4EB4Full;
  h ^= h >> 29;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 32;
  return h % 100 < 4;  // 4 % of 9 mm cells
}

}  // namespace

PartScene::PartScene(const FormedPart& part, const GridSpec& grid, const Eigen::Isometry3d& machine_from_datum, Table table)
    : part_(part), grid_(grid), printed_(printedArea(grid, part.blank())), machine_from_datum_(machine_from_datum),
      datum_from_machine_(machine_from_datum.inverse()), at_origin_(machine_from_datum.isApprox(Eigen::Isometry3d::Identity(), 1e-15)),
      table_(table) {
  // A bound on the slope from a dense sample, with margin: marching by gap / (|dz| + slope |dxy|)
  // can then never step through the surface.
  const BlankRect box = part.footprint();
  double slope = 0;
  for (int i = 0; i <= 400; ++i)
    for (int j = 0; j <= 400; ++j) {
      const double x = box.min.x() + (box.max.x() - box.min.x()) * i / 400.0;
      const double y = box.min.y() + (box.max.y() - box.min.y()) * j / 400.0;
      slope = std::max(slope, heightGradient([&](double u, double v) { return part.height(u, v); }, x, y).norm());
    }
  max_slope_ = 1.3 * slope + 0.1;
  footprint_ = {box.min - Vec2(1, 1), box.max + Vec2(1, 1)};
}

std::optional<Hit> PartScene::cast(const Ray& ray, double footprint_per_mm, double t_hint) const {
  if (at_origin_) {
    if (std::optional<Hit> hit = castOnPart(ray, footprint_per_mm, t_hint)) return hit;
    return hitTable(ray, table_);
  }
  // Distances along the ray are the same in both frames.
  const Ray in_datum{datum_from_machine_ * ray.origin, datum_from_machine_.linear() * ray.direction};
  std::optional<Hit> hit = castOnPart(in_datum, footprint_per_mm, t_hint);
  if (!hit) return hitTable(ray, table_);
  hit->point = machine_from_datum_ * hit->point;
  hit->normal = machine_from_datum_.linear() * hit->normal;
  return hit;
}

std::optional<Hit> PartScene::castOnPart(const Ray& ray, double footprint_per_mm, double t_hint) const {
  const Vec3& o = ray.origin;
  const Vec3& d = ray.direction;
  const auto gap = [&](double t) {
    const Vec3 p = o + t * d;
    return p.z() - part_.height(p.x(), p.y());
  };
  // The search interval: between the slab of heights the part occupies.
  const double z_top = part_.maxHeight() + 0.5, z_bottom = part_.minHeight() - 0.5;
  double t0 = 0, t1 = 0;
  if (std::abs(d.z()) < 1e-12) return std::nullopt;
  t0 = std::max(0.0, (z_top - o.z()) / d.z());
  t1 = (z_bottom - o.z()) / d.z();
  if (t1 < t0) std::swap(t0, t1);
  t0 = std::max(t0, 0.0);
  // And over the part's footprint: a ray beside the part ends here. (It used to march down to the
  // flange's plane to be told it was past the blank: on the dome's views 29 % of the rays and 46 %
  // of the height evaluations, for the same images.)
  for (int axis = 0; axis < 2; ++axis) {
    const double lo = footprint_.min(axis), hi = footprint_.max(axis);
    if (std::abs(d(axis)) < 1e-12) {
      if (o(axis) < lo || o(axis) > hi) return std::nullopt;
      continue;
    }
    double ta = (lo - o(axis)) / d(axis), tb = (hi - o(axis)) / d(axis);
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (!(t0 < t1)) return std::nullopt;
  const double denominator = std::abs(d.z()) + max_slope_ * std::sqrt(d.x() * d.x() + d.y() * d.y());
  double t = t0, g = 0, t_prev = t0, g_prev = 0;
  bool started = false, bracketed = false;
  if (t_hint > 0) {
    // A neighbouring ray's hit is a close start (coherent rays of a row or a profile): this ray's
    // hit is usually within the march's smallest step of it, so a bracket that wide around the hint,
    // above the surface at its near end, holds it after two evaluations (the march took three or
    // four from 0.05 before the hint). The bracket is no wider than a march step, so it skips
    // nothing the march would have found.
    const double near = t_hint - 0.01, far = t_hint + 0.01;
    if (near > t0 && far < t1) {
      if (const double g_near = gap(near); g_near > 0) {
        t_prev = near;
        g_prev = g_near;
        t = far;
        g = gap(far);
        started = true;
        bracketed = g <= 0;
      }
    }
    // Otherwise from a little further back, the start still above the surface.
    for (const double back : {0.05, 0.5}) {
      if (started || !(t_hint - back > t0)) continue;
      if (const double g_back = gap(t_hint - back); g_back > 0) {
        t = t_hint - back;
        g = g_back;
        started = true;
      }
    }
  }
  if (!started) {
    g = gap(t);
    if (g < 0) return std::nullopt;  // starts below the surface: looking from underneath
  }
  // March with steps that cannot cross the surface (the gap shrinks by at most `denominator` per
  // unit step), then bracket and refine by the Illinois variant of regula falsi.
  while (!bracketed && t < t1) {
    t_prev = t;
    g_prev = g;
    t += std::max(g / denominator, 0.02);
    g = gap(t);
    bracketed = g <= 0;
  }
  if (!bracketed) return std::nullopt;
  double a = t_prev, fa = g_prev, b = t, fb = g;
  int side = 0;
  // Regula falsi keeps one end fixed, so the bracket need not shrink: stop on a small gap instead
  // (1e-8 mm of height is far below any noise the sensors add).
  for (int it = 0; it < 60 && b - a > 1e-9; ++it) {
    const double c = (a * fb - b * fa) / (fb - fa);
    const double fc = gap(c);
    if (std::abs(fc) < 1e-8) {
      a = b = c;
      break;
    }
    if (fc > 0) {
      a = c;
      fa = fc;
      if (side == 1) fb *= 0.5;
      side = 1;
    } else {
      b = c;
      fb = fc;
      if (side == -1) fa *= 0.5;
      side = -1;
    }
  }
  const double t_hit = 0.5 * (a + b);
  const Vec3 p = o + t_hit * d;
  const Vec2 m = part_.materialAt(p.x(), p.y());
  if (!part_.blank().contains(m)) return std::nullopt;  // past the blank's edge
  Hit hit;
  hit.t = t_hit;
  hit.point = p;
  hit.normal = part_.normal(p.x(), p.y());
  const double coverage = inkCoverage(grid_, printed_, m, footprint_per_mm * t_hit);
  hit.albedo = kSheetAlbedo + (kInkAlbedo - kSheetAlbedo) * coverage;
  hit.shiny = shinyCell(m);
  return hit;
}

PlateScene::PlateScene(const CirclePlate& plate, const Eigen::Isometry3d& machine_from_plate, Table table)
    : plate_(plate), machine_from_plate_(machine_from_plate), plate_from_machine_(machine_from_plate.inverse()),
      table_(table) {}

std::optional<Hit> PlateScene::cast(const Ray& ray, double footprint_per_mm, double) const {
  const Vec3 o = plate_from_machine_ * ray.origin;
  const Vec3 d = plate_from_machine_.linear() * ray.direction;
  if (d.z() < -1e-12) {
    const double t = -o.z() / d.z();
    const Vec3 p = o + t * d;
    const double x_max = (plate_.columns - 1) * plate_.pitch + plate_.margin;
    const double y_max = (plate_.rows - 1) * plate_.pitch + plate_.margin;
    if (t > 0 && p.x() >= -plate_.margin && p.x() <= x_max && p.y() >= -plate_.margin && p.y() <= y_max) {
      const int i = std::clamp(static_cast<int>(std::lround(p.x() / plate_.pitch)), 0, plate_.columns - 1);
      const int j = std::clamp(static_cast<int>(std::lround(p.y() / plate_.pitch)), 0, plate_.rows - 1);
      const double dist = (p.head<2>() - plate_.dotCentre(i, j).head<2>()).norm();
      const double cover = discCoverage(dist, 0.5 * plate_.dot_diameter, footprint_per_mm * t);
      Hit hit;
      hit.t = t;
      hit.point = ray.origin + t * ray.direction;
      hit.normal = machine_from_plate_.linear() * Vec3::UnitZ();
      hit.albedo = 0.85 + (0.04 - 0.85) * cover;
      return hit;
    }
  }
  return hitTable(ray, table_);
}

SphereScene::SphereScene(const ReferenceSphere& sphere, Table table) : sphere_(sphere), table_(table) {}

std::optional<Hit> SphereScene::cast(const Ray& ray, double, double) const {
  const Vec3 oc = ray.origin - sphere_.centre;
  const double b = oc.dot(ray.direction);
  const double c = oc.squaredNorm() - sphere_.radius * sphere_.radius;
  const double disc = b * b - c;
  if (disc >= 0) {
    const double t = -b - std::sqrt(disc);
    if (t > 0) {
      Hit hit;
      hit.t = t;
      hit.point = ray.origin + t * ray.direction;
      hit.normal = (hit.point - sphere_.centre) / sphere_.radius;
      hit.albedo = sphere_.albedo;
      return hit;
    }
  }
  return hitTable(ray, table_);
}

}  // namespace stampscan::sim
