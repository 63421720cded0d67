// Surfaces fitted to parts of one cloud, joined into one surface where they overlap.
//
// A scan's sweeps are fitted one by one as they are measured (shape_and_strain.hpp: ShapePiece), so
// that the surface is ready when the last sweep is. Where two sweeps overlap, each piece's fit knows
// only its own returns. The joined surface there is the weighted mean of the pieces' projections,
// each weighted by the square of its data's density at its foot: the density is the inverse
// variance of a local fit's offset (the paper's WLS estimate averages the points it weighs, Eq. (2)),
// and squaring it fades a piece out over its strip's edge, where its fit sees data on one side only
// and is least sure. The density is a smooth (biweight) count over cells a bandwidth wide, so the
// weights, and the joined surface and its normals, vary continuously: no seam where one piece's
// strip ends inside another's.
//
// Each piece orients its normals by the same rule (normals.hpp), and a foot whose normal opposes the
// heaviest one's is turned before it is averaged.
#pragma once

#include "stampscan/fitting/mesh.hpp"
#include "stampscan/fitting/projection.hpp"
#include "stampscan/fitting/surface_fit.hpp"

#include <cstdint>
#include <unordered_map>
#include <unordered_set>
#include <vector>

namespace stampscan::fitting::detail {

// How densely one piece's data cover space, smoothly: the count of its points near x with biweight
// weights over the distance to each cell's centroid (support: one cell).
class PieceDensity {
 public:
  PieceDensity(const std::vector<Vec3>& points, double cell);
  double at(const Vec3& x) const;
  // Whether the piece's data come within about two cells of x (at least one cell, at most four): a
  // cheap test before its surface is asked to project x.
  bool reaches(const Vec3& x) const;

 private:
  bool inBounds(const Vec3& x) const;  // within the points' bounds grown by one cell

  struct CellSums {
    Vec3 sum = Vec3::Zero();
    double count = 0;
  };
  double cell_;
  Vec3 origin_, low_, high_;
  std::unordered_map<std::uint64_t, CellSums> cells_;  // sums, then (after construction) centroid and count
  // Blocks two cells wide holding data, and their neighbours: one lookup says whether x is near data.
  std::unordered_set<std::uint64_t> near_blocks_;
};

struct JoinedPiece {
  const FittedSurface* fit = nullptr;
  PieceDensity density;
};

class JoinedSurface : public ImplicitSurface, public DataLocator {
 public:
  // The pieces' fits are borrowed (their data too).
  explicit JoinedSurface(const std::vector<const FittedSurface*>& fits);

  // Not offered: the joined surface has no single list of data points.
  Projection projectPoint(std::size_t i) const override;
  Projection project(const Vec3& x) const override;
  // The densest piece's at x.
  double bandwidthAt(const Vec3& x) const override;
  bool hasScalar() const override { return false; }

  // DataLocator: over every piece's data.
  std::optional<std::pair<Vec3, double>> nearest(const Vec3& x) const override;
  double spacingAt(const Vec3& data_point) const override;

 private:
  std::vector<JoinedPiece> pieces_;
  std::vector<TreeLocator> data_;
};

}  // namespace stampscan::fitting::detail
