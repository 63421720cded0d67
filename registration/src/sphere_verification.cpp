#include "stampscan/registration/sphere_verification.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

namespace stampscan::registration {

namespace {

struct AlgebraicSphere {
  Vec3 centre = Vec3::Zero();
  double radius = 0;
  bool valid = false;  // false when the points do not determine a sphere
};

// The linear fit |x|^2 = 2 c.x + (r^2 - |c|^2): not the least-squares sphere (it weighs points by
// their distance), but close to it and without a start; the geometric fit starts from it.
template <typename PointAt>
AlgebraicSphere algebraicSphere(std::size_t n, PointAt point) {
  Eigen::MatrixXd A(static_cast<Eigen::Index>(n), 4);
  Eigen::VectorXd b(static_cast<Eigen::Index>(n));
  // Centred, so that a sphere far from the origin does not lose digits.
  Vec3 mean = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) mean += point(i);
  mean /= static_cast<double>(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 x = point(i) - mean;
    A.row(static_cast<Eigen::Index>(i)) << 2 * x.x(), 2 * x.y(), 2 * x.z(), 1;
    b(static_cast<Eigen::Index>(i)) = x.squaredNorm();
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  AlgebraicSphere s;
  if (qr.rank() < 4) return s;
  const Eigen::Vector4d x = qr.solve(b);
  const double r2 = x(3) + x.head<3>().squaredNorm();
  if (!(r2 > 0) || !std::isfinite(r2)) return s;
  s.centre = mean + x.head<3>();
  s.radius = std::sqrt(r2);
  s.valid = true;
  return s;
}

// The sphere of radius R among points that also hold other surfaces (the table under the sphere):
// spheres through random quadruples of points, the one with a radius near R that has most points
// within `shell` of it. Seeded, so that a verification is repeatable.
Vec3 locateSphere(std::span<const Vec3> points, double R, double shell) {
  // Counting on a few thousand points is enough to tell the sphere from the table.
  const std::size_t stride = std::max<std::size_t>(1, points.size() / 4000);
  std::vector<Vec3> sample;
  for (std::size_t i = 0; i < points.size(); i += stride) sample.push_back(points[i]);
  std::mt19937_64 rng(10360);
  std::uniform_int_distribution<std::size_t> pick(0, sample.size() - 1);
  Vec3 best = Vec3::Zero();
  std::size_t best_count = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const std::size_t idx[4] = {pick(rng), pick(rng), pick(rng), pick(rng)};
    const AlgebraicSphere s = algebraicSphere(4, [&](std::size_t k) { return sample[idx[k]]; });
    if (!s.valid || std::abs(s.radius - R) > 0.1 * R) continue;
    std::size_t count = 0;
    for (const Vec3& x : sample)
      if (std::abs((x - s.centre).norm() - R) < shell) ++count;
    if (count > best_count) {
      best_count = count;
      best = s.centre;
    }
  }
  if (best_count == 0) throw std::runtime_error("no sphere of radius " + std::to_string(R) + " mm among the points");
  // Refine the centre on the points in the shell (radius held at R): Gauss-Newton, 3 unknowns.
  for (int it = 0; it < 20; ++it) {
    Eigen::Matrix3d JtJ = Eigen::Matrix3d::Zero();
    Vec3 Jtr = Vec3::Zero();
    for (const Vec3& x : sample) {
      const Vec3 d = x - best;
      const double dist = d.norm();
      const double r = dist - R;
      if (std::abs(r) >= shell || dist == 0) continue;
      const Vec3 j = -d / dist;
      JtJ += j * j.transpose();
      Jtr += j * r;
    }
    const Vec3 step = JtJ.ldlt().solve(-Jtr);
    if (!step.allFinite()) break;
    best += step;
    if (step.norm() < 1e-7) break;
  }
  return best;
}

}  // namespace

