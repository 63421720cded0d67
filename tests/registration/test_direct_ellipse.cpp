// The direct least-squares ellipse fit against the ellipses that made its points, and against
// OpenCV's fit of the same points (cv::fitEllipseDirect, which it replaces on the hot paths).
#include "stampscan/registration/direct_ellipse.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>
#include <random>

namespace stampscan::registration {
namespace {

struct Drawn {
  Eigen::Vector2d centre;
  double a, b, angle;  // semi-axes and the major axis' angle
  Eigen::Matrix2d shape() const {
    const Eigen::Matrix2d R = Eigen::Rotation2Dd(angle).toRotationMatrix();
    return R * Eigen::Vector2d(a, b).asDiagonal() * R.transpose();
  }
  std::vector<Eigen::Vector2d> points(int n, double from, double to, double noise, std::mt19937& rng) const {
    std::normal_distribution<double> gauss(0, noise);
    std::vector<Eigen::Vector2d> out;
    const Eigen::Matrix2d M = shape();
    for (int k = 0; k < n; ++k) {
      const double t = from + (to - from) * k / n;
      out.push_back(centre + M * Eigen::Vector2d(std::cos(t), std::sin(t)) + Eigen::Vector2d(gauss(rng), gauss(rng)));
    }
    return out;
  }
};

TEST(DirectEllipse, RecoversTheEllipseThatMadeItsPoints) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 200; ++trial) {
    // A printed circle's size in millimetres, far from the origin as on the sheet; the arc as little
    // as a third of the ring (a ring cut by the sweep's edge).
    const Drawn e{{200 * u(rng) - 100, 200 * u(rng) - 100}, 1.1 + 0.4 * u(rng), 0.9 + 0.2 * u(rng), 2 * std::numbers::pi * u(rng)};
    const double span = 2 * std::numbers::pi * (trial % 2 == 0 ? 1.0 : 0.35);
    const auto fit = fitDirectEllipse(e.points(60, 0, span, 0, rng));
    ASSERT_TRUE(fit) << "trial " << trial;
    EXPECT_LT((fit->centre - e.centre).norm(), 1e-8) << "trial " << trial;
    EXPECT_LT((fit->shape - e.shape()).cwiseAbs().maxCoeff(), 1e-8) << "trial " << trial;
  }
}

TEST(DirectEllipse, FitsWhatOpenCvFitsOnNoisyPoints) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 200; ++trial) {
    const Drawn e{{10 * u(rng), 10 * u(rng)}, 1.2 + 0.3 * u(rng), 1.0 + 0.15 * u(rng), std::numbers::pi * u(rng)};
    const std::vector<Eigen::Vector2d> pts = e.points(360, 0, 2 * std::numbers::pi, 0.003, rng);
    const auto fit = fitDirectEllipse(pts);
    ASSERT_TRUE(fit);
    // OpenCV's in micrometres (it takes floats), as the measurement used it.
    std::vector<cv::Point2f> cv_pts;
    for (const auto& q : pts) cv_pts.emplace_back(static_cast<float>(1000 * q.x()), static_cast<float>(1000 * q.y()));
    const cv::RotatedRect box = cv::fitEllipseDirect(cv_pts);
    const Drawn theirs{{box.center.x / 1000.0, box.center.y / 1000.0}, box.size.width / 2000.0, box.size.height / 2000.0,
                       box.angle * std::numbers::pi / 180};
    // The same fit: 20 nm apart at most (OpenCV's comes out some 15 nm larger, from its floats),
    // against 160 nm that the 3 um noise moves the axes of either.
    EXPECT_LT((fit->centre - theirs.centre).norm(), 4e-5) << "trial " << trial;
    EXPECT_LT((fit->shape - theirs.shape()).cwiseAbs().maxCoeff(), 4e-5) << "trial " << trial;
  }
}

TEST(DirectEllipse, RefusesWhatIsNoEllipse) {
  EXPECT_FALSE(fitDirectEllipse({}));
  EXPECT_FALSE(fitDirectEllipse({{0, 0}, {1, 0}, {0, 1}, {1, 1}, {2, 3}}));  // five points fit any conic
  std::vector<Eigen::Vector2d> line;
  for (int k = 0; k < 20; ++k) line.emplace_back(k, 2 * k + 1);
  EXPECT_FALSE(fitDirectEllipse(line));
  std::vector<Eigen::Vector2d> same(20, Eigen::Vector2d(3, 4));
  EXPECT_FALSE(fitDirectEllipse(same));
}

}  // namespace
}  // namespace stampscan::registration
