// The part's surface from dense shape points (a laser's returns) with the strain of sparse carriers
// (the grid elements) on it.
//
// The paper fits one 4D cloud, a position and a scalar attribute per point (Sec. 5: the scalar is
// carried by the projection, Eqs. (15)-(16) or the smooth field). A scanned part gives the two at
// very different densities: the laser's returns, some hundreds per square millimetre, carry the
// shape only; the grid elements, one per 2.54 mm, carry the strain. One fit over both would either
// smooth the shape at the elements' spacing or look for strain at the laser's. So each is fitted at
// its own density: the shape from the dense points with the default method (anchored_surface.hpp),
// the strain as the smooth scalar field over the elements with a bandwidth chosen for the strain
// (shape_and_strain.cpp says how); every output point and mesh vertex lies on the shape and reads
// the strain field there.
//
// The output is the shape surface sampled once per cell of `output_spacing_mm`, not once per input
// point: a session's 30 million returns would make a cloud no viewer needs, while the fit still
// uses every return.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/mesh.hpp"
#include "stampscan/fitting/surface_fit.hpp"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace stampscan::fitting {

struct ShapeAndStrainParams {
  FitParams shape;   // the dense points' fit (its progress callback also reports the other stages)
  double output_spacing_mm = 0.5;  // one output point per cube of this size that holds shape points
  bool with_mesh = true;           // mesh cells are output_spacing_mm wide
  // Strain is read only within this many carrier spacings of a carrier (the spacing: the median
  // distance from a carrier to its fourth nearest, a square grid's pitch whether or not elements were
  // found twice): a missing element or two is bridged; beyond, the surface has no strain (NaN)
  // rather than an extrapolation.
  double strain_reach = 2.0;
};

struct ShapeAndStrain {
  Cloud surface;  // points on the shape with normals and strain
  Mesh mesh;      // empty unless asked for
  // The surface's strain at each carrier (at its foot on the shape), in the carriers' order: what
  // the map shows where an element was measured, to compare with the element's own value. NaN
  // where the surface does not reach the carrier (its foot more than a tenth of a spacing away).
  std::vector<double> strain_at_carriers;
  FitStats shape_stats;
  BandwidthSummary strain_bandwidth;  // the strain field's, chosen at the carriers by cross-validation
  double carrier_spacing = 0;         // mm: the grid's pitch, as strain_reach says
  MeshStats mesh_stats;
  std::size_t shape_points = 0, carriers = 0;
  std::size_t without_strain = 0;  // output points beyond the carriers' reach
  std::size_t not_converged = 0;   // output points whose projection on the shape did not settle
  double seconds = 0;  // the shape's fit and the strain's
};

// One part of the shape points fitted on its own: a sweep's laser returns, fitted while the next
// sweep is scanned. A ShapeSurface joins the pieces where they overlap (joined_surface.hpp says
// how). Owns its points. Throws std::invalid_argument when they are empty or more than four billion.
class ShapePiece {
 public:
  ShapePiece(std::vector<Vec3> points, const FitParams& params = {});
  ~ShapePiece();
  ShapePiece(const ShapePiece&) = delete;
  ShapePiece& operator=(const ShapePiece&) = delete;

  std::size_t points() const { return points_.size(); }
  const FitStats& stats() const { return fit_->preparationStats(); }
  double seconds() const { return seconds_; }

 private:
  friend class ShapeSurface;
  Cloud points_;
  std::unique_ptr<FittedSurface> fit_;
  double seconds_ = 0;
};

// The shape fitted alone, before the carriers are known: the dense points' surface, sampled once per
// output cell, and its mesh, without strain. A scan fits each sweep as a piece as soon as it is
// measured and joins them after its last part sweep, while the stereo views are still being
// measured; the strain follows with them (strainOnShape).
class ShapeSurface {
 public:
  // All the points as one piece. Throws std::invalid_argument as ShapePiece does, and when the
  // output spacing is not positive.
  ShapeSurface(std::vector<Vec3> points, const ShapeAndStrainParams& params = {});
  // Pieces fitted apart (a scan's sweeps), joined. Their FitParams are their own; the progress
  // callback of `params.shape` reports the joining. Throws std::invalid_argument when there are no
  // pieces or the output spacing is not positive.
  ShapeSurface(std::vector<std::unique_ptr<ShapePiece>> pieces, const ShapeAndStrainParams& params = {});
  ~ShapeSurface();
  ShapeSurface(const ShapeSurface&) = delete;
  ShapeSurface& operator=(const ShapeSurface&) = delete;

  // The implicit surface the output points lie on (the progress callback of the parameters is not
  // called after construction). With several pieces it projects by position only.
  const ImplicitSurface& implicitSurface() const { return *surface_; }
  std::size_t points() const { return points_; }
  std::size_t pieces() const { return pieces_.size(); }
  // The output points (positions and normals; the strain stays to strainOnShape).
  const Cloud& surface() const { return surface_points_; }
  const Mesh& mesh() const { return mesh_; }  // empty unless ShapeAndStrainParams::with_mesh
  const MeshStats& meshStats() const { return mesh_stats_; }
  const FitStats& stats() const { return stats_; }
  std::size_t notConverged() const { return not_converged_; }
  // The pieces' fits and the joining; with pieces fitted while scanning, only the joining came after.
  double seconds() const { return seconds_; }
  double joinSeconds() const { return join_seconds_; }

 private:
  void join(const ShapeAndStrainParams& params);

  std::vector<std::unique_ptr<ShapePiece>> pieces_;
  const ImplicitSurface* surface_ = nullptr;  // the one piece's, or the joined surface (data_)
  std::unique_ptr<DataLocator> data_;         // where the data are, for the mesh
  std::size_t points_ = 0;
  Cloud surface_points_;
  Mesh mesh_;
  MeshStats mesh_stats_;
  FitStats stats_;
  std::size_t not_converged_ = 0;
  double seconds_ = 0, join_seconds_ = 0;
};

// The carriers' strain on a fitted shape: the strain field (shape_and_strain.cpp says how) read at
// the shape's output points, its mesh vertices and the carriers' feet. `carriers`: points with
// strain, one per grid element: several measurements of one element, a few micrometres apart, are to
// be merged first (registration's element_merge.hpp), or their distance would be taken for the
// grid's spacing and the field would reach almost nowhere. A kStrainUncertainty scalar, when
// present, weights each carrier by its inverse variance; further scalars are not carried. Throws
// std::invalid_argument when the carriers are empty or have no strain.
ShapeAndStrain strainOnShape(const ShapeSurface& shape, const Cloud& carriers, const ShapeAndStrainParams& params = {});

// Both at once. `shape`: the dense points (positions; normals are not needed, strain must be absent).
// Both are borrowed for the call. Throws std::invalid_argument as the two above do, and when the
// shape has strain.
ShapeAndStrain fitShapeAndStrain(const Cloud& shape, const Cloud& carriers, const ShapeAndStrainParams& params = {});

}  // namespace stampscan::fitting
