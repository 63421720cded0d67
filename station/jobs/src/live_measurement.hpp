// Measuring a scan while it is recorded: the ScanJob tees the runner's messages into a
// LiveScanTrace, and this measures each stage on a thread of its own as soon as the plan's steps
// that feed it are done: the digitizer's calibration after the last sphere sweep, the cameras'
// after the last plate view, each part sweep after it ends, each part view once every part sweep
// is in (its rings are matched on the laser's surface). So the Cloud4D is ready soon after the last
// sweep instead of a whole measurement after it. On a second thread each part sweep's laser returns
// are fitted as a piece of the surface as soon as the sweep is measured, while the next is scanned;
// after the last part sweep the pieces are joined, while the stereo views are measured; the strain
// of all the elements goes on the surface when they are in (fitting/shape_and_strain.hpp).
//
// The thread keeps its own copy of what it still needs (new messages are copied once, under the
// live trace's lock, and dropped once measured; the laser profiles, the bulk, are moved out of the
// live trace rather than copied), so the devices' threads never wait for it.
#pragma once

#include "stampscan/acquisition/scan_plan.hpp"
#include "stampscan/fitting/shape_and_strain.hpp"
#include "stampscan/registration/measure_scan.hpp"

#include <atomic>
#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>

namespace stampscan::jobs {

class LiveMeasurement {
 public:
  LiveMeasurement(registration::LiveScanTrace& live, const acquisition::ScanPlan& plan,
                  const registration::MeasureParams& params, registration::MeasureObserver* observer);
  // Stops the threads (what they measured is dropped unless finish() and shape() were called); a
  // surface fit under way stops at its next stage.
  ~LiveMeasurement();
  LiveMeasurement(const LiveMeasurement&) = delete;
  LiveMeasurement& operator=(const LiveMeasurement&) = delete;

  // The first `steps` steps of the plan are done (called from the run's thread as it goes).
  void stepsDone(std::size_t steps);
  // The run is over and completed: measures what is left and returns the whole. Rethrows what a
  // stage threw.
  registration::ScanMeasurement finish();
  // Any thread: stops what is left to measure (the views not measured yet, the surface fit at its
  // next step); finish() then returns what was measured, and shape() nothing.
  void cancel();
  // After finish(): the surface fitted to every part sweep's laser returns (null when the plan's
  // sweeps returned none). Waits for the fit; rethrows what it threw.
  std::unique_ptr<fitting::ShapeSurface> shape();

 private:
  void loop();
  void pull();                          // new messages of the live trace into mine_
  void advance(std::size_t step);       // what became measurable with step `step` done
  void measureReadyViews();
  // The laser returns of the sweeps the measurer has measured since, queued for the shape thread;
  // `last`: no more will come (the thread joins the pieces once it has fitted them).
  void queueShapePieces(bool last);
  void fitShape();  // the shape thread

  registration::LiveScanTrace& live_;  // its profiles are taken, not copied
  const acquisition::ScanPlan& plan_;
  registration::MeasureParams params_;
  registration::ScanMeasurer measurer_;

  // The thread's copy of the trace and how far into the live one it has copied.
  registration::ScanTrace mine_;
  std::map<std::string, std::size_t> taken_pairs_;
  std::size_t part_sweeps_measured_ = 0, part_views_detected_ = 0;
  std::size_t sphere_done_ = 0, plate_done_ = 0, part_sweeps_done_ = 0, part_views_done_ = 0;
  std::vector<registration::SweepWindow> pending_sweeps_;  // ended, not measured yet
  bool plate_step_passed_ = false;  // the cameras' calibration was tried after the last plate view

  // The surface fit, on a thread of its own: a queue of sweeps' returns, each fitted as a piece,
  // joined once the queue is closed; the flag stops it at its next stage.
  registration::MeasureObserver* observer_;
  std::atomic<bool> shape_cancelled_ = false, views_cancelled_ = false;
  std::mutex shape_mutex_;
  std::condition_variable shape_wake_;
  std::deque<std::vector<fitting::Vec3>> shape_queue_;
  bool shape_closed_ = false;
  std::unique_ptr<fitting::ShapeSurface> shape_;
  std::exception_ptr shape_failure_;
  std::thread shape_thread_;

  // The measuring thread (declared last: it starts once everything above is made).
  std::mutex mutex_;
  std::condition_variable wake_;
  std::size_t steps_done_ = 0, steps_advanced_ = 0;
  bool run_over_ = false, stop_ = false, idle_ = true;
  std::exception_ptr failure_;
  std::thread thread_;
};

}  // namespace stampscan::jobs
