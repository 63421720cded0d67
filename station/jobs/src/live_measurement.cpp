#include "live_measurement.hpp"

#include <malloc.h>

#include <algorithm>
#include <iterator>
#include <string>

namespace stampscan::jobs {

namespace {

// Thrown from the surface fit's progress callback to stop it (a scan aborted while it ran).
struct ShapeFitCancelled {};

template <typename T>
void appendFrom(std::vector<T>& to, const std::vector<T>& from, std::size_t& taken) {
  for (; taken < from.size(); ++taken) to.push_back(from[taken]);
}

template <typename T>
void moveAppend(std::vector<T>& to, std::vector<T>& from) {
  if (to.empty()) to = std::move(from);
  else std::move(from.begin(), from.end(), std::back_inserter(to));
}

}  // namespace

LiveMeasurement::LiveMeasurement(registration::LiveScanTrace& live, const acquisition::ScanPlan& plan,
                                 const registration::MeasureParams& params, registration::MeasureObserver* observer)
    : live_(live),
      plan_(plan),
      params_(params),
      measurer_(params, observer),
      observer_(observer),
      thread_([this] { loop(); }) {}

LiveMeasurement::~LiveMeasurement() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  cancel();
  if (shape_thread_.joinable()) shape_thread_.join();
}

void LiveMeasurement::queueShapePieces(bool last) {
  std::vector<std::vector<fitting::Vec3>> sweeps = measurer_.takeSurfacePoints();
  {
    std::lock_guard lock(shape_mutex_);
    if (shape_closed_) return;
    for (auto& returns : sweeps) shape_queue_.push_back(std::move(returns));
    shape_closed_ = last;
  }
  shape_wake_.notify_all();
  if (!shape_thread_.joinable()) shape_thread_ = std::thread([this] { fitShape(); });
}

void LiveMeasurement::fitShape() {
  try {
    fitting::ShapeAndStrainParams params;
    params.shape.progress = [this](const std::string&, double) {
      if (shape_cancelled_) throw ShapeFitCancelled{};
    };
    std::vector<std::unique_ptr<fitting::ShapePiece>> pieces;
    std::size_t returns = 0;
    for (;;) {
      std::vector<fitting::Vec3> sweep;
      {
        std::unique_lock lock(shape_mutex_);
        shape_wake_.wait(lock, [&] { return shape_cancelled_ || shape_closed_ || !shape_queue_.empty(); });
        if (shape_cancelled_) return;
        if (shape_queue_.empty()) break;  // closed, and every sweep fitted
        sweep = std::move(shape_queue_.front());
        shape_queue_.pop_front();
      }
      returns += sweep.size();
      pieces.push_back(std::make_unique<fitting::ShapePiece>(std::move(sweep), params.shape));
      // A piece's fit frees a few hundred megabytes of working memory on TBB's threads, whose malloc
      // arenas would keep it from the system while the next sweeps' returns come in: given back,
      // a whole part's peak is some 160 MB lower (glibc).
      malloc_trim(0);
    }
    if (pieces.empty()) return;
    if (observer_)
      observer_->stageDone("surface", "joining the surface of " + std::to_string(pieces.size()) + " sweeps (" +
                                          std::to_string(returns) + " laser returns, each fitted as it was measured)");
    shape_ = std::make_unique<fitting::ShapeSurface>(std::move(pieces), params);
  } catch (const ShapeFitCancelled&) {
  } catch (...) {
    shape_failure_ = std::current_exception();
  }
}

void LiveMeasurement::cancel() {
  views_cancelled_ = true;
  {
    std::lock_guard lock(shape_mutex_);
    shape_cancelled_ = true;
  }
  shape_wake_.notify_all();
}

std::unique_ptr<fitting::ShapeSurface> LiveMeasurement::shape() {
  queueShapePieces(true);  // (finish() has closed the queue already)
  if (shape_thread_.joinable()) shape_thread_.join();
  if (shape_failure_) std::rethrow_exception(shape_failure_);
  return std::move(shape_);
}

