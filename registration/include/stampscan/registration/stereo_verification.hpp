// Verification of the stereo pair on the calibration plate. A passive stereo pair measures marks,
// not surfaces, so the sphere of ISO 10360-8's probing errors shows it nothing; the plate's dots are
// marks at certified positions on a flat artefact, and give the two checks that standard and
// VDI/VDE 2634 part 1 make of optical systems on such artefacts:
//
//   flat form error  F[Form.Pla]  the dots triangulated from a pair of views (both cameras, the
//                                 calibration in use), the range of their signed distances from the
//                                 least-squares plane; the worst view counts
//   length error     E            every distance between two triangulated dots minus the certified
//                                 one (the pitch times their grid offset); the largest in size counts
//
// The views should be new images, not those the cameras were calibrated on: the check is of the
// calibration (`station verify` takes them afresh; on the virtual cell from the built-in plan's first
// plate poses, with new sensor noise).
// Thread safety: pure functions of their arguments.
#pragma once

#include "stampscan/registration/camera_calibration.hpp"

#include <opencv2/core.hpp>

#include <cstddef>
#include <vector>

namespace stampscan::registration {

struct StereoPlateParams {
  double form_mpe_mm = 0.050;    // MPE of the flat form error
  double length_mpe_mm = 0.050;  // MPE of the length error
};

struct StereoPlateCheck {
  std::size_t views = 0;            // pairs in which both cameras found the plate
  std::size_t dots = 0;             // dots triangulated, over those views
  double form_error_mm = 0;         // F[Form.Pla], the worst view's
  double length_error_mm = 0;       // E, the largest in size (signed)
  double longest_length_mm = 0;     // the longest certified length checked (the plate's diagonal)
  double rms_length_error_mm = 0;   // over every pair of dots of every view
  bool form_passed = false, length_passed = false;
  bool passed() const { return form_passed && length_passed; }
};

// The dots of one view pair in the left camera's frame (mm), in plateModel() order; empty when
// either camera does not find the plate.
std::vector<cv::Point3d> triangulatePlate(const cv::Mat& left, const cv::Mat& right, const StereoCalibration& stereo,
                                          const CirclePlateSpec& plate);

// Throws std::runtime_error when no pair shows the plate in both cameras.
StereoPlateCheck verifyStereoOnPlate(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                                     const StereoCalibration& stereo, const CirclePlateSpec& plate,
                                     const StereoPlateParams& params = {});

}  // namespace stampscan::registration
