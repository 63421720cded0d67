#include "stampscan/registration/measure_scan.hpp"

#include "stampscan/registration/icp.hpp"
#include "stampscan/registration/stereo_squares.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
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

void tell(MeasureObserver* observer, std::string_view stage, const std::string& text) {
  if (observer) observer->stageDone(stage, text);
}

// The stereo views: rings (or square cells) matched on the laser's surface, each view's pose
// refined by ICP of its triangulated elements against the laser's.
void measureStereo(const ScanTrace& trace, const trace::SessionDescription& session, const HeadTrack& track,
                   std::int64_t camera_offset, const RingDetectionParams& rings, const SquareDetectionParams& squares,
                   ScanMeasurement& out) {
  const StereoRig& rig = *out.rig;
  std::vector<Vec3> laser_positions, laser_normals;
  for (const auto& g : out.elements) {
    laser_positions.push_back(g.position);
    laser_normals.push_back(g.normal);
  }
  const PointToPlaneIcp icp(laser_positions, laser_normals);
  const bool circles = session.grid == "circle";
  for (std::size_t v = 0; v < trace.part_left.size(); ++v) {
    const std::int64_t t = trace.part_left[v].device_time_ns - camera_offset;
    if (!track.covers(t)) continue;
    ++out.stereo_views;
    const auto view_id = static_cast<std::uint32_t>(1000 + v);
    auto view = circles ? measureStereoPair(trace.part_left[v].image, trace.part_right[v].image, rig, track.poseAt(t),
                                            laser_positions, rings, view_id)
                        : measureStereoSquares(trace.part_left[v].image, trace.part_right[v].image, rig, track.poseAt(t),
                                               laser_positions, squares, view_id);
    if (view.size() < 10) continue;
    std::vector<Vec3> source;
    for (const auto& g : view) source.push_back(g.position);
    IcpParams ip;
    ip.max_correspondence_distance = 1.0;
    // Stereo and laser measure the same grid elements: each pairs with its own, so the offset
    // along the sheet counts as much as across it. Point-to-plane alone let errors across the
    // sheet on the radii slide a view sideways along the walls (0.064 mm position RMS on a full
    // square-grid pan session, 0.039 with this).
    ip.tangential_weight = 1.0;
    const IcpResult fit = icp.align(source, Eigen::Isometry3d::Identity(), ip);
    if (fit.converged && fit.fitness > 0.5) {
      out.worst_icp_correction_mm = std::max(out.worst_icp_correction_mm, fit.transform.translation().norm());
      for (auto& g : view) {
        g.position = fit.transform * g.position;
        g.normal = fit.transform.linear() * g.normal;
        g.major_direction = fit.transform.linear() * g.major_direction;
      }
    }
    out.stereo_elements += view.size();
    out.elements.insert(out.elements.end(), view.begin(), view.end());
  }
  if (out.stereo_elements == 0 && !trace.part_left.empty()) {
    // Say why when it is the images' scale: the line's centre needs the line to span pixels.
    const std::int64_t t = trace.part_left.front().device_time_ns - camera_offset;
    if (!track.covers(t)) return;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& q : laser_positions) centroid += q;
    centroid /= static_cast<double>(laser_positions.size());
    const double depth = ((track.poseAt(t) * rig.head_from_left).inverse() * centroid).z();
    const double line_px = (circles ? rings.line_width : squares.line_width) * rig.left.matrix(0, 0) / depth;
    if (depth > 0 && line_px < 1.5)
      out.stereo_note = format("the printed line is %.1f px wide in these images; the stereo path needs about 1.5 px or "
                               "more (quick sessions render at a quarter of the resolution)",
                               line_px);
  }
}

}  // namespace

Eigen::Isometry3d toIsometry(const trace::RigidPose& pose) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T.linear()(r, c) = pose.rotation[static_cast<std::size_t>(3 * r + c)];
    T.translation()(r) = pose.translation[static_cast<std::size_t>(r)];
  }
  return T;
}

trace::RigidPose toRigidPose(const Eigen::Isometry3d& T) {
  trace::RigidPose p;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) p.rotation[static_cast<std::size_t>(3 * r + c)] = T.linear()(r, c);
    p.translation[static_cast<std::size_t>(r)] = T.translation()(r);
  }
  return p;
}

