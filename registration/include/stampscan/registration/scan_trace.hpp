// A recorded or simulated scan trace, read and decoded for processing: the session description,
// the CMM's head track, the devices' clock pairs, the sweeps (from the CMM's events), every laser profile, and the camera
// frames of the calibration plate. Damage to the trace is kept in `health` and reported; whatever
// could be recovered is processed.
#pragma once

#include "stampscan/acquisition/trace/mcap_reader.hpp"
#include "stampscan/acquisition/trace/session_description.hpp"
#include "stampscan/registration/laser_geometry.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::registration {

struct SweepWindow {
  std::string label;  // the CMM event's detail, e.g. "part sweep 3", "reference_sphere sweep 0"
  std::int64_t begin_ns = 0, end_ns = 0;  // station clock
  bool is(const std::string& scene) const { return label.rfind(scene + " sweep", 0) == 0; }
};

struct CameraImage {
  std::uint64_t trigger_id = 0;
  std::int64_t device_time_ns = 0;
  cv::Mat image;
};

struct ScanTrace {
  std::optional<trace::SessionDescription> session;  // absent in a trace that has none
  std::vector<HeadSample> head;
  std::map<std::string, std::vector<std::pair<std::int64_t, std::int64_t>>> clock_pairs;  // device -> (station, device)
  std::vector<SweepWindow> sweeps;
  std::vector<Profile> profiles;
  // Frames taken while the calibration plate was in view, paired by trigger (left[i] with right[i]).
  std::vector<CameraImage> plate_left, plate_right;
  std::size_t part_frames = 0;  // frames of the part
  // Pairs of frames of the part, by trigger; kept only when asked for (they are large).
  std::vector<CameraImage> part_left, part_right;
  double scan_seconds = 0;      // first to last CMM report
  trace::TraceHealth health;
};

using LoadProgress = std::function<void(double fraction)>;
// Throws std::runtime_error naming the file when it is not an MCAP trace, holds no CMM reports, or
// has a session description that does not decode.
ScanTrace loadScanTrace(const std::filesystem::path& file, const LoadProgress& progress = {}, bool keep_part_frames = false);

}  // namespace stampscan::registration