void LiveMeasurement::stepsDone(std::size_t steps) {
  {
    std::lock_guard lock(mutex_);
    steps_done_ = std::max(steps_done_, std::min(steps, plan_.steps.size()));
  }
  wake_.notify_all();
}

void LiveMeasurement::loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, [&] { return stop_ || run_over_ || steps_advanced_ < steps_done_; });
    if (stop_) return;
    if (steps_advanced_ < steps_done_) {
      const std::size_t step = steps_advanced_++;
      lock.unlock();
      try {
        if (!failure_) advance(step);
      } catch (...) {
        failure_ = std::current_exception();
      }
      lock.lock();
      continue;
    }
    if (run_over_) return;
  }
}

void LiveMeasurement::pull() {
  live_.with([&](const registration::ScanTrace& t) {
    if (!mine_.session && t.session) mine_.session = t.session;
    // Whole: a late position report goes in before later ones (ScanTraceBuilder).
    if (mine_.head.size() != t.head.size()) mine_.head = t.head;
    mine_.sweeps = t.sweeps;  // few; and a sweep run again replaces its discarded first run
    for (const auto& [device, pairs] : t.clock_pairs) appendFrom(mine_.clock_pairs[device], pairs, taken_pairs_[device]);
    return 0;
  });
  // The profiles and frames are moved, not copied: a session's are hundreds of megabytes.
  registration::TraceBulk bulk = live_.takeBulk();
  moveAppend(mine_.profiles, bulk.profiles);
  moveAppend(mine_.plate_left, bulk.plate_left);
  moveAppend(mine_.plate_right, bulk.plate_right);
  moveAppend(mine_.part_left, bulk.part_left);
  moveAppend(mine_.part_right, bulk.part_right);
}

void LiveMeasurement::advance(std::size_t step) {
  pull();
  const acquisition::PlanStep& s = plan_.steps[step];
  if (const auto* sweep = std::get_if<acquisition::SweepStep>(&s)) {
    // The step's sweep window: the last of its label (a sweep run again after losing profiles has
    // its first run discarded).
    const std::string label = trace::sweepLabel(sweep->scene, sweep->index);
    if (sweep->scene == acquisition::Scene::Part)
      for (auto w = mine_.sweeps.rbegin(); w != mine_.sweeps.rend(); ++w)
        if (w->label == label) {
          pending_sweeps_.push_back(*w);
          break;
        }
    if (sweep->scene == acquisition::Scene::ReferenceSphere && ++sphere_done_ == plan_.sweepCount(acquisition::Scene::ReferenceSphere)) {
      measurer_.calibrateDigitizer(mine_);
      // The sphere's profiles are done with (those of a sweep already under way stay).
      std::int64_t last_end = 0;
      for (const auto& w : mine_.sweeps)
        if (w.is(acquisition::Scene::ReferenceSphere)) last_end = std::max(last_end, w.end_ns);
      const registration::DigitizerCalibration& d = measurer_.digitizer();
      std::erase_if(mine_.profiles, [&](const registration::Profile& p) { return d.exposureTime(p) <= last_end; });
    }
  } else {
    const auto& view = std::get<acquisition::StereoStep>(s);
    if (view.scene == acquisition::Scene::CalibrationPlate) ++plate_done_;
  }
  // Each plate view's dots are found as soon as both its images are in, and the images let go:
  // twelve pairs of images are some 150 MB, their dots a few kilobytes.
  const std::size_t found = measurer_.findPlateDots(mine_);
  mine_.plate_left.erase(mine_.plate_left.begin(), mine_.plate_left.begin() + static_cast<std::ptrdiff_t>(found));
  mine_.plate_right.erase(mine_.plate_right.begin(), mine_.plate_right.begin() + static_cast<std::ptrdiff_t>(found));
  // The cameras once every plate view is in and the head has moved on from the last one (the hand-
  // eye calibration needs the head track to reach past each view); when they do not calibrate,
  // finish() tries again with the whole head track.
  const std::size_t plates = plan_.stereoCount(acquisition::Scene::CalibrationPlate);
  if (plates > 0 && plate_done_ == plates && !plate_step_passed_) {
    if (std::holds_alternative<acquisition::StereoStep>(s) && std::get<acquisition::StereoStep>(s).scene == acquisition::Scene::CalibrationPlate) {
      // this step is the last plate view: wait for the next one
    } else {
      plate_step_passed_ = true;
      measurer_.calibrateCameras(mine_);
    }
  }
  // Part sweeps can be measured once the digitizer is calibrated (a plan without sphere sweeps uses
  // the stored calibration: the first part sweep then calibrates).
  if (!pending_sweeps_.empty() && !measurer_.digitizerCalibrated() && plan_.sweepCount(acquisition::Scene::ReferenceSphere) == 0)
    measurer_.calibrateDigitizer(mine_);
  if (measurer_.digitizerCalibrated() && !pending_sweeps_.empty()) {
    std::int64_t last_end = 0;
    for (const registration::SweepWindow& w : pending_sweeps_) {
      measurer_.measureSweep(mine_, w, static_cast<std::uint32_t>(part_sweeps_measured_++));
      last_end = std::max(last_end, w.end_ns);
    }
    pending_sweeps_.clear();
    const registration::DigitizerCalibration& d = measurer_.digitizer();
    std::erase_if(mine_.profiles, [&](const registration::Profile& p) { return d.exposureTime(p) <= last_end; });
    // Each sweep's returns are fitted as a piece of the surface while the next sweep is scanned.
    queueShapePieces(part_sweeps_measured_ >= plan_.sweepCount(acquisition::Scene::Part));
  }
  measureReadyViews();
}

