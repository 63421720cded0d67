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

#include "stampscan/registration/calibration_store.hpp"
#include "stampscan/registration/camera_calibration.hpp"
#include "stampscan/registration/digitizer_calibration.hpp"
#include "stampscan/registration/element_merge.hpp"
#include "stampscan/registration/grid_element.hpp"
#include "stampscan/registration/laser_rings.hpp"
#include "stampscan/registration/scan_trace.hpp"
#include "stampscan/registration/stereo_rings.hpp"
#include "stampscan/registration/stereo_squares.hpp"

#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace stampscan::registration {

struct MeasureParams {
  // Used when the trace has no reference-sphere sweeps (its clock offset is taken from the trace).
  std::optional<DigitizerCalibration> digitizer;
  // Used when the trace has too few plate views: the cameras' stored calibration (intrinsics, the
  // pair's extrinsics, the left camera's mount on the head); their clock offset is the trace's.
  std::optional<CameraCalibrationFile> cameras;
  // Also measure the stereo views (needs plate views in the trace, or the stored calibration above).
  bool with_stereo = false;
  // Fewer plate views than this and the cameras are not calibrated from the trace.
  std::size_t min_plate_views = 5;
  // Profiles taken where the head track may be further than this from the true path are left out
  // (HeadTrack::chordError): a tenth of the goal for positions.
  double max_track_error_mm = 0.005;
  // Also keep every laser return of the part sweeps in the machine frame (ScanMeasurement::
  // surface_points): the dense shape a fit can take the part's surface from. 24 bytes a point.
  bool keep_surface_points = false;
};

// The profiles of each sweep of a sphere scene (the reference sphere's, or the ball bar's second
// sphere's) in the trace's order: those exposed (device time - clock offset - latency) within the
// sweep where the head track is to be trusted (HeadTrack::chordError <= max_track_error_mm).
std::vector<std::vector<Profile>> sphereSweepProfiles(const ScanTrace& trace, const HeadTrack& track,
                                                      std::int64_t clock_offset_ns, std::int64_t latency_ns,
                                                      double max_track_error_mm,
                                                      trace::Scene scene = trace::Scene::ReferenceSphere);

// The cameras calibrated on a trace's plate views: each camera and the pair (calibrateStereo) and,
// when the head track covers at least three views, the left camera's mount on the head (hand-eye,
// from the head poses at the views' exposures, timed by the cameras' clock pairs).
struct CameraRigCalibration {
  StereoCalibration stereo;
  std::optional<HandEyeResult> head_from_left;
  std::int64_t camera_offset_ns = 0;  // the left camera's clock minus the station's
  // The head pose and the left camera's plate pose of each view the hand-eye used.
  std::vector<Eigen::Isometry3d> machine_from_head, camera_from_plate;
};
// A view of the plate as calibration needs it: the dots each camera found, and when the left camera
// took it (its clock).
struct PlateViewPair {
  std::int64_t left_time_ns = 0;
  PlateView left, right;
};
// The dots of the trace's plate views plate_left[0..n) / plate_right[0..n) with n the fewer of the
// two (the views of a scan whose second image is not in yet are left); nothing without a plate
// description.
std::vector<PlateViewPair> findPlateViews(const ScanTrace& trace);
// Nothing when there are fewer plate views than `min_plate_views` or the trace has no plate
// description; throws std::runtime_error when the views do not calibrate (too few show the plate).
// The trace gives the plate, the head track and the clock pairs.
std::optional<CameraRigCalibration> calibrateCameraRig(const std::vector<PlateViewPair>& views, const ScanTrace& trace,
                                                       std::size_t min_plate_views);
// The same on the trace's own plate views.
std::optional<CameraRigCalibration> calibrateCameraRig(const ScanTrace& trace, std::size_t min_plate_views);

// What happened, stage by stage, for the operator; `stage` is a short word ("digitizer", "laser",
// "stereo", "cameras"), `text` one line.
class MeasureObserver {
 public:
  virtual ~MeasureObserver() = default;
  virtual void stageDone(std::string_view stage, const std::string& text) = 0;
  // The grid elements one part sweep (stage "laser") or one stereo view ("stereo") has just added,
  // machine frame, so that a live view can show the cloud grow. Called from the measuring thread.
  virtual void elementsMeasured(std::string_view /*stage*/, const std::vector<GridElement>& /*elements*/) {}
};

struct ScanMeasurement {
  std::vector<GridElement> elements;  // every measurement: the laser's, then the stereo views'
  // One element per printed element, the measurements of each merged (element_merge.hpp): what the
  // strain field over the surface is fitted to.
  MergedElements merged;
  // Every return of the part sweeps, machine frame, one list per sweep in their order
  // (MeasureParams::keep_surface_points): each sweep is fitted as a piece of the surface.
  std::vector<std::vector<Vec3>> surface_points;

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

// The measuring workflow stage by stage, so that a scan being recorded is measured as it goes: each
// stage runs as soon as its data is complete (the digitizer's calibration after the sphere sweeps,
// each part sweep after it ends, ...), and the Cloud4D is ready soon after the last sweep.
// measureScan() runs the same stages on a whole trace. Each stage reads what it needs from the
// trace it is given, which may be the whole trace or the part of it that stage needs (the head
// track, the clock pairs, the sweep's profiles or the view's frames). Not thread-safe; the stages
// run one at a time (a sweep's rings are found on TBB's threads).
class PointToPlaneIcp;

class ScanMeasurer {
 public:
  explicit ScanMeasurer(MeasureParams params = {}, MeasureObserver* observer = nullptr);
  ~ScanMeasurer();
  ScanMeasurer(const ScanMeasurer&) = delete;
  ScanMeasurer& operator=(const ScanMeasurer&) = delete;

