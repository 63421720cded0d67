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
  double seconds = 0;
};

// `shape`: the dense points (positions; normals are not needed, strain must be absent). `carriers`:
// points with strain, one per grid element: several measurements of one element, a few micrometres
// apart, are to be merged first (registration's element_merge.hpp), or their distance would be
// taken for the grid's spacing and the field would reach almost nowhere. A kStrainUncertainty
// scalar, when present, weights each carrier by its inverse variance; further scalars are not carried. Both are borrowed for the call. Throws
// std::invalid_argument when either is empty, the shape has strain, the carriers have none, or the
// spacing is not positive.
ShapeAndStrain fitShapeAndStrain(const Cloud& shape, const Cloud& carriers, const ShapeAndStrainParams& params = {});

}  // namespace stampscan::fitting
