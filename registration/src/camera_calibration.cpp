#include "stampscan/registration/camera_calibration.hpp"

#include "stampscan/fitting/median.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampscan::registration {

namespace {

cv::Mat to8bit(const cv::Mat& image) {
  if (image.depth() == CV_8U) return image;
  cv::Mat out;
  double lo = 0, hi = 0;
  cv::minMaxLoc(image, &lo, &hi);
  image.convertTo(out, CV_8U, hi > lo ? 255.0 / (hi - lo) : 1.0, hi > lo ? -lo * 255.0 / (hi - lo) : 0.0);
  return out;
}

Eigen::Isometry3d poseFrom(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix3d r;
  cv::cv2eigen(R, r);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = r;
  T.translation() = Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  return T;
}

double rms(const std::vector<cv::Point2f>& a, const std::vector<cv::Point2f>& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const cv::Point2f d = a[i] - b[i];
    sum += static_cast<double>(d.dot(d));
  }
  return a.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(a.size()));
}

// Where each view puts the (fixed) plate under a candidate mount; their spread is the residual.
void scoreHandEye(const std::vector<Eigen::Isometry3d>& machine_from_head,
                  const std::vector<Eigen::Isometry3d>& camera_from_plate, HandEyeResult& out) {
  std::vector<Eigen::Isometry3d> plates;
  Eigen::Vector3d mean_t = Eigen::Vector3d::Zero();
  Eigen::Matrix3d mean_r = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < machine_from_head.size(); ++i) {
    plates.push_back(machine_from_head[i] * out.head_from_camera * camera_from_plate[i]);
    mean_t += plates.back().translation();
    mean_r += plates.back().linear();
  }
  const double n = static_cast<double>(plates.size());
  mean_t /= n;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(mean_r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d rotation = svd.matrixU() * svd.matrixV().transpose();
  if (rotation.determinant() < 0) rotation = -rotation;
  out.machine_from_plate.linear() = rotation;
  out.machine_from_plate.translation() = mean_t;
  double sq_t = 0, sq_r = 0;
  for (const Eigen::Isometry3d& p : plates) {
    sq_t += (p.translation() - mean_t).squaredNorm();
    const double angle = Eigen::AngleAxisd(rotation.transpose() * p.linear()).angle();
    sq_r += angle * angle;
  }
  out.residual_mm = std::sqrt(sq_t / n);
  out.residual_deg = std::sqrt(sq_r / n) * 180 / M_PI;
}

}  // namespace

std::vector<cv::Point3f> plateModel(const CirclePlateSpec& plate) {
  std::vector<cv::Point3f> model;
  for (int j = 0; j < plate.rows; ++j)
    for (int i = 0; i < plate.columns; ++i)
      model.emplace_back(static_cast<float>(i * plate.pitch), static_cast<float>(j * plate.pitch), 0.0f);
  return model;
}

std::vector<cv::Point2f> detectCirclePlate(const cv::Mat& image, const CirclePlateSpec& plate) {
  const cv::Mat gray = to8bit(image);
  cv::SimpleBlobDetector::Params p;
  p.filterByColor = true;
  p.blobColor = 0;  // dark dots on a white plate
  p.minArea = 12;
  p.maxArea = static_cast<float>(gray.total()) / 50.0f;
  p.filterByInertia = true;
  p.minInertiaRatio = 0.2f;  // tilted plates make ellipses
  p.filterByConvexity = true;
  p.minConvexity = 0.85f;
  p.filterByCircularity = false;
  const cv::Ptr<cv::FeatureDetector> detector = cv::SimpleBlobDetector::create(p);
  std::vector<cv::Point2f> centres;
  const cv::Size pattern(plate.columns, plate.rows);
  // The default grid finder fails on plates turned by about 45 degrees in the image; the clustering
  // one handles those (and is slower), so it is the fallback.
  bool found = cv::findCirclesGrid(gray, pattern, centres, cv::CALIB_CB_SYMMETRIC_GRID, detector);
  if (!found) found = cv::findCirclesGrid(gray, pattern, centres, cv::CALIB_CB_SYMMETRIC_GRID | cv::CALIB_CB_CLUSTERING, detector);
  if (!found || centres.size() != static_cast<std::size_t>(plate.columns * plate.rows)) return {};
  // A symmetric grid reads the same turned by 180 degrees. Fix the order so that the plate's x axis
  // (along a row) points to the right of the image: then views from different directions, and the
  // two cameras of a pair, all number the dots alike (the head turns by less than 90 degrees).
  if (centres[static_cast<std::size_t>(plate.columns - 1)].x < centres[0].x) std::reverse(centres.begin(), centres.end());
  return centres;
}

PlateView findPlate(const cv::Mat& image, const CirclePlateSpec& plate) {
  if (image.empty()) return {};
  return {image.size(), detectCirclePlate(image, plate)};
}

