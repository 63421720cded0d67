// Camera, stereo and head-to-camera calibration from the simulator's plate scene, against the
// simulator's true intrinsics, baseline and mount.
#include "session_support.hpp"
#include "stampscan/registration/camera_calibration.hpp"
#include "stampscan/registration/stereo_verification.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>

namespace {

using namespace stampscan;

struct PlateSession {
  test_support::DecodedSession session;
  sim::ScanSummary summary;
  std::vector<cv::Mat> left, right;
  std::vector<Eigen::Isometry3d> heads;
};

const PlateSession& plateSession() {
  static const PlateSession s = [] {
    PlateSession out;
    sim::ScanParams p;
    p.laser = p.stereo = false;
    p.sphere_sweeps = 0;
    p.plate_poses = 14;
    p.image_scale = 0.5;
    p.seed = 11;
    out.summary = sim::generateScan(p, out.session);
    const std::int64_t offset = out.session.clockOffset("camera_left");
    for (const auto& [trigger, pair] : out.session.pairs) {
      if (!pair.complete()) continue;
      out.left.push_back(test_support::DecodedSession::image(pair.left));
      out.right.push_back(test_support::DecodedSession::image(pair.right));
      out.heads.push_back(out.session.headAt(pair.left.device_time_ns - offset).pose());
    }
    return out;
  }();
  return s;
}

registration::CirclePlateSpec plateSpec() {
  const sim::CirclePlate plate;
  return {plate.columns, plate.rows, plate.pitch};
}

TEST(CameraCalibration, RecoversTheTrueIntrinsics) {
  const PlateSession& s = plateSession();
  ASSERT_EQ(s.left.size(), 14u);
  const registration::CameraCalibration c = registration::calibrateCamera(s.left, plateSpec());
  const sim::CameraIntrinsics& truth = s.summary.truth.left;
  std::printf("left camera: rms %.3f px; fx %.2f (true %.2f) fy %.2f (%.2f) cx %.2f (%.2f) cy %.2f (%.2f) k1 %.4f (%.4f) k2 %.4f (%.4f)\n",
              c.rms_px, c.model.matrix(0, 0), truth.fx, c.model.matrix(1, 1), truth.fy, c.model.matrix(0, 2), truth.cx,
              c.model.matrix(1, 2), truth.cy, c.model.distortion.at<double>(0), truth.k1, c.model.distortion.at<double>(1),
              truth.k2);
  std::size_t used = 0;
  for (const auto& v : c.views) {
    used += v.used;
    if (!v.used) std::printf("  view %zu left out: %s\n", v.view, v.note.c_str());
  }
  EXPECT_GE(used, 12u);
  EXPECT_LT(c.rms_px, 0.2);
  EXPECT_NEAR(c.model.matrix(0, 0) / truth.fx, 1.0, 0.003);
  EXPECT_NEAR(c.model.matrix(1, 1) / truth.fy, 1.0, 0.003);
  EXPECT_NEAR(c.model.matrix(0, 2), truth.cx, 3.0);
  EXPECT_NEAR(c.model.matrix(1, 2), truth.cy, 3.0);
  EXPECT_NEAR(c.model.distortion.at<double>(0), truth.k1, 0.02);
}

TEST(CameraCalibration, StereoBaselineAndHeadMountMatchTheTruth) {
  const PlateSession& s = plateSession();
  const registration::StereoCalibration st = registration::calibrateStereo(s.left, s.right, plateSpec());
  const sim::CellTruth& truth = s.summary.truth;
  const Eigen::Isometry3d true_right_from_left = truth.head_from_right.inverse() * truth.head_from_left;
  const double true_baseline = true_right_from_left.translation().norm();
  std::printf("stereo: %zu pairs, rms %.3f px, baseline %.3f mm (true %.3f)\n", st.pairs_used, st.rms_px, st.baseline_mm,
              true_baseline);
  EXPECT_NEAR(st.baseline_mm, true_baseline, 0.3);
  EXPECT_LT(Eigen::AngleAxisd(st.right_from_left.linear() * true_right_from_left.linear().transpose()).angle(), 2e-3);

  // Head to left camera, from the head poses the CMM reported and the plate poses the left camera saw.
  std::vector<Eigen::Isometry3d> heads, plates;
  for (std::size_t v = 0; v < s.left.size(); ++v)
    if (st.left.plate_poses[v]) {
      heads.push_back(s.heads[v]);
      plates.push_back(*st.left.plate_poses[v]);
    }
  const registration::HandEyeResult he = registration::calibrateHeadToCamera(heads, plates);
  const Eigen::Isometry3d error = he.head_from_camera * truth.head_from_left.inverse();
  std::printf("head to left camera: error %.3f mm, %.4f deg; plate spread %.3f mm, %.4f deg\n", error.translation().norm(),
              Eigen::AngleAxisd(error.linear()).angle() * 180 / M_PI, he.residual_mm, he.residual_deg);
  EXPECT_LT((he.head_from_camera.translation() - truth.head_from_left.translation()).norm(), 1.0);
  EXPECT_LT(Eigen::AngleAxisd(error.linear()).angle(), 2e-3);
  // The plate's centre (the symmetric dot grid may be numbered from either end).
  const sim::CirclePlate plate;
  const Eigen::Vector3d centre((plate.columns - 1) * plate.pitch / 2, (plate.rows - 1) * plate.pitch / 2, 0);
  EXPECT_LT((he.machine_from_plate * centre - truth.plate_poses[0] * centre).norm(), 0.5);
}

TEST(CameraCalibration, ViewsWithoutThePlateAreLeftOutWithAReason) {
  const PlateSession& s = plateSession();
  std::vector<cv::Mat> images(s.left.begin(), s.left.begin() + 7);
  images.push_back(cv::Mat(s.left[0].size(), CV_8U, cv::Scalar(30)));  // a dark frame
  const registration::CameraCalibration c = registration::calibrateCamera(images, plateSpec());
  EXPECT_FALSE(c.views.back().used);
  EXPECT_EQ(c.views.back().note, "plate not found");
  EXPECT_FALSE(c.plate_poses.back().has_value());
  const std::vector<cv::Mat> too_few(s.left.begin(), s.left.begin() + 3);
  try {
    registration::calibrateCamera(too_few, plateSpec());
    ADD_FAILURE() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("found in 3 of 3 views"), std::string::npos) << e.what();
  }
}

