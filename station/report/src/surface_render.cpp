#include "stampscan/report/surface_render.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace stampscan::report {

namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kFar = -std::numeric_limits<float>::infinity();

// Brightness from the angle between the surface and the line of sight: a light at the eye. A face
// seen square-on keeps its colour exactly, so a value can be read back from its colour.
float headLight(double cos_angle) { return static_cast<float>(0.45 + 0.55 * std::min(1.0, std::abs(cos_angle))); }

RenderedView emptyRendering(const ViewProjection& projection) {
  RenderedView r;
  r.width = projection.width();
  r.height = projection.height();
  const std::size_t n = static_cast<std::size_t>(r.width) * static_cast<std::size_t>(r.height);
  r.depth.assign(n, kFar);
  r.value.assign(n, kNaN);
  r.shade.assign(n, 0.0f);
  r.covered.assign(n, 0);
  return r;
}
}  // namespace

std::vector<View> standardViews() {
  using fitting::Vec3;
  return {{"top", Vec3::UnitZ(), Vec3::UnitY()},
          {"front", -Vec3::UnitY(), Vec3::UnitZ()},
          {"side", Vec3::UnitX(), Vec3::UnitZ()},
          {"oblique", Vec3(0.55, -0.65, 0.75).normalized(), Vec3::UnitZ()}};
}

ViewProjection::ViewProjection(const View& view, const std::vector<fitting::Vec3>& points, int width, int height,
                               int margin_px)
    : width_(width), height_(height) {
  toward_ = view.toward_viewer.normalized();
  right_ = view.up.cross(toward_).normalized();
  up_ = toward_.cross(right_);
  double min_u = 0, max_u = 0, min_v = 0, max_v = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double u = points[i].dot(right_), v = points[i].dot(up_);
    min_u = i ? std::min(min_u, u) : u;
    max_u = i ? std::max(max_u, u) : u;
    min_v = i ? std::min(min_v, v) : v;
    max_v = i ? std::max(max_v, v) : v;
  }
  const double usable_w = std::max(1, width - 2 * margin_px), usable_h = std::max(1, height - 2 * margin_px);
  scale_ = std::min(usable_w / std::max(max_u - min_u, 1e-6), usable_h / std::max(max_v - min_v, 1e-6));
  centre_ = right_ * 0.5 * (min_u + max_u) + up_ * 0.5 * (min_v + max_v);
}

Eigen::Vector3d ViewProjection::toPixel(const fitting::Vec3& p) const {
  const fitting::Vec3 d = p - centre_;
  return {0.5 * width_ + d.dot(right_) * scale_, 0.5 * height_ - d.dot(up_) * scale_, p.dot(toward_)};
}

RenderedView renderMesh(const fitting::Mesh& mesh, const std::vector<double>& vertex_values,
                        const ViewProjection& projection) {
  RenderedView r = emptyRendering(projection);
  const fitting::Cloud& v = mesh.vertices;
  std::vector<Eigen::Vector3d> screen(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) screen[i] = projection.toPixel(v.positions[i]);
  const fitting::Vec3& toward = projection.towardViewer();

  for (const fitting::Triangle& t : mesh.triangles) {
    const Eigen::Vector3d& a = screen[t.v[0]];
    const Eigen::Vector3d& b = screen[t.v[1]];
    const Eigen::Vector3d& c = screen[t.v[2]];
    const double area = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    if (std::abs(area) < 1e-12) continue;  // seen edge-on
    const fitting::Vec3 face =
        (v.positions[t.v[1]] - v.positions[t.v[0]]).cross(v.positions[t.v[2]] - v.positions[t.v[0]]).normalized();
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
    const int x1 = std::min(r.width - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
    const int y1 = std::min(r.height - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
    const double va = vertex_values[t.v[0]], vb = vertex_values[t.v[1]], vc = vertex_values[t.v[2]];
    for (int y = y0; y <= y1; ++y) {
      const double py = y + 0.5;
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5;
        // Barycentric weights of the pixel centre; a pixel on a shared edge belongs to both triangles
        // (the z-test picks one), so no gap opens between them.
        const double wa = ((b.x() - px) * (c.y() - py) - (c.x() - px) * (b.y() - py)) / area;
        const double wb = ((c.x() - px) * (a.y() - py) - (a.x() - px) * (c.y() - py)) / area;
        const double wc = 1.0 - wa - wb;
        if (wa < -1e-9 || wb < -1e-9 || wc < -1e-9) continue;
        const double depth = wa * a.z() + wb * b.z() + wc * c.z();
        const std::size_t i = r.at(x, y);
        if (depth <= r.depth[i]) continue;
        r.depth[i] = static_cast<float>(depth);
        r.value[i] = static_cast<float>(wa * va + wb * vb + wc * vc);
        fitting::Vec3 normal = face;
        if (v.hasNormals()) {
          const fitting::Vec3 n = wa * v.normals[t.v[0]] + wb * v.normals[t.v[1]] + wc * v.normals[t.v[2]];
          if (n.squaredNorm() > 1e-12) normal = n.normalized();
        }
        r.shade[i] = headLight(normal.dot(toward));
        r.covered[i] = 1;
      }
    }
  }
  return r;
}

RenderedView renderPoints(const std::vector<fitting::Vec3>& points, const std::vector<double>& values, double radius_mm,
                          const ViewProjection& projection) {
  RenderedView r = emptyRendering(projection);
  const double radius_px = std::max(1.0, radius_mm * projection.pixelsPerMm());
  const int reach = static_cast<int>(std::ceil(radius_px));
  for (std::size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector3d s = projection.toPixel(points[k]);
    const int cx = static_cast<int>(std::floor(s.x())), cy = static_cast<int>(std::floor(s.y()));
    for (int y = std::max(0, cy - reach); y <= std::min(r.height - 1, cy + reach); ++y)
      for (int x = std::max(0, cx - reach); x <= std::min(r.width - 1, cx + reach); ++x) {
        const double dx = x + 0.5 - s.x(), dy = y + 0.5 - s.y();
        if (dx * dx + dy * dy > radius_px * radius_px) continue;
        const std::size_t i = r.at(x, y);
        if (s.z() <= r.depth[i]) continue;
        r.depth[i] = static_cast<float>(s.z());
        r.value[i] = static_cast<float>(values[k]);
        r.shade[i] = 1.0f;
        r.covered[i] = 1;
      }
  }
  return r;
}

bool visible(const RenderedView& rendered, const ViewProjection& projection, const fitting::Vec3& p,
             double tolerance_mm) {
  const Eigen::Vector3d s = projection.toPixel(p);
  const int x = static_cast<int>(std::floor(s.x())), y = static_cast<int>(std::floor(s.y()));
  if (x < 0 || y < 0 || x >= rendered.width || y >= rendered.height) return false;
  // The nearest surface in a small window: the spot may sit just beside a pixel centre.
  float nearest = kFar;
  for (int dy = -2; dy <= 2; ++dy)
    for (int dx = -2; dx <= 2; ++dx) {
      const int xx = x + dx, yy = y + dy;
      if (xx < 0 || yy < 0 || xx >= rendered.width || yy >= rendered.height) continue;
      nearest = std::max(nearest, rendered.depth[rendered.at(xx, yy)]);
    }
  return nearest == kFar || s.z() >= nearest - tolerance_mm;
}

}  // namespace stampscan::report