namespace {

std::vector<PlateView> findPlates(const std::vector<cv::Mat>& images, const CirclePlateSpec& plate) {
  std::vector<PlateView> views(images.size());
  tbb::parallel_for(std::size_t{0}, images.size(), [&](std::size_t v) { views[v] = findPlate(images[v], plate); });
  return views;
}

}  // namespace

CameraCalibration calibrateCamera(const std::vector<cv::Mat>& images, const CirclePlateSpec& plate,
                                  const CalibrationParams& params) {
  return calibrateCamera(findPlates(images, plate), plate, params);
}

CameraCalibration calibrateCamera(const std::vector<PlateView>& views, const CirclePlateSpec& plate,
                                  const CalibrationParams& params) {
  CameraCalibration out;
  out.views.resize(views.size());
  out.plate_poses.assign(views.size(), std::nullopt);
  cv::Size size;
  for (std::size_t v = 0; v < views.size(); ++v) {
    out.views[v].view = v;
    if (views[v].image_size.empty()) {
      out.views[v].note = "empty image";
      continue;
    }
    if (size.area() == 0) size = views[v].image_size;
    if (views[v].image_size != size) {
      out.views[v].note = "image size differs from the first view";
      continue;
    }
    out.views[v].used = !views[v].dots.empty();
    if (!out.views[v].used) out.views[v].note = "plate not found";
  }
  const std::vector<cv::Point3f> model = plateModel(plate);
  const int flags = params.fix_k3 ? cv::CALIB_FIX_K3 : 0;
  cv::Mat K, D;
  for (int round = 0; round < 3; ++round) {
    std::vector<std::vector<cv::Point3f>> object;
    std::vector<std::vector<cv::Point2f>> points;
    std::vector<std::size_t> index;
    for (std::size_t v = 0; v < views.size(); ++v)
      if (out.views[v].used) {
        object.push_back(model);
        points.push_back(views[v].dots);
        index.push_back(v);
      }
    if (points.size() < params.min_views)
      throw std::runtime_error("camera calibration: the plate was found in " + std::to_string(points.size()) + " of " +
                               std::to_string(views.size()) + " views; at least " + std::to_string(params.min_views) +
                               " are needed");
    std::vector<cv::Mat> rvecs, tvecs;
    cv::Mat intrinsics_sd, extrinsics_sd, view_errors;
    out.rms_px = cv::calibrateCamera(object, points, size, K, D, rvecs, tvecs, intrinsics_sd, extrinsics_sd, view_errors, flags);
    out.intrinsics_sd.assign(intrinsics_sd.begin<double>(), intrinsics_sd.begin<double>() + std::min(9, intrinsics_sd.rows));
    std::vector<double> errors;
    for (std::size_t k = 0; k < index.size(); ++k) {
      std::vector<cv::Point2f> projected;
      cv::projectPoints(model, rvecs[k], tvecs[k], K, D, projected);
      out.views[index[k]].rms_px = rms(projected, points[k]);
      out.plate_poses[index[k]] = poseFrom(rvecs[k], tvecs[k]);
      errors.push_back(out.views[index[k]].rms_px);
    }
    const double limit = std::max(params.outlier_factor * fitting::medianOr(errors, 0.0), params.outlier_floor_px);
    bool dropped = false;
    for (std::size_t v : index)
      if (out.views[v].rms_px > limit) {
        out.views[v].used = false;
        out.views[v].note = "reprojection error stands out (" + std::to_string(out.views[v].rms_px) + " px)";
        out.plate_poses[v].reset();
        dropped = true;
      }
    if (!dropped) break;
  }
  out.model.size = size;
  out.model.matrix = cv::Matx33d(K);
  out.model.distortion = D.clone();
  return out;
}

StereoCalibration calibrateStereo(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                                  const CirclePlateSpec& plate, const CalibrationParams& params) {
  if (left.size() != right.size()) throw std::invalid_argument("stereo calibration: left and right image counts differ");
  return calibrateStereo(findPlates(left, plate), findPlates(right, plate), plate, params);
}