  // From the trace's sphere sweeps, or the stored calibration of the params. Throws
  // std::runtime_error when there is neither, or no session description, or no clock pairs.
  void calibrateDigitizer(const ScanTrace& trace);
  // The plate's dots in the trace's plate views whose two images are in (findPlateViews), kept for
  // calibrateCameras: a scan calls it as the views arrive and then lets their images go. Returns how
  // many views it took, the first ones of the trace's lists; the caller removes them from its lists.
  std::size_t findPlateDots(const ScanTrace& trace);
  // From the plate views findPlateDots took and the trace's own, when there are enough of them;
  // otherwise from the stored calibration of the params once the trace has the cameras' clock
  // pairs; otherwise the cameras stay uncalibrated and the stereo views cannot be measured.
  void calibrateCameras(const ScanTrace& trace);
  // The grid elements of one part sweep (after calibrateDigitizer).
  void measureSweep(const ScanTrace& trace, const SweepWindow& sweep, std::uint32_t sweep_id);
  // Every part sweep of the trace, in parallel.
  void measureSweeps(const ScanTrace& trace);
  // The stereo view part_left[view] / part_right[view] of the trace searched for the grid's elements
  // (after calibrateCameras): the bulk of a view's work, which needs neither the laser nor the head's
  // pose, so a scan runs it as the frames arrive and the images can go. The view then waits for
  // measureDetectedView.
  void detectView(const ScanTrace& trace, std::size_t view, std::uint32_t view_id);
  // The first view detectView left waiting, matched on the laser's surface and registered to its
  // elements (after every part sweep). False (and nothing done) when none waits or the trace's head
  // track does not reach its time yet.
  bool measureDetectedView(const ScanTrace& trace);

  bool digitizerCalibrated() const { return digitizer_ready_; }
  const DigitizerCalibration& digitizer() const { return out_.digitizer; }
  bool camerasCalibrated() const { return out_.rig.has_value(); }
  // The returns of the part sweeps measured since the last call (MeasureParams::keep_surface_points),
  // one list per sweep, handed over: a scan fits each sweep's as it comes; finish() then has only
  // later ones.
  std::vector<std::vector<Vec3>> takeSurfacePoints() { return std::exchange(surface_points_, {}); }
  // The laser's elements, then the views'. Throws std::runtime_error when no element was found.
  ScanMeasurement finish();

 private:
  void tell(std::string_view stage, const std::string& text);

  MeasureParams params_;
  MeasureObserver* observer_;
  ScanMeasurement out_;
  bool digitizer_ready_ = false;
  std::string grid_ = "circle";
  RingDetectionParams rings_;
  SquareDetectionParams squares_;
  std::int64_t camera_offset_ = 0;
  std::vector<PlateViewPair> plate_views_;  // findPlateDots's
  std::vector<GridElement> laser_, stereo_;
  // A detected view waiting for its matching: its elements in both images, or, for a pair without a
  // working distance, the images themselves.
  struct PendingView {
    std::int64_t time_ns = 0;  // on the head track's clock
    std::uint32_t id = 0;
    std::optional<StereoRingImages> rings;
    std::optional<StereoCellImages> cells;
    cv::Mat left, right;
  };
  // A view's images searched for elements of the size they have at `depth` (stage 1).
  void searchView(PendingView& pending, const cv::Mat& left, const cv::Mat& right, double depth) const;
  std::deque<PendingView> pending_views_;
  std::vector<std::vector<Vec3>> surface_points_;  // per part sweep
  // A sparse sample of the laser's returns (about one per square millimetre per sweep): the depth
  // prior of the stereo matching, with the elements. On a steep wall, where the laser finds few
  // elements, the depth then comes from the sheet there, not from a plane through the elements
  // around.
  std::vector<Vec3> depth_prior_;
  // The views are registered on the laser's elements, one point per grid element (the ICP keeps a
  // reference to its target: it lives here, as long as the ICP).
  std::vector<Vec3> icp_target_;
  std::unique_ptr<PointToPlaneIcp> icp_;  // made at the first view
  double laser_seconds_ = 0, stereo_seconds_ = 0;
};

// The stages above on a whole trace. Throws std::runtime_error naming what is missing: no session
// description, no clock pairs for the digitizer, no sphere sweeps and no stored calibration, no
// grid element found, stereo asked for without plate views.
ScanMeasurement measureScan(const ScanTrace& trace, const MeasureParams& params = {}, MeasureObserver* observer = nullptr);

}  // namespace stampscan::registration
