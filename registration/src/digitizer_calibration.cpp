#include "stampscan/registration/digitizer_calibration.hpp"

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampscan::registration {

namespace {

// One measured return: where it was in the sensor frame, and its uncorrected stamp.
struct Sample {
  Vec3 sensor;
  std::int64_t stamp_ns;  // device time minus clock offset (the exposure time if latency were 0)
};

// Parameters: rotation increment (3) and translation increment (3) of the mount, latency in ms,
// sphere centre (3).
using Params = Eigen::Matrix<double, 10, 1>;

Eigen::Isometry3d mountOf(const Eigen::Isometry3d& nominal, const Params& p) {
  Eigen::Isometry3d X = nominal;
  const Vec3 w = p.segment<3>(0);
  if (w.norm() > 0) X.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() * nominal.linear();
  X.translation() = nominal.translation() + p.segment<3>(3);
  return X;
}

// Algebraic sphere fit |x|^2 = 2 c.x + (r^2 - |c|^2): the start for the centre.
Vec3 sphereCentre(const std::vector<Vec3>& points) {
  Eigen::MatrixXd A(points.size(), 4);
  Eigen::VectorXd b(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    A.row(static_cast<Eigen::Index>(i)) << 2 * points[i].x(), 2 * points[i].y(), 2 * points[i].z(), 1;
    b(static_cast<Eigen::Index>(i)) = points[i].squaredNorm();
  }
  const Eigen::Vector4d x = A.colPivHouseholderQr().solve(b);
  return x.head<3>();
}

}  // namespace

SphereCalibrationResult calibrateDigitizer(const std::vector<Profile>& profiles, const HeadTrack& track,
                                           const SphereCalibrationParams& params) {
  std::vector<Sample> all;
  for (const Profile& p : profiles) {
    if (p.overexposed) continue;
    for (std::size_t i = 0; i < p.range.size(); ++i)
      if (p.range[i] > 0) all.push_back({sensorPoint(p, i), p.device_time_ns - params.nominal.clock_offset_ns});
  }
  if (all.size() < 200) throw std::runtime_error("digitizer calibration: only " + std::to_string(all.size()) +
                                                 " returns in the sphere sweeps; at least 200 are needed");
  std::vector<Sample> samples;
  const std::size_t stride = std::max<std::size_t>(1, all.size() / params.max_points);
  for (std::size_t i = 0; i < all.size(); i += stride)
    if (track.covers(all[i].stamp_ns - 10'000'000) && track.covers(all[i].stamp_ns + 10'000'000)) samples.push_back(all[i]);
  const std::size_t n = samples.size();
  const double R = params.sphere_radius;

  const auto residuals = [&](const Params& p, Eigen::VectorXd& r) {
    const Eigen::Isometry3d X = mountOf(params.nominal.head_from_digitizer, p);
    const auto latency = static_cast<std::int64_t>(std::llround(p(6) * 1e6));
    const Vec3 c = p.segment<3>(7);
    r.resize(static_cast<Eigen::Index>(n));
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      const Vec3 x = track.poseAt(samples[i].stamp_ns - latency) * (X * samples[i].sensor);
      r(static_cast<Eigen::Index>(i)) = (x - c).norm() - R;
    });
  };

  Params p = Params::Zero();
  {
    std::vector<Vec3> start;
    for (const Sample& s : samples) start.push_back(track.poseAt(s.stamp_ns) * (params.nominal.head_from_digitizer * s.sensor));
    p.segment<3>(7) = sphereCentre(start);
  }
  // Gauss-Newton with Levenberg damping and Tukey weights; forward-difference Jacobian (10 columns).
  const Params steps = (Params() << 1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4, 1e-3, 1e-4, 1e-4, 1e-4).finished();
  Eigen::VectorXd r, r_step, w(static_cast<Eigen::Index>(n));
  double lambda = 1e-3;
  SphereCalibrationResult out;
  residuals(p, r);
  const auto weights = [&](const Eigen::VectorXd& res) {
    std::vector<double> a(static_cast<std::size_t>(res.size()));
    for (Eigen::Index i = 0; i < res.size(); ++i) a[static_cast<std::size_t>(i)] = std::abs(res(i));
    std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2), a.end());
    const double cutoff = params.tukey_constant * std::max(1.4826 * a[a.size() / 2], 1e-6);
    for (Eigen::Index i = 0; i < res.size(); ++i) {
      const double u = res(i) / cutoff;
      w(i) = std::abs(u) < 1 ? (1 - u * u) * (1 - u * u) : 0.0;
    }
  };
  const auto cost = [&](const Eigen::VectorXd& res) { return (w.array() * res.array().square()).sum(); };
  weights(r);
  for (int it = 0; it < params.max_iterations; ++it) {
    out.iterations = it + 1;
    Eigen::MatrixXd J(static_cast<Eigen::Index>(n), 10);
    for (int k = 0; k < 10; ++k) {
      Params q = p;
      q(k) += steps(k);
      residuals(q, r_step);
      J.col(k) = (r_step - r) / steps(k);
    }
    const Eigen::Matrix<double, 10, 10> JtWJ = J.transpose() * w.asDiagonal() * J;
    const Eigen::Matrix<double, 10, 1> JtWr = J.transpose() * (w.array() * r.array()).matrix();
    const double before = cost(r);
    bool improved = false;
    for (int tries = 0; tries < 10 && !improved; ++tries) {
      Eigen::Matrix<double, 10, 10> A = JtWJ;
      A.diagonal() *= 1 + lambda;
      const Params delta = A.ldlt().solve(-JtWr);
      residuals(p + delta, r_step);
      if (cost(r_step) < before) {
        p += delta;
        r = r_step;
        lambda = std::max(lambda * 0.3, 1e-9);
        improved = true;
        if (delta.cwiseQuotient(steps).cwiseAbs().maxCoeff() < 1e-2) it = params.max_iterations;  // converged
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
    weights(r);
  }
  out.calibration = params.nominal;
  out.calibration.head_from_digitizer = mountOf(params.nominal.head_from_digitizer, p);
  out.calibration.latency_ns = static_cast<std::int64_t>(std::llround(p(6) * 1e6));
  out.sphere_centre = p.segment<3>(7);
  out.points = n;
  double sum = 0;
  for (Eigen::Index i = 0; i < r.size(); ++i)
    if (w(i) > 0) {
      sum += r(i) * r(i);
      ++out.inliers;
    }
  out.rms_mm = out.inliers ? std::sqrt(sum / static_cast<double>(out.inliers)) : 0;
  return out;
}

}  // namespace stampscan::registration