StereoCalibration calibrateStereo(const std::vector<PlateView>& left, const std::vector<PlateView>& right,
                                  const CirclePlateSpec& plate, const CalibrationParams& params) {
  if (left.size() != right.size()) throw std::invalid_argument("stereo calibration: left and right view counts differ");
  StereoCalibration out;
  out.left = calibrateCamera(left, plate, params);
  out.right = calibrateCamera(right, plate, params);
  const std::vector<cv::Point3f> model = plateModel(plate);
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> l, r;
  for (std::size_t v = 0; v < left.size(); ++v) {
    if (!out.left.views[v].used || !out.right.views[v].used) continue;
    object.push_back(model);
    l.push_back(left[v].dots);
    r.push_back(right[v].dots);
  }
  out.pairs_used = object.size();
  if (out.pairs_used < 3)
    throw std::runtime_error("stereo calibration: only " + std::to_string(out.pairs_used) +
                             " pairs show the plate in both cameras; at least 3 are needed");
  cv::Mat K1(out.left.model.matrix), K2(out.right.model.matrix);
  cv::Mat D1 = out.left.model.distortion.clone(), D2 = out.right.model.distortion.clone();
  cv::Mat R, T, E, F;
  out.rms_px = cv::stereoCalibrate(object, l, r, K1, D1, K2, D2, out.left.model.size, R, T, E, F, cv::CALIB_FIX_INTRINSIC);
  out.right_from_left = poseFrom([&] {
    cv::Mat rvec;
    cv::Rodrigues(R, rvec);
    return rvec;
  }(), T);
  out.baseline_mm = cv::norm(T);
  // The baseline's standard uncertainty by the jackknife over the pairs (each left out once).
  if (out.pairs_used >= 4) {
    std::vector<double> baselines;
    for (std::size_t leave = 0; leave < object.size(); ++leave) {
      std::vector<std::vector<cv::Point3f>> o;
      std::vector<std::vector<cv::Point2f>> a, b;
      for (std::size_t k = 0; k < object.size(); ++k)
        if (k != leave) {
          o.push_back(object[k]);
          a.push_back(l[k]);
          b.push_back(r[k]);
        }
      cv::Mat R2, T2, E2, F2;
      cv::stereoCalibrate(o, a, b, K1, D1, K2, D2, out.left.model.size, R2, T2, E2, F2, cv::CALIB_FIX_INTRINSIC);
      baselines.push_back(cv::norm(T2));
    }
    out.baseline_sd_mm = jackknifeSd(baselines);
  }
  return out;
}

double jackknifeSd(const std::vector<double>& values) {
  const std::size_t n = values.size();
  if (n < 2) return 0;
  double mean = 0;
  for (double v : values) mean += v;
  mean /= static_cast<double>(n);
  double ss = 0;
  for (double v : values) ss += (v - mean) * (v - mean);
  return std::sqrt(static_cast<double>(n - 1) / static_cast<double>(n) * ss);
}

HandEyeResult calibrateHeadToCamera(const std::vector<Eigen::Isometry3d>& machine_from_head,
                                    const std::vector<Eigen::Isometry3d>& camera_from_plate) {
  if (machine_from_head.size() != camera_from_plate.size() || machine_from_head.size() < 3)
    throw std::invalid_argument("hand-eye calibration: needs at least 3 views with both a head pose and a plate pose");
  std::vector<cv::Mat> R_head, t_head, R_plate, t_plate;
  // Fresh matrices for every entry: eigen2cv writes into an existing buffer of the right size, and the
  // vectors hold headers that share it.
  const auto rotation = [](const Eigen::Isometry3d& T) {
    cv::Mat m;
    cv::eigen2cv(Eigen::Matrix3d(T.linear()), m);
    return m;
  };
  const auto translation = [](const Eigen::Isometry3d& T) {
    cv::Mat m;
    cv::eigen2cv(Eigen::Vector3d(T.translation()), m);
    return m;
  };
  for (std::size_t i = 0; i < machine_from_head.size(); ++i) {
    R_head.push_back(rotation(machine_from_head[i]));
    t_head.push_back(translation(machine_from_head[i]));
    R_plate.push_back(rotation(camera_from_plate[i]));
    t_plate.push_back(translation(camera_from_plate[i]));
  }
  // The closed-form solvers differ in how they weigh rotation against translation; each is tried and
  // the one under which the fixed plate moves least is kept.
  HandEyeResult best;
  bool have = false;
  for (const cv::HandEyeCalibrationMethod method :
       {cv::CALIB_HAND_EYE_PARK, cv::CALIB_HAND_EYE_TSAI, cv::CALIB_HAND_EYE_HORAUD, cv::CALIB_HAND_EYE_DANIILIDIS}) {
    cv::Mat R, t;
    cv::calibrateHandEye(R_head, t_head, R_plate, t_plate, R, t, method);
    if (R.empty() || t.empty()) continue;
    HandEyeResult candidate;
    Eigen::Matrix3d r;
    cv::cv2eigen(R, r);
    candidate.head_from_camera.linear() = r;
    candidate.head_from_camera.translation() = Eigen::Vector3d(t.at<double>(0), t.at<double>(1), t.at<double>(2));
    scoreHandEye(machine_from_head, camera_from_plate, candidate);
    if (!have || candidate.residual_mm < best.residual_mm) best = candidate;
    have = true;
  }
  if (!have) throw std::runtime_error("hand-eye calibration: no solver returned a result");
  return best;
}

}  // namespace stampscan::registration
