// Camera and stereo calibration from images of the circle plate, and the head-to-camera (hand-eye)
// transform from the CMM's head poses, with OpenCV. Every view gets its reprojection error; views
// where the plate is not found, or whose error stands out, are left out and say why.
//
// Frames: OpenCV's camera frame (x right, y down, z forward); the plate frame has dot (i, j) at
// (i * pitch, j * pitch, 0); the head frame is the CMM's (see sim::HeadState::pose: the station
// reads the same translation * Rz(b) * Rx(a) from the CMM's position reports).
#pragma once

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <optional>
#include <string>
#include <vector>

namespace stampscan::registration {

struct CirclePlateSpec {
  int columns = 9, rows = 7;  // dots
  double pitch = 6;           // mm between dot centres
};

// Dot centres in the image, ordered as plateModel() lists them; empty when the plate is not found.
std::vector<cv::Point2f> detectCirclePlate(const cv::Mat& image, const CirclePlateSpec& plate);
std::vector<cv::Point3f> plateModel(const CirclePlateSpec& plate);

// What calibration needs of one camera's image of the plate: the image's size and the dots found
// there (detectCirclePlate; empty when not found). A few hundred bytes instead of the image, so a
// scan finds them as each view arrives and lets the image go.
struct PlateView {
  cv::Size image_size;  // empty for an empty image
  std::vector<cv::Point2f> dots;
};
PlateView findPlate(const cv::Mat& image, const CirclePlateSpec& plate);

struct CameraModel {
  cv::Size size;
  cv::Matx33d matrix = cv::Matx33d::eye();  // fx 0 cx; 0 fy cy; 0 0 1
  cv::Mat distortion;                       // k1 k2 p1 p2 k3 (1x5)
};

struct ViewReport {
  std::size_t view = 0;    // index in the input
  bool used = false;
  double rms_px = 0;       // reprojection RMS in pixels (0 when not found)
  std::string note;        // why it was left out
};

struct CameraCalibration {
  CameraModel model;
  double rms_px = 0;                  // over the used views
  // Standard deviations of fx, fy, cx, cy (px), k1, k2, p1, p2, k3, as the least-squares fit's
  // Jacobian gives them (cv::calibrateCamera); empty when not estimated.
  std::vector<double> intrinsics_sd;
  std::vector<ViewReport> views;
  // camera_from_plate of every view, empty for views left out.
  std::vector<std::optional<Eigen::Isometry3d>> plate_poses;
};

struct CalibrationParams {
  std::size_t min_views = 5;
  double outlier_factor = 3.0;   // a view whose RMS exceeds this times the median is dropped...
  double outlier_floor_px = 0.3; // ...unless it is below this anyway
  bool fix_k3 = true;            // few views cannot tell k3 from k1, k2 apart
};

// Throws std::runtime_error naming how many views were usable when fewer than min_views are.
CameraCalibration calibrateCamera(const std::vector<PlateView>& views, const CirclePlateSpec& plate,
                                  const CalibrationParams& params = {});
// The same from the images (the plate is found in each first).
CameraCalibration calibrateCamera(const std::vector<cv::Mat>& images, const CirclePlateSpec& plate,
                                  const CalibrationParams& params = {});

struct StereoCalibration {
  CameraCalibration left, right;
  Eigen::Isometry3d right_from_left = Eigen::Isometry3d::Identity();
  double baseline_mm = 0;
  double baseline_sd_mm = 0;  // standard uncertainty, jackknife over the pairs (0 with fewer than 4)
  double rms_px = 0;
  std::size_t pairs_used = 0;
};

// Pairs are images taken at the same trigger. Each camera is calibrated on its own first, then the
// extrinsics are estimated from the pairs where both saw the plate.
StereoCalibration calibrateStereo(const std::vector<PlateView>& left, const std::vector<PlateView>& right,
                                  const CirclePlateSpec& plate, const CalibrationParams& params = {});
StereoCalibration calibrateStereo(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                                  const CirclePlateSpec& plate, const CalibrationParams& params = {});

// head_from_camera from views of a plate that did not move: for each view the head pose
// (machine_from_head, from the CMM) and camera_from_plate. AX = XB, solved by OpenCV (Park's
// method) and refined by least squares on the plate's implied machine pose. Throws with fewer than
// three views.
struct HandEyeResult {
  Eigen::Isometry3d head_from_camera = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d machine_from_plate = Eigen::Isometry3d::Identity();
  double residual_mm = 0;    // RMS spread of the plate's implied machine position over the views
  double residual_deg = 0;   // RMS spread of its implied orientation
};
// The jackknife's standard error of an estimate from its leave-one-out values θ_i:
// sqrt((n - 1) / n * Σ (θ_i - mean)²); 0 with fewer than 2 values.
double jackknifeSd(const std::vector<double>& leave_one_out);

HandEyeResult calibrateHeadToCamera(const std::vector<Eigen::Isometry3d>& machine_from_head,
                                    const std::vector<Eigen::Isometry3d>& camera_from_plate);

}  // namespace stampscan::registration
