// The data's moments accumulated once over a pyramid of cubic cells (a private part of fitting/).
//
// A WLS fit over a wide support would visit every point under it: its cost grows with the square of
// the bandwidth, and with the density. Here each cell keeps the weighted count, centroid and
// covariance of its points (and their mean strain); each level's cells are twice the size of the
// level below. A fit at bandwidth h reads the level whose cells are about h / kCellsPerBandwidth
// wide, so it visits a bounded number of cells (some tens) whatever h and the density, while
// every point still contributes through its cell's moments: the variance reduction of the wide
// support is kept, not subsampled away.
//
// What a cell loses is only how its points spread inside it, and the covariance brings that back
// to second order: for a quadric height field f, the mean of f over a cell's points is
// f(mean) + (the quadratic terms applied to the in-plane covariance), exactly. So a cell enters a
// quadric fit as one row with the covariance-corrected design (QuadricPatch::Sums::addCell), and a
// plane fit as its centroid plus its covariance (WeightedSums::addCell); neither is biased by the
// curvature inside the cell.
#pragma once

#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/quadric_patch.hpp"
#include "stampscan/fitting/scalar_field.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

namespace stampscan::fitting::detail {

// Cells per bandwidth at the level a strain fit reads: a linear field needs far fewer elements than
// a cubic patch, and the strain is measured per grid element anyway.
inline constexpr double kStrainCellsPerBandwidth = 1.0;
// Cells per bandwidth at the level a fit reads: with 2, a Gaussian of width h spans ~9 cells across
// its support of 2.2 h each way (about 60 cells on a surface). The weight is taken at each cell's
// centroid, which smooths the kernel a little but, being symmetric, biases nothing; 2, 2.5 and 3
// cells per h gave the same accuracy on the benchmark's shapes.
inline constexpr double kCellsPerBandwidth = 2.0;

// Single precision beside a double centroid: the covariance of a cell a fraction of a millimetre
// wide needs no more, and the pyramid stays within the memory budget of the fit.
struct CellMoments {
  float weight = 0;     // sum of the points' weights
  float weight_sq = 0;  // sum of their squares: the cell mean's variance is sigma^2 weight_sq / weight^2
  float strain = std::numeric_limits<float>::quiet_NaN();  // weighted mean strain
  float cov[6] = {};    // weighted covariance about the centroid: xx, xy, xz, yy, yz, zz
  Eigen::Matrix3d covariance() const {
    Eigen::Matrix3d c;
    c << cov[0], cov[1], cov[2], cov[1], cov[3], cov[4], cov[2], cov[4], cov[5];
    return c;
  }
};

// One element a fit reads: a cell, or below the finest level a single point (no spread).
struct CellElement {
  const Vec3& centroid;
  const CellMoments* moments;  // null for a single point
  double weight, weight_sq, strain;
  Eigen::Matrix3d covariance() const { return moments ? moments->covariance() : Eigen::Matrix3d::Zero(); }
};

class CellPyramid {
 public:
  // `weights`: one per point, in [0, 1]; 0 leaves a point out. `points`, `tree` (over the points)
  // and `strain` (may be null) must outlive the pyramid. Levels are added until the cells are at
  // least `largest_bandwidth` / kCellsPerBandwidth wide. Fits narrower than the finest level
  // serves read the points themselves (level -1).
  CellPyramid(const std::vector<Vec3>& points, const KdTree& tree, std::vector<float> weights,
              const std::vector<double>* strain, double base_cell, double largest_bandwidth);
  ~CellPyramid();
  CellPyramid(const CellPyramid&) = delete;
  CellPyramid& operator=(const CellPyramid&) = delete;

  int levels() const { return static_cast<int>(levels_.size()); }
  double cellSize(int level) const;
  // The level a fit at bandwidth h reads (-1: the points): cells at most h / cells_per_bandwidth.
  int levelFor(double h, double cells_per_bandwidth = kCellsPerBandwidth) const;
  // Elements of `level` whose centroid lies within `radius` of x.
  void near(int level, const Vec3& x, double radius, std::vector<Neighbor>& out) const;
  CellElement element(int level, std::uint32_t index) const;
  const Vec3& centroid(int level, std::uint32_t cell) const;
  const CellMoments& moments(int level, std::uint32_t cell) const;
  std::size_t cells(int level) const;
  std::size_t bytes() const;

