#include "stampscan/registration/stereo_verification.hpp"

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampscan::registration {

std::vector<cv::Point3d> triangulatePlate(const cv::Mat& left, const cv::Mat& right, const StereoCalibration& stereo,
                                          const CirclePlateSpec& plate) {
  const std::vector<cv::Point2f> l = detectCirclePlate(left, plate), r = detectCirclePlate(right, plate);
  if (l.empty() || r.empty() || l.size() != r.size()) return {};
  // Normalised image coordinates (distortion removed), then the two cameras' projections: the left
  // at the origin, the right at right_from_left.
  std::vector<cv::Point2f> ln, rn;
  cv::undistortPoints(l, ln, cv::Mat(stereo.left.model.matrix), stereo.left.model.distortion);
  cv::undistortPoints(r, rn, cv::Mat(stereo.right.model.matrix), stereo.right.model.distortion);
  cv::Matx34d p_left = cv::Matx34d::eye(), p_right;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) p_right(i, j) = stereo.right_from_left.linear()(i, j);
    p_right(i, 3) = stereo.right_from_left.translation()(i);
  }
  cv::Mat homogeneous;
  cv::triangulatePoints(p_left, p_right, ln, rn, homogeneous);
  homogeneous.convertTo(homogeneous, CV_64F);
  std::vector<cv::Point3d> out;
  for (int k = 0; k < homogeneous.cols; ++k) {
    const double w = homogeneous.at<double>(3, k);
    out.emplace_back(homogeneous.at<double>(0, k) / w, homogeneous.at<double>(1, k) / w, homogeneous.at<double>(2, k) / w);
  }
  return out;
}

namespace {

// The range of the points' signed distances from their least-squares plane.
double flatForm(const std::vector<cv::Point3d>& points) {
  Eigen::MatrixXd m(static_cast<Eigen::Index>(points.size()), 3);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += Eigen::Vector3d(p.x, p.y, p.z);
  mean /= static_cast<double>(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    m.row(static_cast<Eigen::Index>(i)) = Eigen::Vector3d(points[i].x, points[i].y, points[i].z) - mean;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(m, Eigen::ComputeThinV);
  const Eigen::Vector3d normal = svd.matrixV().col(2);
  const Eigen::VectorXd d = m * normal;
  return d.maxCoeff() - d.minCoeff();
}

}  // namespace

StereoPlateCheck verifyStereoOnPlate(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                                     const StereoCalibration& stereo, const CirclePlateSpec& plate,
                                     const StereoPlateParams& params) {
  if (left.size() != right.size()) throw std::invalid_argument("stereo verification: left and right image counts differ");
  const std::vector<cv::Point3f> model = plateModel(plate);
  StereoPlateCheck out;
  double ss = 0;
  std::size_t pairs = 0;
  for (std::size_t v = 0; v < left.size(); ++v) {
    const std::vector<cv::Point3d> dots = triangulatePlate(left[v], right[v], stereo, plate);
    if (dots.size() != model.size()) continue;
    ++out.views;
    out.dots += dots.size();
    out.form_error_mm = std::max(out.form_error_mm, flatForm(dots));
    for (std::size_t i = 0; i < dots.size(); ++i)
      for (std::size_t j = i + 1; j < dots.size(); ++j) {
        const double certified = cv::norm(cv::Point3d(model[i]) - cv::Point3d(model[j]));
        const double error = cv::norm(dots[i] - dots[j]) - certified;
        if (std::abs(error) > std::abs(out.length_error_mm)) out.length_error_mm = error;
        out.longest_length_mm = std::max(out.longest_length_mm, certified);
        ss += error * error;
        ++pairs;
      }
  }
  if (out.views == 0)
    throw std::runtime_error("stereo verification: no view shows the whole plate in both cameras (" +
                             std::to_string(left.size()) + " views)");
  out.rms_length_error_mm = std::sqrt(ss / static_cast<double>(pairs));
  out.form_passed = out.form_error_mm <= params.form_mpe_mm;
  out.length_passed = std::abs(out.length_error_mm) <= params.length_mpe_mm;
  return out;
}

}  // namespace stampscan::registration
