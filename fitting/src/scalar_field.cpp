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

std::optional<LinearScalar> fitTangentLinear(const Vec3& x, const Vec3& n, const std::vector<ScalarSample>& samples) {
  const Eigen::Matrix3d frame = frameAround(n);
  const Vec3 t1 = frame.col(0), t2 = frame.col(1);
  // One pass: the weighted moments of (1, u, v) about x and of the values. The samples' spread sets
  // the scale of the tangent coordinates afterwards, for conditioning.
  double sum_w = 0, spread_sq = 0;
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const ScalarSample& s : samples) {
    if (!(s.weight > 0)) continue;
    const Vec3 d = s.position - x;
    const double u = d.dot(t1), v = d.dot(t2), w = s.weight;
    sum_w += w;
    spread_sq += w * d.squaredNorm();
    A(0, 1) += w * u;
    A(0, 2) += w * v;
    A(1, 1) += w * u * u;
    A(1, 2) += w * u * v;
    A(2, 2) += w * v * v;
    b(0) += w * s.value;
    b(1) += w * s.value * u;
    b(2) += w * s.value * v;
  }
  if (!(sum_w > 0)) return std::nullopt;
  LinearScalar field{b(0) / sum_w, Vec3::Zero()};
  const double scale = std::sqrt(spread_sq / sum_w);
  if (!(scale > 0)) return field;
  // In scaled coordinates (u, v) / scale, normalised by the total weight.
  A(0, 0) = sum_w;
  A(0, 1) /= scale;
  A(0, 2) /= scale;
  A(1, 1) /= scale * scale;
  A(1, 2) /= scale * scale;
  A(2, 2) /= scale * scale;
  A(1, 0) = A(0, 1);
  A(2, 0) = A(0, 2);
  A(2, 1) = A(1, 2);
  b(1) /= scale;
  b(2) /= scale;
  A /= sum_w;
  b /= sum_w;
  // The linear terms need spread in both tangent directions.
  if (A.determinant() > 1e-6) {
    const Eigen::Vector3d c = A.ldlt().solve(b);
    if (c.allFinite()) field = {c(0), (c(1) * t1 + c(2) * t2) / scale};
  }
  return field;
}

double smoothScalar(const Vec3& x, const Vec3& n, const std::vector<ScalarSample>& samples) {
  const auto field = fitTangentLinear(x, n, samples);
  return field ? field->value : std::numeric_limits<double>::quiet_NaN();
}

std::optional<LocalPolynomial> fitTangentPolynomial(const Vec3& x, const Vec3& n, const std::vector<ScalarSample>& samples,
                                                    int degree, double scale) {
  if (degree != 1 && degree != 2) throw std::invalid_argument("tangent polynomial: degree 1 or 2");
  if (!(scale > 0)) throw std::invalid_argument("tangent polynomial: the scale must be positive");
  using Row = Eigen::Matrix<double, 6, 1>;
  const int terms = degree == 1 ? 3 : 6;
  const Eigen::Matrix3d frame = frameAround(n);
  const auto row = [&](const Vec3& p) {
    const Vec3 d = (p - x) / scale;
    const double u = d.dot(frame.col(0)), v = d.dot(frame.col(1));
    Row a;
    a << 1.0, u, v, u * u, u * v, v * v;
    return a;
  };
  Eigen::Matrix<double, 6, 6> M = Eigen::Matrix<double, 6, 6>::Zero();
  double sum_w = 0;
  std::size_t used = 0;
  for (const ScalarSample& s : samples) {
    if (!(s.weight > 0)) continue;
    const Row a = row(s.position);
    M.noalias() += s.weight * a * a.transpose();
    sum_w += s.weight;
    ++used;
  }
  if (used < static_cast<std::size_t>(terms) || !(sum_w > 0)) return std::nullopt;
  // At most 6 x 6: on the stack, not the heap (a fit per surface point and model).
  using Normal = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
  using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>;
  const Normal normal = M.topLeftCorner(terms, terms) / sum_w;
  const Eigen::LDLT<Normal> solver(normal);
  // Pivoted LDLT: a near-zero pivot against the largest means a direction the samples do not span.
  const Vector pivots = solver.vectorD();
  if (solver.info() != Eigen::Success || !(pivots.minCoeff() > 1e-8 * pivots.maxCoeff())) return std::nullopt;
  const Vector z = solver.solve(Vector::Unit(terms, 0));
  LocalPolynomial fit{0.0, 0.0};
  for (const ScalarSample& s : samples) {
    if (!(s.weight > 0)) continue;
    const double l = s.weight / sum_w * row(s.position).head(terms).dot(z);
    fit.value += l * s.value;
    fit.amplification += std::abs(l);
  }
  if (!std::isfinite(fit.value) || !std::isfinite(fit.amplification)) return std::nullopt;
  return fit;
}

}  // namespace stampscan::fitting
