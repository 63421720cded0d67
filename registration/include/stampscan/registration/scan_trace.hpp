// A recorded or simulated scan trace, read and decoded for processing: the session description,
// the CMM's head track, the devices' clock pairs, the sweeps (from the CMM's events), every laser profile, and the camera
// frames of the calibration plate. Damage to the trace is kept in `health` and reported; whatever
// could be recovered is processed.
#pragma once

#include "stampscan/acquisition/trace/mcap_reader.hpp"
#include "stampscan/acquisition/trace/session_description.hpp"
#include "stampscan/acquisition/trace/trace_messages.hpp"
#include "stampscan/acquisition/trace/trace_sink.hpp"
#include "stampscan/registration/laser_geometry.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <span>
#include <string_view>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace stampscan::registration {

struct SweepWindow {
  std::string label;  // the CMM event's detail, e.g. "part sweep 3", "reference_sphere sweep 0"
  std::int64_t begin_ns = 0, end_ns = 0;  // station clock
  bool is(trace::Scene scene) const { return trace::isSweepOf(label, scene); }
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

// What makes a trace large, added since a consumer last took it: the laser profiles and the paired
// camera frames (plate and part views; `left[i]` with `right[i]`).
struct TraceBulk {
  std::vector<Profile> profiles;
  std::vector<CameraImage> plate_left, plate_right, part_left, part_right;
};

// Decodes a trace's messages one at a time into a ScanTrace: loadScanTrace() feeds it from a file,
// LiveScanTrace from a scan as its messages arrive. Not thread-safe.
class ScanTraceBuilder {
 public:
  explicit ScanTraceBuilder(bool keep_part_frames = false) : keep_part_frames_(keep_part_frames) {}
  // One message on a standard topic; one that does not decode is counted and skipped.
  void add(std::string_view topic, std::span<const std::byte> bytes);
  // The session description ("cell"); throws trace::SessionDescriptionError when it does not decode.
  void metadata(const std::string& name, const std::map<std::string, std::string>& values);
  const ScanTrace& trace() const { return out_; }
  // The trace as it stands. A sweep still open is kept up to the last position when `cut` (the
  // trace ended mid-sweep: a crash or a power cut). On an rvalue the trace is moved out, not copied
  // (a session's profiles are hundreds of megabytes): std::move(builder).finish(cut).
  ScanTrace finish(bool cut) const&;
  ScanTrace finish(bool cut) &&;
  // The bulk added since the last call (laser profiles, paired frames), moved out of the trace.
  TraceBulk takeBulk();
  std::size_t decodeErrors() const { return decode_errors_; }
  const std::string& firstDecodeError() const { return first_decode_error_; }

 private:
  bool keep_part_frames_;
  ScanTrace out_;
  std::optional<trace::Scene> scene_;  // the scene the frames belong to, from the scene markers
  std::map<std::uint64_t, std::pair<trace::CameraFrame, trace::CameraFrame>> pending_pairs_;  // by trigger
  std::int64_t sweep_begin_ = -1;
  std::string sweep_label_;
  std::size_t decode_errors_ = 0;
  std::string first_decode_error_;
};

// A scan's trace decoded as it is recorded: the ScanRunner's sink is tee'd to it, and the measuring
// thread reads what has arrived so far under its lock (with()). Thread-safe.
class LiveScanTrace final : public trace::TraceSink {
 public:
  explicit LiveScanTrace(bool keep_part_frames) : builder_(keep_part_frames) {}
  void message(std::string_view topic, std::int64_t log_time_ns, std::vector<std::byte> bytes) override;
  void metadata(const std::string& name, const std::map<std::string, std::string>& values) override;
  // Runs f(const ScanTrace&) under the lock; keep it short (the devices' threads wait).
  template <typename F>
  auto with(F&& f) const {
    std::lock_guard lock(mutex_);
    return f(builder_.trace());
  }
  // The profiles and frames that arrived since the last call, moved out: the measuring thread owns
  // them from there and the live trace keeps no copy of a session's hundreds of megabytes (the
  // trace's profiles and frames then hold only those not taken yet).
  TraceBulk takeBulk();

 private:
  mutable std::mutex mutex_;
  ScanTraceBuilder builder_;
};

using LoadProgress = std::function<void(double fraction)>;
// Throws std::runtime_error naming the file when it is not an MCAP trace, holds no CMM reports, or
// has a session description that does not decode.
ScanTrace loadScanTrace(const std::filesystem::path& file, const LoadProgress& progress = {}, bool keep_part_frames = false);

}  // namespace stampscan::registration
