#include "stampscan/registration/measure_scan.hpp"

#include "stampscan/acquisition/trace/rigid_pose.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/registration/icp.hpp"
#include "stampscan/registration/stereo_squares.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iterator>
#include <limits>
#include <stdexcept>

namespace stampscan::registration {

namespace {

class StageClock {
 public:
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - last_).count();
    last_ = now;
    return s;
  }

 private:
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

std::string format(const char* fmt, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

// The profiles whose exposure falls within the sweep's window, where the head track is to be
// trusted (HeadTrack::chordError): where the head started or stopped between two sparse position
// reports, the track is off by up to a tenth of a millimetre and rings there come out squashed.
std::vector<Profile> profilesIn(const ScanTrace& t, const HeadTrack& track, const SweepWindow& w, std::int64_t clock_offset,
                                std::int64_t latency, double max_chord_error) {
  std::vector<Profile> out;
  for (const auto& p : t.profiles) {
    const std::int64_t exposure = p.device_time_ns - clock_offset - latency;
    if (exposure >= w.begin_ns && exposure <= w.end_ns && track.covers(exposure) &&
        track.chordError(exposure) <= max_chord_error)
      out.push_back(p);
  }
  return out;
}

// The sweep's returns in the machine frame (the profiles outside the head track are left out, as
// the measurement leaves them out).
std::vector<Vec3> surfacePointsOf(const std::vector<Profile>& profiles, const HeadTrack& track,
                                  const DigitizerCalibration& calibration) {
  std::vector<Vec3> points;
  for (const Profile& p : profiles) profileToMachine(p, track, calibration, points);
  return points;
}

// Every kPriorPointStride-th return of every kPriorProfileStride-th profile: about 0.7 mm across the
// fan by 1 mm along a sweep at the usual speed.
constexpr std::size_t kPriorProfileStride = 20, kPriorPointStride = 16;
std::vector<Vec3> depthPriorOf(const std::vector<Profile>& profiles, const HeadTrack& track,
                               const DigitizerCalibration& calibration) {
  std::vector<Vec3> points;
  for (std::size_t r = 0; r < profiles.size(); r += kPriorProfileStride) {
    const Profile& p = profiles[r];
    const std::int64_t t = calibration.exposureTime(p);
    if (!track.covers(t)) continue;
    const Eigen::Isometry3d machine_from_sensor = track.poseAt(t) * calibration.head_from_digitizer;
    // Saturated returns (glare) may be misplaced: left out, as the elements' raster leaves them out.
    for (std::size_t i = 0; i < p.range.size(); i += kPriorPointStride)
      if (p.range[i] > 0 && !(i < p.intensity.size() && p.intensity[i] == 65535))
        points.push_back(machine_from_sensor * sensorPoint(p, i));
  }
  return points;
}

}  // namespace

std::vector<std::vector<Profile>> sphereSweepProfiles(const ScanTrace& trace, const HeadTrack& track,
                                                      std::int64_t clock_offset_ns, std::int64_t latency_ns,
                                                      double max_track_error_mm, trace::Scene scene) {
  std::vector<std::vector<Profile>> out;
  for (const auto& w : trace.sweeps)
    if (w.is(scene)) out.push_back(profilesIn(trace, track, w, clock_offset_ns, latency_ns, max_track_error_mm));
  return out;
}

ScanMeasurer::ScanMeasurer(MeasureParams params, MeasureObserver* observer) : params_(params), observer_(observer) {}

ScanMeasurer::~ScanMeasurer() = default;

void ScanMeasurer::tell(std::string_view stage, const std::string& text) {
  if (observer_) observer_->stageDone(stage, text);
}

void ScanMeasurer::calibrateDigitizer(const ScanTrace& trace) {
  if (!trace.session) throw std::runtime_error("the trace has no session description (metadata 'cell')");
  const trace::SessionDescription& session = *trace.session;
  grid_ = session.grid;
  rings_.printed_radius = 0.5 * session.grid_circle_diameter_mm;
  squares_.pitch = session.grid_pitch_mm;
  rings_.line_width = squares_.line_width = session.grid_line_width_mm;
  const auto pairs = trace.clock_pairs.find("digitizer");
  if (pairs == trace.clock_pairs.end()) throw std::runtime_error("the trace has no clock-sync pairs for the digitizer");
  const std::int64_t digitizer_offset = clockOffset(pairs->second);
  const HeadTrack track(trace.head);
  StageClock clock;
  std::vector<Profile> sphere;
  for (auto& sweep : sphereSweepProfiles(trace, track, digitizer_offset, 0, params_.max_track_error_mm))
    sphere.insert(sphere.end(), sweep.begin(), sweep.end());
  if (!sphere.empty()) {
    if (!session.reference_sphere_radius_mm)
      throw std::runtime_error("the trace has reference-sphere sweeps but its session description gives no sphere radius");
    SphereCalibrationParams sp;
    sp.sphere_radius = *session.reference_sphere_radius_mm;
    sp.nominal.head_from_digitizer = trace::toIsometry(session.head_from_digitizer_nominal);
    sp.nominal.clock_offset_ns = digitizer_offset;
    out_.sphere = ::stampscan::registration::calibrateDigitizer(sphere, track, sp);
    out_.digitizer = out_.sphere->calibration;
    tell("digitizer",
         format("calibrated on the reference sphere: latency %.3f ms, residual %.4f mm RMS over %zu points (%.2f s)",
                static_cast<double>(out_.digitizer.latency_ns) * 1e-6, out_.sphere->rms_mm, out_.sphere->inliers, clock.lap()));
  } else {
    if (!params_.digitizer)
      throw std::runtime_error("the trace has no reference-sphere sweeps to calibrate the digitizer, and no stored "
                               "calibration was given");
    out_.digitizer = *params_.digitizer;
    tell("digitizer", "the stored calibration (the trace has no reference-sphere sweeps)");
  }
  out_.digitizer.clock_offset_ns = digitizer_offset;
  digitizer_ready_ = true;
}

namespace {

std::optional<CirclePlateSpec> plateOf(const ScanTrace& trace) {
  if (!trace.session || !trace.session->plate) return std::nullopt;
  const trace::PlateRecord& plate = *trace.session->plate;
  return CirclePlateSpec{plate.columns, plate.rows, plate.pitch_mm};
}

}  // namespace

std::vector<PlateViewPair> findPlateViews(const ScanTrace& trace) {
  const std::optional<CirclePlateSpec> spec = plateOf(trace);
  if (!spec) return {};
  std::vector<PlateViewPair> views(std::min(trace.plate_left.size(), trace.plate_right.size()));
  // Each image on its own: twelve views' plates are found in a second on two cores.
  tbb::parallel_for(std::size_t{0}, 2 * views.size(), [&](std::size_t k) {
    const std::size_t v = k / 2;
    if (k % 2 == 0) {
      views[v].left_time_ns = trace.plate_left[v].device_time_ns;
      views[v].left = findPlate(trace.plate_left[v].image, *spec);
    } else {
      views[v].right = findPlate(trace.plate_right[v].image, *spec);
    }
  });
  return views;
}

std::optional<CameraRigCalibration> calibrateCameraRig(const ScanTrace& trace, std::size_t min_plate_views) {
  if (trace.plate_left.size() < min_plate_views) return std::nullopt;
  return calibrateCameraRig(findPlateViews(trace), trace, min_plate_views);
}

std::optional<CameraRigCalibration> calibrateCameraRig(const std::vector<PlateViewPair>& views, const ScanTrace& trace,
                                                       std::size_t min_plate_views) {
  const std::optional<CirclePlateSpec> spec = plateOf(trace);
  if (views.size() < min_plate_views || !spec) return std::nullopt;
  std::vector<PlateView> left, right;
  for (const PlateViewPair& view : views) {
    left.push_back(view.left);
    right.push_back(view.right);
  }
  CameraRigCalibration rig;
  rig.stereo = calibrateStereo(left, right, *spec);
  const auto camera_pairs = trace.clock_pairs.find("camera_left");
  if (camera_pairs == trace.clock_pairs.end() || trace.head.size() < 2) return rig;
  rig.camera_offset_ns = clockOffset(camera_pairs->second);
  const HeadTrack track(trace.head);
  for (std::size_t v = 0; v < views.size(); ++v) {
    const std::int64_t t = views[v].left_time_ns - rig.camera_offset_ns;
    if (rig.stereo.left.plate_poses[v] && track.covers(t)) {
      rig.machine_from_head.push_back(track.poseAt(t));
      rig.camera_from_plate.push_back(*rig.stereo.left.plate_poses[v]);
    }
  }
  if (rig.machine_from_head.size() >= 3) rig.head_from_left = calibrateHeadToCamera(rig.machine_from_head, rig.camera_from_plate);
  return rig;
}

std::size_t ScanMeasurer::findPlateDots(const ScanTrace& trace) {
  std::vector<PlateViewPair> found = findPlateViews(trace);
  std::move(found.begin(), found.end(), std::back_inserter(plate_views_));
  return found.size();
}

void ScanMeasurer::calibrateCameras(const ScanTrace& trace) {
  std::vector<PlateViewPair> views = plate_views_;
  std::vector<PlateViewPair> in_trace = findPlateViews(trace);
  std::move(in_trace.begin(), in_trace.end(), std::back_inserter(views));
  if (views.size() < params_.min_plate_views && params_.cameras) {
    const auto camera_pairs = trace.clock_pairs.find("camera_left");
    if (camera_pairs == trace.clock_pairs.end() || camera_pairs->second.empty()) return;
    const CameraCalibrationFile& stored = *params_.cameras;
    camera_offset_ = clockOffset(camera_pairs->second);
    out_.stereo = stored.stereo;
    out_.head_from_left = stored.head_from_left;
    out_.rig = StereoRig{stored.stereo.left.model, stored.stereo.right.model, stored.head_from_left.head_from_camera,
                         stored.stereo.right_from_left};
    tell("cameras", format("the stored calibration (created %s): baseline %.3f mm", stored.created.c_str(),
                           stored.stereo.baseline_mm));
    return;
  }
  StageClock clock;
  const std::optional<CameraRigCalibration> rig = calibrateCameraRig(views, trace, params_.min_plate_views);
  if (!rig) return;
  out_.stereo = rig->stereo;
  const StereoCalibration& stereo = *out_.stereo;
  std::string text = format("calibrated on %zu plate views: reprojection %.3f / %.3f px, baseline %.3f mm",
                            stereo.pairs_used, stereo.left.rms_px, stereo.right.rms_px, stereo.baseline_mm);
  if (rig->head_from_left) {
    camera_offset_ = rig->camera_offset_ns;
    out_.head_from_left = rig->head_from_left;
    text += format(", head mount residual %.3f mm", out_.head_from_left->residual_mm);
    out_.rig = StereoRig{stereo.left.model, stereo.right.model, out_.head_from_left->head_from_camera, stereo.right_from_left};
  }
  tell("cameras", text + format(" (%.2f s)", clock.lap()));
}

void ScanMeasurer::measureSweep(const ScanTrace& trace, const SweepWindow& sweep, std::uint32_t sweep_id) {
  if (!digitizer_ready_) throw std::logic_error("ScanMeasurer: measureSweep before calibrateDigitizer");
  StageClock clock;
  const HeadTrack track(trace.head);
  const auto profiles = profilesIn(trace, track, sweep, out_.digitizer.clock_offset_ns, out_.digitizer.latency_ns,
                                   params_.max_track_error_mm);
  RingDetectionStats stats;
  const std::vector<GridElement> found =
      grid_ == "circle" ? detectLaserRings(profiles, track, out_.digitizer, rings_, sweep_id, &stats)
                        : detectLaserSquares(profiles, track, out_.digitizer, squares_, sweep_id, &stats);
  laser_.insert(laser_.end(), found.begin(), found.end());
  if (params_.with_stereo) {
    const std::vector<Vec3> prior = depthPriorOf(profiles, track, out_.digitizer);
    depth_prior_.insert(depth_prior_.end(), prior.begin(), prior.end());
  }
  if (params_.keep_surface_points) {
    std::vector<Vec3> returns = surfacePointsOf(profiles, track, out_.digitizer);
    if (!returns.empty()) surface_points_.push_back(std::move(returns));
  }
  if (observer_) observer_->elementsMeasured("laser", found);
  out_.laser_stats.candidates += stats.candidates;
  out_.laser_stats.rejected_size += stats.rejected_size;
  out_.laser_stats.rejected_gap += stats.rejected_gap;
  out_.laser_stats.rejected_fit += stats.rejected_fit;
  out_.laser_stats.found += stats.found;
  ++out_.laser_sweeps;
  laser_seconds_ += clock.lap();
}

void ScanMeasurer::measureSweeps(const ScanTrace& trace) {
  if (!digitizer_ready_) throw std::logic_error("ScanMeasurer: measureSweeps before calibrateDigitizer");
  StageClock clock;
  std::vector<SweepWindow> part;
  for (const auto& w : trace.sweeps)
    if (w.is(trace::Scene::Part)) part.push_back(w);
  const HeadTrack track(trace.head);
  std::vector<std::vector<GridElement>> per_sweep(part.size());
  std::vector<RingDetectionStats> stats(part.size());
  std::vector<std::vector<Vec3>> returns(part.size()), priors(part.size());
  tbb::parallel_for(std::size_t{0}, part.size(), [&](std::size_t k) {
    const auto profiles = profilesIn(trace, track, part[k], out_.digitizer.clock_offset_ns, out_.digitizer.latency_ns,
                                     params_.max_track_error_mm);
    const auto id = static_cast<std::uint32_t>(k);
    per_sweep[k] = grid_ == "circle" ? detectLaserRings(profiles, track, out_.digitizer, rings_, id, &stats[k])
                                     : detectLaserSquares(profiles, track, out_.digitizer, squares_, id, &stats[k]);
    if (params_.keep_surface_points) returns[k] = surfacePointsOf(profiles, track, out_.digitizer);
    if (params_.with_stereo) priors[k] = depthPriorOf(profiles, track, out_.digitizer);
  });
  for (std::size_t k = 0; k < part.size(); ++k) {
    depth_prior_.insert(depth_prior_.end(), priors[k].begin(), priors[k].end());
    if (!returns[k].empty()) surface_points_.push_back(std::move(returns[k]));
    laser_.insert(laser_.end(), per_sweep[k].begin(), per_sweep[k].end());
    if (observer_) observer_->elementsMeasured("laser", per_sweep[k]);
    out_.laser_stats.candidates += stats[k].candidates;
    out_.laser_stats.rejected_size += stats[k].rejected_size;
    out_.laser_stats.rejected_gap += stats[k].rejected_gap;
    out_.laser_stats.rejected_fit += stats[k].rejected_fit;
    out_.laser_stats.found += stats[k].found;
  }
  out_.laser_sweeps += part.size();
  laser_seconds_ += clock.lap();
}

void ScanMeasurer::detectView(const ScanTrace& trace, std::size_t v, std::uint32_t view_id) {
  if (!out_.rig) throw std::runtime_error("the stereo views need the cameras calibrated: the trace has no plate views");
  StageClock clock;
  PendingView pending;
  pending.time_ns = trace.part_left[v].device_time_ns - camera_offset_;
  pending.id = view_id;
  // The elements' size in pixels at the pair's working distance, where the views are aimed: from
  // the calibration alone, so the images are searched as they come, before the laser has measured
  // the part (the search allows for a wide range of sizes). A pair without vergence has no working
  // distance of its own: its images wait for the laser's depth.
  if (const std::optional<double> depth = workingDistance(*out_.rig)) {
    searchView(pending, trace.part_left[v].image, trace.part_right[v].image, *depth);
  } else {
    pending.left = trace.part_left[v].image;
    pending.right = trace.part_right[v].image;
  }
  pending_views_.push_back(std::move(pending));
  stereo_seconds_ += clock.lap();
}

void ScanMeasurer::searchView(PendingView& pending, const cv::Mat& left, const cv::Mat& right, double depth) const {
  if (grid_ == "circle")
    pending.rings = detectStereoRings(left, right, pixelsAtDepth(*out_.rig, rings_.printed_radius, depth), rings_);
  else
    pending.cells = detectStereoCells(left, right, pixelsAtDepth(*out_.rig, squares_.pitch, depth), squares_);
}

bool ScanMeasurer::measureDetectedView(const ScanTrace& trace) {
  if (pending_views_.empty() || trace.head.size() < 2) return false;
  PendingView& pending = pending_views_.front();
  const HeadTrack track(trace.head);
  const std::int64_t t = pending.time_ns;
  const std::uint32_t view_id = pending.id;
  if (!track.covers(t)) return false;
  StageClock clock;
  ++out_.stereo_views;
  std::vector<Vec3> laser_positions, laser_normals;
  for (const auto& g : laser_) {
    laser_positions.push_back(g.position);
    laser_normals.push_back(g.normal);
  }
  if (!icp_) {
    // One target point per grid element: the laser's overlapping strips find most elements twice, a
    // few micrometres apart, and the ICP's test for pairs beyond the target's edge counts in the
    // target's typical spacing (the nearest other point): with twins, a few micrometres, and every
    // pair of a view lying a few hundredths of a millimetre to the side was dropped (so was the view's
    // registration, now and then).
    std::vector<Vec3> normals;
    const fitting::KdTree all(laser_positions);
    std::vector<char> taken(laser_positions.size(), 0);
    std::vector<fitting::Neighbor> near;
    const double twin = 0.25 * (grid_ == "circle" ? rings_.printed_radius * 2 : squares_.pitch);
    for (std::size_t i = 0; i < laser_positions.size(); ++i) {
      if (taken[i]) continue;
      all.radius(laser_positions[i], twin, near);
      for (const fitting::Neighbor& n : near) taken[n.index] = 1;
      icp_target_.push_back(laser_positions[i]);
      normals.push_back(laser_normals[i]);
    }
    icp_ = std::make_unique<PointToPlaneIcp>(icp_target_, std::move(normals));
  }
  const StereoRig& rig = *out_.rig;
  std::vector<Vec3> prior = laser_positions;
  prior.insert(prior.end(), depth_prior_.begin(), depth_prior_.end());
  const StereoViewPose pose{.rig = rig, .machine_from_head = track.poseAt(t), .prior = prior, .index = view_id};
  // A pair without a working distance kept its images: searched now, at the laser's depth.
  if (!pending.left.empty()) {
    if (const double depth = priorDepth(pose); depth > 0) searchView(pending, pending.left, pending.right, depth);
    pending.left.release();
    pending.right.release();
  }
  std::vector<GridElement> view;
  if (pending.rings) view = measureStereoPair(*pending.rings, pose, rings_);
  else if (pending.cells) view = measureStereoSquares(*pending.cells, pose, squares_);
  pending_views_.pop_front();
  if (view.size() >= 10) {
    std::vector<Vec3> source;
    for (const auto& g : view) source.push_back(g.position);
    IcpParams ip;
    ip.max_correspondence_distance = 1.0;
    // Stereo and laser measure the same grid elements: each pairs with its own, so the offset
    // along the sheet counts as much as across it. Point-to-plane alone let errors across the
    // sheet on the radii slide a view sideways along the walls (0.064 mm position RMS on a full
    // square-grid pan session, 0.039 with this).
    ip.tangential_weight = 1.0;
    const IcpResult fit = icp_->align(source, Eigen::Isometry3d::Identity(), ip);
    if (fit.converged && fit.fitness > 0.5) {
      out_.worst_icp_correction_mm = std::max(out_.worst_icp_correction_mm, fit.transform.translation().norm());
      for (auto& g : view) {
        g.position = fit.transform * g.position;
        g.normal = fit.transform.linear() * g.normal;
        g.major_direction = fit.transform.linear() * g.major_direction;
      }
    }
    stereo_.insert(stereo_.end(), view.begin(), view.end());
    if (observer_) observer_->elementsMeasured("stereo", view);
  } else if (stereo_.empty() && out_.stereo_note.empty() && !laser_positions.empty()) {
    // Say why when it is the images' scale: the line's centre needs the line to span pixels.
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& q : laser_positions) centroid += q;
    centroid /= static_cast<double>(laser_positions.size());
    const double depth = ((track.poseAt(t) * rig.head_from_left).inverse() * centroid).z();
    const double line_px = pixelsAtDepth(rig, grid_ == "circle" ? rings_.line_width : squares_.line_width, depth);
    if (depth > 0 && line_px < 1.5)
      out_.stereo_note = format("the printed line is %.1f px wide in these images; the stereo path needs about 1.5 px "
                                "or more (quick sessions render at a quarter of the resolution)",
                                line_px);
  }
  stereo_seconds_ += clock.lap();
  return true;
}

