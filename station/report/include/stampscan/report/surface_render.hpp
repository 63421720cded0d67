// A small z-buffer renderer for the strain maps: orthographic views of the fitted mesh (or, without
// a mesh, of the elements as discs), with a scalar per pixel interpolated from the vertices and a
// head-light shade that shows the shape. Colouring is left to the caller, so one rendering serves
// any colour scale and the tests can read the value behind a pixel.
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace stampscan::report {

// An orthographic view direction. `toward_viewer` points from the part to the eye; `up` is the
// world direction that shows upwards (made orthogonal to toward_viewer).
struct View {
  std::string name;  // "top", "front", "side", "oblique": used in file names and captions
  fitting::Vec3 toward_viewer;
  fitting::Vec3 up;
};
// The standard views of a part on the fixture (z up): from above, from the front (-y), from the
// side (+x), and one oblique view from front right above.
std::vector<View> standardViews();

// Places a view's projection of a set of points into a width x height pixel raster, centred, with
// `margin_px` free on each side. Pixel (0, 0) is the top-left corner; pixel centres are at +0.5.
class ViewProjection {
 public:
  ViewProjection(const View& view, const std::vector<fitting::Vec3>& points, int width, int height, int margin_px = 12);
  // Pixel x, y, and depth (larger is nearer the viewer, in mm).
  Eigen::Vector3d toPixel(const fitting::Vec3& p) const;
  double pixelsPerMm() const { return scale_; }
  const fitting::Vec3& towardViewer() const { return toward_; }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  fitting::Vec3 right_, up_, toward_, centre_;
  double scale_ = 1;
  int width_, height_;
};

// What the renderer leaves per pixel. value is NaN and shade 0 where nothing was drawn
// (`covered` false).
struct RenderedView {
  int width = 0, height = 0;
  std::vector<float> depth, value, shade;
  std::vector<std::uint8_t> covered;
  std::size_t at(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
  }
};

// The mesh's triangles; `vertex_values` has one value per mesh vertex (NaN for none).
RenderedView renderMesh(const fitting::Mesh& mesh, const std::vector<double>& vertex_values,
                        const ViewProjection& projection);
// The points as flat discs of `radius_mm` facing the viewer (when there is no mesh).
RenderedView renderPoints(const std::vector<fitting::Vec3>& points, const std::vector<double>& values, double radius_mm,
                          const ViewProjection& projection);

// Whether `p` is visible in the rendering (not hidden behind the surface by more than `tolerance_mm`).
bool visible(const RenderedView& rendered, const ViewProjection& projection, const fitting::Vec3& p,
             double tolerance_mm);

}  // namespace stampscan::report
