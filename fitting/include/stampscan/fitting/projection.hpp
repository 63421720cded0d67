// The WLS implicit surface and its projection operator (paper Sec. 3.2): the surface is the zero set
// of f(P*) = n(P*).(a(P*) - P*) (Eq. (1)), and a point is carried onto it by Ahn's iteration: fit
// locally around the current estimate P*, project onto the fit, repeat until the step is below a
// tolerance. The paper sees 3-4 iterations.
//
// Weights come from one of three kernels:
//  - Euclidean (Eqs. (3)-(5)): w = K(|P* - P_i|, h), recomputed as P* moves;
//  - data-to-data (Eqs. (10)-(11)): w = exp(-|P_i - P_j|^2 / h^2) with P_j the data point being
//    projected, fixed during the iteration;
//  - graph distance (Sec. 3.3): w = K(graph distance from P_j to P_i in the r-SIG, h).
// Beyond the paper: the local model may be an algebraic sphere instead of a plane (no shrinkage at
// peaks), and a robust reweighting (Tukey's biweight on the residuals) ignores outliers.
//
// Thread safety: projection is const and safe from many threads at once.
#pragma once

#include "stampscan/fitting/bandwidth.hpp"
#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/kernels.hpp"
#include "stampscan/fitting/normals.hpp"
#include "stampscan/fitting/scalar_field.hpp"
#include "stampscan/fitting/sig_graph.hpp"

#include <optional>
#include <vector>

namespace stampscan::fitting {

enum class WeightScheme { Euclidean, DataToData, GraphDistance };
enum class SurfaceModel { Plane, Sphere };

struct ProjectionParams {
  SurfaceModel model = SurfaceModel::Sphere;
  KernelType kernel = KernelType::Gaussian;
  WeightScheme weights = WeightScheme::Euclidean;
  bool robust = true;
  int max_iterations = 20;
  double tolerance = 1e-6;  // the iteration stops when a step is shorter than tolerance * h
  ScalarFieldType scalar = ScalarFieldType::Smooth;
};

struct Projection {
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();
  double scalar = 0;        // NaN when there is no scalar data nearby
  double bandwidth = 0;     // h used
  int iterations = 0;
  bool converged = false;
  bool valid = false;       // false when no neighbour carried weight (the point is left where it was)
  std::size_t neighbors = 0;
};

// What every fitted surface offers: projection of its own data points and of any point in space.
class ImplicitSurface {
 public:
  virtual ~ImplicitSurface() = default;
  // Projects data point i of the cloud the surface was fitted to.
  virtual Projection projectPoint(std::size_t i) const = 0;
  // Projects any point x onto the surface.
  virtual Projection project(const Vec3& x) const = 0;
  // The data's scale around x: the bandwidth the surface uses there, or where the default method
  // widened its fits, the narrower bandwidth the data's spacing called for (meshing and gap
  // detection go by it).
  virtual double bandwidthAt(const Vec3& x) const = 0;
  // Whether projections carry a scalar (strain).
  virtual bool hasScalar() const = 0;
  // Signed distance from x to the surface along its normal (NaN where nothing is fitted), and
  // the projection it came from.
  double signedDistance(const Vec3& x, Projection* projection = nullptr) const;
};

// The data a surface is defined by; all referenced vectors must outlive the WlsSurface.
struct SurfaceData {
  const std::vector<Vec3>* points = nullptr;
  const KdTree* tree = nullptr;
  const BandwidthField* bandwidths = nullptr;       // h at each data point (already smoothed)
  const std::vector<Vec3f>* normals = nullptr;      // oriented; give the fitted normals their sign
  const SigGraph* graph = nullptr;                  // required by WeightScheme::GraphDistance
  const std::vector<double>* scalar = nullptr;      // optional strain per point
};

class WlsSurface : public ImplicitSurface {
 public:
  WlsSurface(const SurfaceData& data, const ProjectionParams& params);

  // Projects data point i (its own bandwidth; the anchor of data-to-data and graph kernels).
  Projection projectPoint(std::size_t i) const override;
  // Projects any point x, with h(x) interpolated from nearby points (Eqs. (9), (13)) and the nearest
  // data point as anchor.
  Projection project(const Vec3& x) const override;
  double bandwidthAt(const Vec3& x) const override;
  bool hasScalar() const override { return data_.scalar != nullptr; }

  const ProjectionParams& params() const { return params_; }
  const SurfaceData& data() const { return data_; }

 private:
  Projection run(const Vec3& start, std::uint32_t anchor, double h) const;
  SurfaceData data_;
  ProjectionParams params_;
};

}  // namespace stampscan::fitting