ScanMeasurement ScanMeasurer::finish() {
  out_.elements = laser_;
  out_.laser_elements = laser_.size();
  out_.surface_points = std::move(surface_points_);
  tell("laser", format("%zu sweeps, %s grid: %zu grid elements (%zu incomplete and %zu poor fits left out) (%.2f s)",
                       out_.laser_sweeps, grid_.c_str(), out_.laser_elements, out_.laser_stats.rejected_gap,
                       out_.laser_stats.rejected_fit, laser_seconds_));
  if (out_.elements.empty()) throw std::runtime_error("no grid element was found in the laser sweeps");
  if (out_.stereo_views > 0) {
    out_.stereo_elements = stereo_.size();
    out_.elements.insert(out_.elements.end(), stereo_.begin(), stereo_.end());
    tell("stereo", format("%zu views: %zu grid elements, ICP corrections up to %.3f mm (%.2f s)", out_.stereo_views,
                          out_.stereo_elements, out_.worst_icp_correction_mm, stereo_seconds_));
    if (!out_.stereo_note.empty()) tell("stereo", out_.stereo_note);
  }
  // Measurements of one printed element stand a few hundredths of a millimetre apart; neighbouring
  // elements a pitch, stretched or compressed by a few tens of percent at most.
  out_.merged = mergeMeasurements(out_.elements, 0.25 * squares_.pitch);
  // An element that overlaps a better-supported one is a wrong match: its measurements go.
  if (const std::vector<std::uint32_t> overlapping = overlappingElements(out_.merged); !overlapping.empty()) {
    std::vector<bool> wrong(out_.merged.elements.size(), false);
    for (std::uint32_t e : overlapping) wrong[e] = true;
    std::vector<GridElement> kept;
    for (std::size_t i = 0; i < out_.elements.size(); ++i)
      if (!wrong[out_.merged.element_of[i]]) kept.push_back(out_.elements[i]);
    tell("elements", format("%zu elements left out: each overlaps a neighbour measured more often (%zu measurements)",
                            overlapping.size(), out_.elements.size() - kept.size()));
    out_.elements = std::move(kept);
    out_.merged = mergeMeasurements(out_.elements, 0.25 * squares_.pitch);
  }
  // The strains at the elements' centres, not the means over their outlines; then merged again, so
  // that the paths' noise is that of measurements of the same thing.
  const std::vector<GridElement> outline_means = std::move(out_.elements);
  for (int pass = 0; pass < 3; ++pass) {
    out_.elements = strainsAtCentres(outline_means, out_.merged, squares_.pitch);
    out_.merged = mergeMeasurements(out_.elements, 0.25 * squares_.pitch);
  }
  addFieldUncertainty(out_.merged, squares_.pitch);
  for (std::size_t i = 0; i < out_.elements.size(); ++i) {
    out_.elements[i].strain_sigma = out_.elements[i].strain_noise = out_.merged.strain_sigma_of[i];
    out_.elements[i].position_sigma_mm = out_.merged.position_sigma_mm_of[i];
  }
  const auto noise = [](const PathNoise& p) {
    if (!p.strain) return std::string("not known (too few twins)");
    if (!p.strain_shared)
      return format("strain %.5f, position %.4f mm from %zu twins (the part its twins share is not known: no element "
                    "was measured by both paths)",
                    *p.strain, *p.position_mm, p.twin_pairs);
    return format("strain %.5f (%.5f shared by its twins), position %.4f mm (%.4f shared), %zu twins", *p.strain,
                  *p.strain_shared, *p.position_mm, *p.position_shared_mm, p.twin_pairs);
  };
  tell("elements", format("%zu measurements of %zu printed elements; one measurement's uncertainty: laser %s%s",
                          out_.merged.measurements, out_.merged.elements.size(), noise(out_.merged.laser).c_str(),
                          out_.stereo_elements ? (", stereo " + noise(out_.merged.stereo)).c_str() : ""));
  return std::move(out_);
}

ScanMeasurement measureScan(const ScanTrace& trace, const MeasureParams& params, MeasureObserver* observer) {
  ScanMeasurer m(params, observer);
  m.calibrateDigitizer(trace);
  m.calibrateCameras(trace);
  m.measureSweeps(trace);
  if (params.with_stereo) {
    if (!m.camerasCalibrated())
      throw std::runtime_error("the stereo views need the cameras calibrated: the trace has no plate views and no stored "
                               "camera calibration was given");
    for (std::size_t v = 0; v < trace.part_left.size(); ++v) m.detectView(trace, v, static_cast<std::uint32_t>(1000 + v));
    while (m.measureDetectedView(trace)) {
    }
  }
  return m.finish();
}

}  // namespace stampscan::registration