SphereFit fitSphere(std::span<const Vec3> points) {
  if (points.size() < 4)
    throw std::invalid_argument("sphere fit: " + std::to_string(points.size()) + " points; at least 4 are needed");
  const AlgebraicSphere start = algebraicSphere(points.size(), [&](std::size_t i) { return points[i]; });
  if (!start.valid) throw std::invalid_argument("sphere fit: the points lie on a plane or a line, not on a sphere");
  // Gauss-Newton on the radial deviations r_i = |x_i - c| - R, unknowns (c, R).
  SphereFit fit;
  Vec3 c = start.centre;
  double R = start.radius;
  for (int it = 0; it < 50; ++it) {
    fit.iterations = it + 1;
    Eigen::Matrix4d JtJ = Eigen::Matrix4d::Zero();
    Eigen::Vector4d Jtr = Eigen::Vector4d::Zero();
    for (const Vec3& x : points) {
      const Vec3 d = x - c;
      const double dist = d.norm();
      if (dist == 0) continue;
      Eigen::Vector4d j;
      j << -d / dist, -1;
      JtJ += j * j.transpose();
      Jtr += j * (dist - R);
    }
    const Eigen::Vector4d step = JtJ.ldlt().solve(-Jtr);
    if (!step.allFinite()) break;
    c += step.head<3>();
    R += step(3);
    if (step.norm() < 1e-10 * std::max(1.0, R)) break;
  }
  fit.centre = c;
  fit.radius = R;
  fit.points = points.size();
  double sum = 0;
  fit.min_deviation_mm = std::numeric_limits<double>::infinity();
  fit.max_deviation_mm = -std::numeric_limits<double>::infinity();
  for (const Vec3& x : points) {
    const double r = (x - c).norm() - R;
    sum += r * r;
    fit.min_deviation_mm = std::min(fit.min_deviation_mm, r);
    fit.max_deviation_mm = std::max(fit.max_deviation_mm, r);
  }
  fit.rms_mm = std::sqrt(sum / static_cast<double>(points.size()));
  return fit;
}

SphereVerification verifySphere(std::span<const Vec3> points, const SphereVerificationParams& params) {
  if (!(params.certified_diameter_mm > 0))
    throw std::invalid_argument("sphere verification: the certified diameter must be positive");
  SphereVerification v;
  v.points_measured = points.size();
  if (points.size() < params.min_points)
    throw std::runtime_error("sphere verification: " + std::to_string(points.size()) + " points measured; at least " +
                             std::to_string(params.min_points) + " are needed on the sphere");
  const double R = 0.5 * params.certified_diameter_mm;
  const Vec3 centre = locateSphere(points, R, params.evaluation_shell_mm);
  std::vector<Vec3> on_sphere;
  for (const Vec3& x : points)
    if (std::abs((x - centre).norm() - R) < params.evaluation_shell_mm) on_sphere.push_back(x);
  v.points_on_sphere = on_sphere.size();
  if (on_sphere.size() < params.min_points)
    throw std::runtime_error("sphere verification: " + std::to_string(on_sphere.size()) + " of " +
                             std::to_string(points.size()) + " points lie on the sphere (within " +
                             std::to_string(params.evaluation_shell_mm) + " mm of its certified radius); at least " +
                             std::to_string(params.min_points) + " are needed");
  v.fit = fitSphere(on_sphere);
  // ISO 10360-8, probing errors: form = the range of radial distances to the least-squares sphere;
  // size = its diameter minus the certified diameter.
  v.form_error_mm = v.fit.max_deviation_mm - v.fit.min_deviation_mm;
  v.size_error_mm = 2 * v.fit.radius - params.certified_diameter_mm;
  v.form_passed = v.form_error_mm <= params.form_mpe_mm;
  v.size_passed = std::abs(v.size_error_mm) <= params.size_mpe_mm;
  return v;
}

std::vector<Vec3> spherePoints(const std::vector<Profile>& profiles, const HeadTrack& track,
                               const DigitizerCalibration& calibration) {
  std::vector<Vec3> points;
  for (const Profile& p : profiles)
    if (!p.overexposed) profileToMachine(p, track, calibration, points);
  return points;
}

}  // namespace stampscan::registration