void LiveMeasurement::measureReadyViews() {
  // A plan without plate views measures with the stored calibration, once the views' clock pairs are in.
  if (params_.with_stereo && !measurer_.camerasCalibrated() && params_.cameras &&
      plan_.stereoCount(acquisition::Scene::CalibrationPlate) == 0)
    measurer_.calibrateCameras(mine_);
  if (!params_.with_stereo || !measurer_.camerasCalibrated()) return;
  // Each view's images are searched as soon as both are in (most of a view's work), and let go.
  while (!views_cancelled_ && !mine_.part_left.empty() && !mine_.part_right.empty()) {
    measurer_.detectView(mine_, 0, static_cast<std::uint32_t>(1000 + part_views_detected_++));
    mine_.part_left.erase(mine_.part_left.begin());
    mine_.part_right.erase(mine_.part_right.begin());
  }
  // A view is matched on the laser's surface and registered to all of its elements: only once every
  // part sweep of the plan is in. (A view waits until the head track reaches past it: the CMM
  // reports only while it moves.)
  if (part_sweeps_measured_ < plan_.sweepCount(acquisition::Scene::Part)) return;
  while (!views_cancelled_ && measurer_.measureDetectedView(mine_)) {
  }
}

registration::ScanMeasurement LiveMeasurement::finish() {
  {
    std::lock_guard lock(mutex_);
    run_over_ = true;
    steps_done_ = plan_.steps.size();
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (failure_) std::rethrow_exception(failure_);
  // Whatever the steps did not trigger (a plan that ended early, views after the last sweep).
  pull();
  if (!measurer_.digitizerCalibrated()) measurer_.calibrateDigitizer(mine_);
  for (const registration::SweepWindow& w : pending_sweeps_)
    measurer_.measureSweep(mine_, w, static_cast<std::uint32_t>(part_sweeps_measured_++));
  pending_sweeps_.clear();
  queueShapePieces(true);  // unless the last part sweep closed the queue
  // Cameras that did not calibrate leave the stereo views out; the laser's elements stand.
  if (params_.with_stereo && !measurer_.camerasCalibrated()) measurer_.calibrateCameras(mine_);
  part_sweeps_measured_ = std::max(part_sweeps_measured_, plan_.sweepCount(acquisition::Scene::Part));
  measureReadyViews();
  return measurer_.finish();
}

}  // namespace stampscan::jobs
