// The cloud of a scan under way, as the panel shows it growing: the grid elements each part sweep
// (and stereo view) adds as the live measurement finds them (registration::MeasureObserver::
// elementsMeasured), kept decimated so that a whole part's scan stays light for the browser. Each
// batch is sent as a `cloud` event; a page opened mid-scan asks for everything so far
// (GET /api/scan/cloud).
//
// Bounded: a batch keeps at most `batch_limit` points (every k-th element) and the whole scan at
// most `total_limit`; what is left out is counted, never silently lost from the figures.
//
// Thread safety: every method may be called from any thread.
#pragma once

#include "stampscan/registration/grid_element.hpp"

#include <cstddef>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace stampscan::hmi {

// Rounded for the wire (a hundredth of a millimetre, 1e-5 of strain): the view needs no more, and
// the events stay short.
struct LivePoints {
  std::vector<double> xyz;        // mm, machine frame, three per point
  std::vector<double> thickness;  // thickness true strain, one per point
  std::size_t size() const { return thickness.size(); }
};

class LiveCloud {
 public:
  explicit LiveCloud(std::size_t batch_limit = 2000, std::size_t total_limit = 20000)
      : batch_limit_(batch_limit), total_limit_(total_limit) {}

  // A new scan: forgets the last one's points.
  void reset(const std::string& run_id = "");
  void setRun(const std::string& run_id);
  // Keeps (a decimation of) the batch; returns the points kept, to be sent to the pages.
  LivePoints add(const std::vector<registration::GridElement>& elements);

  struct Snapshot {
    std::string run_id;
    LivePoints points;
    std::size_t measured = 0;  // elements measured so far, all of them
    std::size_t batches = 0;
  };
  Snapshot snapshot() const;
  // The counts alone (measured, shown), without copying the points.
  std::pair<std::size_t, std::size_t> counts() const;

 private:
  std::size_t batch_limit_, total_limit_;
  mutable std::mutex mutex_;
  Snapshot state_;
};

}  // namespace stampscan::hmi