// A scan keeps each view's dots and lets its images go: the dots, found one view at a time, give the
// very calibration the images give, and a view that is empty or of another size says so.
TEST(CameraCalibration, TheDotsFoundViewByViewCalibrateAsTheImagesDo) {
  const PlateSession& s = plateSession();
  const registration::StereoCalibration from_images = registration::calibrateStereo(s.left, s.right, plateSpec());
  std::vector<registration::PlateView> left, right;
  for (std::size_t v = 0; v < s.left.size(); ++v) {
    left.push_back(registration::findPlate(s.left[v], plateSpec()));
    right.push_back(registration::findPlate(s.right[v], plateSpec()));
    EXPECT_EQ(left.back().image_size, s.left[v].size());
  }
  const registration::StereoCalibration from_dots = registration::calibrateStereo(left, right, plateSpec());
  EXPECT_EQ(from_dots.pairs_used, from_images.pairs_used);
  EXPECT_EQ(from_dots.baseline_mm, from_images.baseline_mm);
  EXPECT_EQ(from_dots.left.rms_px, from_images.left.rms_px);
  EXPECT_TRUE(from_dots.right_from_left.isApprox(from_images.right_from_left, 0));

  left.push_back(registration::findPlate(cv::Mat(), plateSpec()));
  cv::Mat half;
  cv::resize(s.left[0], half, cv::Size(), 0.5, 0.5);
  left.push_back(registration::findPlate(half, plateSpec()));
  const registration::CameraCalibration c = registration::calibrateCamera(left, plateSpec());
  EXPECT_EQ(c.views[s.left.size()].note, "empty image");
  EXPECT_EQ(c.views[s.left.size() + 1].note, "image size differs from the first view");
  EXPECT_FALSE(c.views.back().used);
}

// The stereo pair verified on the plate's dots: calibrated on ten of the views, checked on the
// other four, the dots lie on a plane and keep their certified distances; a baseline 0.1 % off
// (0.12 mm) stretches the 60 mm diagonal by about 0.06 mm, beyond the 0.05 mm MPE.
TEST(StereoVerification, ThePlatesDotsKeepTheirFormAndLengthsUnlessTheBaselineIsOff) {
  const PlateSession& s = plateSession();
  const std::vector<cv::Mat> cal_left(s.left.begin(), s.left.begin() + 10), cal_right(s.right.begin(), s.right.begin() + 10);
  const std::vector<cv::Mat> check_left(s.left.begin() + 10, s.left.end()), check_right(s.right.begin() + 10, s.right.end());
  registration::StereoCalibration stereo = registration::calibrateStereo(cal_left, cal_right, plateSpec());
  const registration::StereoPlateCheck good = registration::verifyStereoOnPlate(check_left, check_right, stereo, plateSpec());
  std::printf("stereo on the plate: %zu views, flat form %.4f mm, length error %+.4f mm (RMS %.4f) up to %.1f mm\n",
              good.views, good.form_error_mm, good.length_error_mm, good.rms_length_error_mm, good.longest_length_mm);
  EXPECT_GE(good.views, 3u);
  EXPECT_EQ(good.dots, good.views * 63);
  EXPECT_NEAR(good.longest_length_mm, std::hypot(8 * 6.0, 6 * 6.0), 1e-9);
  EXPECT_TRUE(good.passed());  // within the 0.05 mm MPEs, at this session's half resolution
  EXPECT_LT(std::abs(good.length_error_mm), 0.02);

  stereo.right_from_left.translation() *= 1.001;
  const registration::StereoPlateCheck stretched =
      registration::verifyStereoOnPlate(check_left, check_right, stereo, plateSpec());
  std::printf("baseline 0.1 %% long: length error %+.4f mm\n", stretched.length_error_mm);
  EXPECT_FALSE(stretched.length_passed);
  EXPECT_GT(stretched.length_error_mm, 0.05);

  EXPECT_THROW(registration::verifyStereoOnPlate({cv::Mat::zeros(100, 100, CV_8U)}, {cv::Mat::zeros(100, 100, CV_8U)},
                                                 stereo, plateSpec()),
               std::runtime_error);
}

}  // namespace
