// Fitting a whole cloud: choose the bandwidths, estimate and orient normals, and project every input
// point onto the WLS surface, carrying its strain. One output point per input point, same order.
#pragma once

#include "stampscan/fitting/anchored_surface.hpp"
#include "stampscan/fitting/bandwidth.hpp"
#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/normals.hpp"
#include "stampscan/fitting/projection.hpp"
#include "stampscan/fitting/sig_graph.hpp"

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>

namespace stampscan::fitting {

enum class FitMethod {
  // Default, no tuning: bandwidth chosen from the data, robust quadric patches fitted at adaptive
  // anchors and blended into one surface (see anchored_surface.hpp).
  Auto,
  // The same local model (robust algebraic sphere, Euclidean Gaussian kernel) fitted afresh at every
  // point with Ahn's iteration, with a density-robust per-point bandwidth. Slower; a reference.
  Apss,
  Euclidean,  // paper Sec. 3.2: plane fit, Gaussian or cubic kernel, fixed h or automatic
  Sig,        // paper Sec. 3.3: r-SIG graph-distance kernel, automatic bandwidth of Eq. (9)
  Gaussian,   // paper Sec. 4: data-to-data Gaussian kernel, automatic bandwidth of Eqs. (12)-(14)
};
FitMethod parseFitMethod(const std::string& name);  // auto | apss | euclidean | sig | gaussian
std::string toString(FitMethod method);

struct FitParams {
  FitMethod method = FitMethod::Auto;
  std::optional<double> bandwidth;  // fixed h in mm; unset means automatic
  KernelType kernel = KernelType::Gaussian;  // Euclidean and Sig methods
  SigParams sig;                             // Sig method
  RobustScaleParams scale;                   // automatic bandwidth of Apss and Euclidean
  AnchoredParams anchored;                   // Auto
  std::optional<SurfaceModel> model;         // default: Sphere for Apss, Plane for the paper's methods
  std::optional<bool> robust;                // default: on for Auto and Apss, off for the paper's methods
  ScalarFieldType scalar = ScalarFieldType::Smooth;
  OrientationParams orientation;
  int max_iterations = 20;
  double tolerance = 1e-6;
  // Called from worker threads (must be thread-safe) with a stage name and its completed fraction.
  std::function<void(const std::string& stage, double fraction)> progress;
};

struct FitStats {
  std::size_t points = 0;
  BandwidthSummary bandwidth;       // the smoothing bandwidth of the fits
  BandwidthSummary data_bandwidth;  // the data's own scale (the same, except where auto widened it):
                                    // what meshing and gap detection go by
  bool widened = false;             // auto: the bandwidth was widened (anchored_surface.hpp)
  double mean_iterations = 0;
  int max_iterations = 0;
  std::size_t not_converged = 0;
  std::size_t invalid = 0;  // points no neighbour could be fitted around (left in place)
  std::size_t orientation_components = 0;
  std::size_t anchors = 0, probes = 0;  // Auto
  std::size_t sig_edges = 0, sig_pruned = 0;
  std::map<std::string, double> stage_seconds;
  double seconds = 0;
};

// Everything the projection needs, prepared once: kd-tree, bandwidths, oriented normals, and the
// r-SIG for the graph kernel. Borrows the input cloud, which must outlive it.
class FittedSurface {
 public:
  FittedSurface(const Cloud& input, const FitParams& params);
  ~FittedSurface();
  FittedSurface(const FittedSurface&) = delete;
  FittedSurface& operator=(const FittedSurface&) = delete;

  // Projects every input point (in parallel; the result does not depend on the thread count).
  Cloud projectAll(FitStats* stats = nullptr) const;
  const ImplicitSurface& surface() const { return *surface_; }
  const KdTree& tree() const { return *tree_; }
  const Cloud& input() const { return input_; }
  const FitStats& preparationStats() const { return prep_stats_; }

 private:
  const Cloud& input_;
  FitParams params_;
  std::unique_ptr<KdTree> tree_;
  std::unique_ptr<BandwidthField> bandwidths_;  // h at each point, and h(x) between them
  PointNormals normals_;
  std::unique_ptr<SigGraph> graph_;
  std::unique_ptr<ImplicitSurface> surface_;
  FitStats prep_stats_;
};

struct FitResult {
  Cloud surface;
  FitStats stats;
};

// Convenience: prepare and project in one call. Throws std::invalid_argument on an empty cloud or
// bad parameters.
FitResult fitSurface(const Cloud& input, const FitParams& params = {});

}  // namespace stampscan::fitting
