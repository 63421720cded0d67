#include "stampscan/registration/icp.hpp"

#include "stampscan/fitting/median.hpp"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampscan::registration {

namespace {

std::vector<Vec3> pcaNormals(const std::vector<Vec3>& points, const fitting::KdTree& tree, int k) {
  std::vector<Vec3> normals(points.size(), Vec3::UnitZ());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 256), [&](const auto& range) {
    std::vector<fitting::Neighbor> nn;
    for (std::size_t i = range.begin(); i < range.end(); ++i) {
      tree.knn(points[i], static_cast<std::size_t>(k), nn);
      Vec3 mean = Vec3::Zero();
      for (const auto& n : nn) mean += points[n.index];
      mean /= static_cast<double>(nn.size());
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      for (const auto& n : nn) cov += (points[n.index] - mean) * (points[n.index] - mean).transpose();
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
      normals[i] = eig.eigenvectors().col(0);
    }
  });
  return normals;
}

struct Pair {
  Vec3 p;       // transformed source point
  Vec3 n;       // target normal
  double r = 0; // signed point-to-plane residual n . (p - q)
  Vec3 along = Vec3::Zero();  // the offset p - q along the target's surface
};


}  // namespace

PointToPlaneIcp::PointToPlaneIcp(const std::vector<Vec3>& target, std::vector<Vec3> normals)
    : target_(target), normals_(std::move(normals)) {
  if (target.size() < 6) throw std::invalid_argument("ICP: the target needs at least 6 points");
  if (!normals_.empty() && normals_.size() != target.size())
    throw std::invalid_argument("ICP: target normals do not match the target points");
  tree_ = std::make_unique<fitting::KdTree>(target_);
  if (normals_.empty()) normals_ = pcaNormals(target_, *tree_, 12);
  diagonal_ = fitting::boundsOf(target_).diagonal();
  // Typical spacing of the target: the median distance to the nearest other point, from a sample.
  std::vector<double> gaps;
  std::vector<fitting::Neighbor> nn;
  const std::size_t stride = std::max<std::size_t>(1, target_.size() / 2000);
  for (std::size_t i = 0; i < target_.size(); i += stride) {
    tree_->knn(target_[i], 2, nn);
    if (nn.size() == 2) gaps.push_back(std::sqrt(nn[1].distance_sq));
  }
  spacing_ = fitting::medianOr(gaps, 0.0);
}

PointToPlaneIcp::~PointToPlaneIcp() = default;

IcpResult PointToPlaneIcp::align(const std::vector<Vec3>& source, const Eigen::Isometry3d& initial,
                                 const IcpParams& params) const {
  IcpResult result;
  result.transform = initial;
  if (source.empty()) return result;
  const double max_distance = params.max_correspondence_distance > 0 ? params.max_correspondence_distance : 0.05 * diagonal_;
  std::vector<Pair> pairs(source.size());
  std::vector<char> valid(source.size());
  for (int it = 0; it < params.max_iterations; ++it) {
    result.iterations = it + 1;
    // Pairs: nearest target point within the distance.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, source.size(), 512), [&](const auto& range) {
      std::vector<fitting::Neighbor> nn;
      for (std::size_t i = range.begin(); i < range.end(); ++i) {
        const Vec3 p = result.transform * source[i];
        tree_->knn(p, 1, nn);
        valid[i] = !nn.empty() && nn[0].distance_sq <= max_distance * max_distance;
        if (!valid[i]) continue;
        const Vec3& n = normals_[nn[0].index];
        const Vec3 offset = p - target_[nn[0].index];
        const double r = n.dot(offset);
        // On a densely sampled surface the nearest point lies almost straight below p: an offset
        // along the surface of more than a few spacings means q is on the target's edge and p is
        // beyond it, in a part the target did not see. Such pairs pull the source sideways.
        if (params.reject_boundary && (offset - r * n).norm() > params.boundary_spacings * spacing_) {
          valid[i] = 0;
          continue;
        }
        pairs[i] = {p, n, r, offset - r * n};
      }
    });
    std::vector<double> abs_residuals;
    abs_residuals.reserve(source.size());
    for (std::size_t i = 0; i < source.size(); ++i)
      if (valid[i]) abs_residuals.push_back(std::abs(pairs[i].r));
    if (abs_residuals.size() < 6) break;
    // Robust scale: 1.4826 * median |r| estimates sigma for Gaussian residuals.
    const double scale = std::max(1.4826 * fitting::medianOr(abs_residuals, 0.0), 1e-12 * diagonal_);
    const double cutoff = params.tukey_constant * scale;
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    double sum_sq = 0, weight_sum = 0;
    std::size_t count = 0;
    for (std::size_t i = 0; i < source.size(); ++i) {
      if (!valid[i]) continue;
      const Pair& q = pairs[i];
      double w = 1;
      if (params.robust) {
        if (std::abs(q.r) >= cutoff) continue;
        const double u = q.r / cutoff;
        w = (1 - u * u) * (1 - u * u);
      }
      // r(delta) ~ r + (p x n) . omega + n . t
      Eigen::Matrix<double, 6, 1> J;
      J.head<3>() = q.p.cross(q.n);
      J.tail<3>() = q.n;
      A.noalias() += w * J * J.transpose();
      b.noalias() -= w * q.r * J;
      if (params.tangential_weight > 0) {
        // The offset along the surface as two more residuals, e . (p - q) for the tangent axes e.
        const Eigen::Matrix3d frame = fitting::frameAround(q.n);
        for (int k = 0; k < 2; ++k) {
          const Vec3 e = frame.col(k);
          J.head<3>() = q.p.cross(e);
          J.tail<3>() = e;
          const double wt = w * params.tangential_weight;
          A.noalias() += wt * J * J.transpose();
          b.noalias() -= wt * e.dot(q.along) * J;
        }
      }
      sum_sq += w * q.r * q.r;
      weight_sum += w;
      ++count;
    }
    result.pairs = count;
    result.fitness = static_cast<double>(abs_residuals.size()) / static_cast<double>(source.size());
    result.rmse = weight_sum > 0 ? std::sqrt(sum_sq / weight_sum) : 0;
    if (count < 6) break;
    const Eigen::Matrix<double, 6, 1> delta = A.ldlt().solve(b);
    const Vec3 omega = delta.head<3>();
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    if (omega.norm() > 0) step.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
    step.translation() = delta.tail<3>();
    result.transform = step * result.transform;
    if (omega.norm() < params.rotation_tolerance && delta.tail<3>().norm() < params.translation_tolerance * diagonal_) {
      result.converged = true;
      break;
    }
  }
  return result;
}

}  // namespace stampscan::registration