ScanMeasurement measureScan(const ScanTrace& trace, const MeasureParams& params, MeasureObserver* observer) {
  if (!trace.session) throw std::runtime_error("the trace has no session description (metadata 'cell')");
  const trace::SessionDescription& session = *trace.session;
  const auto pairs = trace.clock_pairs.find("digitizer");
  if (pairs == trace.clock_pairs.end()) throw std::runtime_error("the trace has no clock-sync pairs for the digitizer");
  const std::int64_t digitizer_offset = clockOffset(pairs->second);
  const HeadTrack track(trace.head);
  ScanMeasurement out;
  StageClock clock;

  // 1. The digitizer's calibration: from the sphere sweeps, or the one given.
  std::vector<Profile> sphere;
  for (const auto& w : trace.sweeps)
    if (w.is("reference_sphere")) {
      auto p = profilesIn(trace, track, w, digitizer_offset, 0, params.max_track_error_mm);
      sphere.insert(sphere.end(), p.begin(), p.end());
    }
  if (!sphere.empty()) {
    if (!session.reference_sphere_radius_mm)
      throw std::runtime_error("the trace has reference-sphere sweeps but its session description gives no sphere radius");
    SphereCalibrationParams sp;
    sp.sphere_radius = *session.reference_sphere_radius_mm;
    sp.nominal.head_from_digitizer = toIsometry(session.head_from_digitizer_nominal);
    sp.nominal.clock_offset_ns = digitizer_offset;
    out.sphere = calibrateDigitizer(sphere, track, sp);
    out.digitizer = out.sphere->calibration;
    tell(observer, "digitizer",
         format("calibrated on the reference sphere: latency %.3f ms, residual %.4f mm RMS over %zu points (%.2f s)",
                static_cast<double>(out.digitizer.latency_ns) * 1e-6, out.sphere->rms_mm, out.sphere->inliers, clock.lap()));
  } else {
    if (!params.digitizer)
      throw std::runtime_error("the trace has no reference-sphere sweeps to calibrate the digitizer, and no stored "
                               "calibration was given");
    out.digitizer = *params.digitizer;
    tell(observer, "digitizer", "the stored calibration (the trace has no reference-sphere sweeps)");
  }
  out.digitizer.clock_offset_ns = digitizer_offset;

  // 2. The cameras, when the trace shows the plate.
  std::int64_t camera_offset = 0;
  if (trace.plate_left.size() >= params.min_plate_views && session.plate) {
    const CirclePlateSpec spec{session.plate->columns, session.plate->rows, session.plate->pitch_mm};
    std::vector<cv::Mat> left, right;
    for (std::size_t i = 0; i < trace.plate_left.size(); ++i) {
      left.push_back(trace.plate_left[i].image);
      right.push_back(trace.plate_right[i].image);
    }
    out.stereo = calibrateStereo(left, right, spec);
    const StereoCalibration& stereo = *out.stereo;
    std::string text = format("calibrated on %zu plate views: reprojection %.3f / %.3f px, baseline %.3f mm",
                              stereo.pairs_used, stereo.left.rms_px, stereo.right.rms_px, stereo.baseline_mm);
    const auto camera_pairs = trace.clock_pairs.find("camera_left");
    if (camera_pairs != trace.clock_pairs.end()) {
      camera_offset = clockOffset(camera_pairs->second);
      std::vector<Eigen::Isometry3d> heads, plates;
      for (std::size_t v = 0; v < left.size(); ++v) {
        const std::int64_t t = trace.plate_left[v].device_time_ns - camera_offset;
        if (stereo.left.plate_poses[v] && track.covers(t)) {
          heads.push_back(track.poseAt(t));
          plates.push_back(*stereo.left.plate_poses[v]);
        }
      }
      if (heads.size() >= 3) {
        out.head_from_left = calibrateHeadToCamera(heads, plates);
        text += format(", head mount residual %.3f mm", out.head_from_left->residual_mm);
        out.rig = StereoRig{stereo.left.model, stereo.right.model, out.head_from_left->head_from_camera,
                            stereo.right_from_left};
      }
    }
    tell(observer, "cameras", text + format(" (%.2f s)", clock.lap()));
  }

  // 3. The laser path: rings (or square cells) in every part sweep, the sweeps in parallel.
  RingDetectionParams rings;
  SquareDetectionParams squares;
  rings.printed_radius = 0.5 * session.grid_circle_diameter_mm;
  squares.pitch = session.grid_pitch_mm;
  rings.line_width = squares.line_width = session.grid_line_width_mm;
  std::vector<SweepWindow> part;
  for (const auto& w : trace.sweeps)
    if (w.is("part")) part.push_back(w);
  std::vector<std::vector<GridElement>> per_sweep(part.size());
  std::vector<RingDetectionStats> stats(part.size());
  const bool circles = session.grid == "circle";
  tbb::parallel_for(std::size_t{0}, part.size(), [&](std::size_t k) {
    const auto profiles =
        profilesIn(trace, track, part[k], out.digitizer.clock_offset_ns, out.digitizer.latency_ns, params.max_track_error_mm);
    const auto id = static_cast<std::uint32_t>(k);
    per_sweep[k] = circles ? detectLaserRings(profiles, track, out.digitizer, rings, id, &stats[k])
                           : detectLaserSquares(profiles, track, out.digitizer, squares, id, &stats[k]);
  });
  for (std::size_t k = 0; k < part.size(); ++k) {
    out.elements.insert(out.elements.end(), per_sweep[k].begin(), per_sweep[k].end());
    out.laser_stats.candidates += stats[k].candidates;
    out.laser_stats.rejected_size += stats[k].rejected_size;
    out.laser_stats.rejected_gap += stats[k].rejected_gap;
    out.laser_stats.rejected_fit += stats[k].rejected_fit;
    out.laser_stats.found += stats[k].found;
  }
  out.laser_sweeps = part.size();
  out.laser_elements = out.elements.size();
  tell(observer, "laser",
       format("%zu sweeps, %s grid: %zu grid elements (%zu incomplete and %zu poor fits left out) (%.2f s)", part.size(),
              session.grid.c_str(), out.laser_elements, out.laser_stats.rejected_gap, out.laser_stats.rejected_fit,
              clock.lap()));
  if (out.elements.empty()) throw std::runtime_error("no grid element was found in the laser sweeps");

  // 4. The stereo views.
  if (params.with_stereo) {
    if (!out.rig) throw std::runtime_error("the stereo views need the cameras calibrated: the trace has no plate views");
    measureStereo(trace, session, track, camera_offset, rings, squares, out);
    tell(observer, "stereo",
         format("%zu views: %zu grid elements, ICP corrections up to %.3f mm (%.2f s)", trace.part_left.size(),
                out.stereo_elements, out.worst_icp_correction_mm, clock.lap()));
    if (!out.stereo_note.empty()) tell(observer, "stereo", out.stereo_note);
  }
  return out;
}

}  // namespace stampscan::registration
