#include "stampscan/fitting/scalar_field.hpp"

#include "stampscan/fitting/kernels.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace stampscan::fitting {

ScalarFieldType parseScalarFieldType(const std::string& name) {
  if (name == "smooth") return ScalarFieldType::Smooth;
  if (name == "shepard") return ScalarFieldType::Shepard;
  throw std::invalid_argument("unknown scalar field '" + name + "' (expected smooth or shepard)");
}

std::string toString(ScalarFieldType type) { return type == ScalarFieldType::Smooth ? "smooth" : "shepard"; }

double shepardScalar(const Vec3& x, const std::vector<ScalarSample>& samples, double R) {
  double sum_w = 0, sum_wc = 0;
  for (const ScalarSample& s : samples) {
    const double r = (s.position - x).norm();
    if (r == 0.0) return s.value;  // Eq. (16) is infinite at r = 0: Shepard's interpolant passes through c_i
    const double w = scalarShepardWeight(r, R);  // Eq. (16)
    sum_w += w;
    sum_wc += w * s.value;
  }
  return sum_w > 0 ? sum_wc / sum_w : std::numeric_limits<double>::quiet_NaN();  // Eq. (15)
}

double smoothScalar(const Vec3& x, const Vec3& n, const std::vector<ScalarSample>& samples) {
  // Tangent basis (t1, t2) of the plane through x.
  const Vec3 helper = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 t1 = n.cross(helper).normalized();
  const Vec3 t2 = n.cross(t1);
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double sum_w = 0, sum_wc = 0, scale_sq = 0;
  for (const ScalarSample& s : samples) {
    if (!(s.weight > 0)) continue;
    const Vec3 d = s.position - x;
    const Eigen::Vector3d row(1.0, d.dot(t1), d.dot(t2));
    A.noalias() += s.weight * row * row.transpose();
    b += s.weight * s.value * row;
    sum_w += s.weight;
    sum_wc += s.weight * s.value;
    scale_sq += s.weight * d.squaredNorm();
  }
  if (!(sum_w > 0)) return std::numeric_limits<double>::quiet_NaN();
  const double mean = sum_wc / sum_w;
  // The linear terms need spread in both tangent directions; judge it relative to the spread.
  const double spread = scale_sq / sum_w;
  if (spread > 0) {
    Eigen::Matrix3d An = A / sum_w;
    const double det = An.determinant();
    if (det > 1e-6 * spread * spread) {
      const Eigen::Vector3d c = An.ldlt().solve(b / sum_w);
      if (c.allFinite()) return c(0);
    }
  }
  return mean;
}

}  // namespace stampscan::fitting
