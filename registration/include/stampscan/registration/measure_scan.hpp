// The measuring workflow on a decoded scan trace: calibrate from the trace's calibration scenes
// (reference-sphere sweeps for the digitizer, plate views for the cameras) or take a stored
// calibration, place every laser profile in the machine frame, find the printed grid elements in
// each sweep's intensity, and (optionally) measure the stereo views and register them to the
// laser's elements. `station process`, `station scan` and the reports all call this; none of them
// measures on its own.
//
// Thread safety: measureScan() is reentrant; it runs the sweeps in parallel (TBB). The observer is
// called from the calling thread only.
#pragma once

#include "stampscan/registration/camera_calibration.hpp"
#include "stampscan/registration/digitizer_calibration.hpp"
#include "stampscan/registration/grid_element.hpp"
#include "stampscan/registration/laser_rings.hpp"
#include "stampscan/registration/scan_trace.hpp"
#include "stampscan/registration/stereo_rings.hpp"

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::registration {

struct MeasureParams {
  // Used when the trace has no reference-sphere sweeps (its clock offset is taken from the trace).
  std::optional<DigitizerCalibration> digitizer;
  // Also measure the stereo views (needs plate views in the trace to calibrate the cameras).
  bool with_stereo = false;
  // Fewer plate views than this and the cameras are not calibrated from the trace.
  std::size_t min_plate_views = 5;
  // Profiles taken where the head track may be further than this from the true path are left out
  // (HeadTrack::chordError): a tenth of the goal for positions.
  double max_track_error_mm = 0.005;
};

// What happened, stage by stage, for the operator; `stage` is a short word ("digitizer", "laser",
// "stereo", "cameras"), `text` one line.
class MeasureObserver {
 public:
  virtual ~MeasureObserver() = default;
  virtual void stageDone(std::string_view stage, const std::string& text) = 0;
};

struct ScanMeasurement {
  std::vector<GridElement> elements;  // the laser's, then the stereo views'

  DigitizerCalibration digitizer;                       // as used (clock offset from the trace)
  std::optional<SphereCalibrationResult> sphere;        // when calibrated from the trace's sphere sweeps
  std::optional<StereoCalibration> stereo;              // when calibrated from the trace's plate views
  std::optional<HandEyeResult> head_from_left;          // the rig's mount, when the head track covers the views
  std::optional<StereoRig> rig;

  std::size_t laser_sweeps = 0, laser_elements = 0;
  RingDetectionStats laser_stats;  // summed over the sweeps
  std::size_t stereo_views = 0, stereo_elements = 0;
  double worst_icp_correction_mm = 0;
  std::string stereo_note;  // why the stereo path found nothing, when it can tell
};

// Throws std::runtime_error naming what is missing: no session description, no clock pairs for the
// digitizer, no sphere sweeps and no stored calibration, no grid element found, stereo asked for
// without plate views.
ScanMeasurement measureScan(const ScanTrace& trace, const MeasureParams& params = {}, MeasureObserver* observer = nullptr);

// Rigid transforms between the trace's record and Eigen.
Eigen::Isometry3d toIsometry(const trace::RigidPose& pose);
trace::RigidPose toRigidPose(const Eigen::Isometry3d& pose);

}  // namespace stampscan::registration