 private:
  struct Level;
  const std::vector<Vec3>& points_;
  const KdTree& point_tree_;
  std::vector<float> weights_;
  const std::vector<double>* strain_;
  double base_cell_;
  std::vector<std::unique_ptr<Level>> levels_;
};

// A cubic height patch (quadric_patch.hpp, order 3: the wide patches are read up to a bandwidth
// from their centres) fitted to the cells of the pyramid around `centre` with Gaussian weights of
// bandwidth h (Eq. (3)) times the cells' weights, with what the bandwidth choice needs (the strain
// has a bandwidth of its own: chooseStrainBandwidth).
struct CellFit {
  QuadricPatch surface;
  double offset = 0;           // signed distance from the centre to the patch, mm
  double offset_factor = 0;    // the offset's standard deviation per unit of the points' noise sigma
  Vec3 frame_normal = Vec3::UnitZ();  // the patch's height axis
  double effective_count = 0;  // (sum w)^2 / sum w^2 over the points
};

struct CellFitScratch {
  std::vector<Neighbor> near;
  std::vector<double> weight;
  std::vector<ScalarSample> samples;
  std::vector<double> variance_rows;  // QuadricPatch::Sums' rows for the offset's variance
};

// Nothing when the cells are too few or do not spread in two directions. `frame_normal`, when
// given, fixes the patch's height axis (so the offsets of fits at several bandwidths are measured
// along one direction); otherwise it is the weighted plane's normal (Eqs. (2), (6), (7)).
std::optional<CellFit> fitOnCells(const CellPyramid& pyramid, const Vec3& centre, double h, const Vec3* frame_normal,
                                  CellFitScratch& scratch);

// The smooth strain field (scalar_field.hpp: linear in the tangent plane at x, normal n) over the
// elements within the support of bandwidth h around x, with Gaussian weights times the elements'
// weights. NaN where no element carries strain.
double strainNear(const CellPyramid& pyramid, const Vec3& x, const Vec3& n, double h, CellFitScratch& scratch);

// The strain field's own bandwidth around x by the same balancing rule as chooseBandwidth below:
// linear strain fits at h_j = h_start * step^j; the strain noise is estimated from the residuals
// of the narrowest fit with enough data. Strain changes faster than the shape's curvature where
// the sheet stretches, so its bandwidth is mostly narrower than the shape's. h is 0 where no
// element carries strain.
struct StrainChoice {
  double h = 0;
  double value = std::numeric_limits<double>::quiet_NaN();  // at x
  Vec3 gradient = Vec3::Zero();
};
StrainChoice chooseStrainBandwidth(const CellPyramid& pyramid, const Vec3& x, const Vec3& n, double h_start, double step,
                             int scales, double gamma, CellFitScratch& scratch);

// The bandwidth by Lepski's balancing rule (Lepski, Mammen & Spokoiny 1997), the same idea as the
// intersection of confidence intervals (Katkovnik 1999): fits at h_j = h_start * step^j, each
// giving the offset y_j of the centre from the patch. Their noise falls as h grows and their bias
// (the shape's terms beyond the quadric, ~h^4) rises; the widest fit whose offset agrees with every
// narrower one's, to within gamma standard deviations of their difference, is kept. `limited` is
// true when a wider fit disagreed (the shape, not the cap, limited h).
struct BandwidthChoice {
  std::optional<CellFit> fit;
  double h = 0;
  bool limited = false;
};
BandwidthChoice chooseBandwidth(const CellPyramid& pyramid, const Vec3& centre, double h_start, double step,
                                int scales, double noise_sigma, double gamma, CellFitScratch& scratch);

}  // namespace stampscan::fitting::detail
