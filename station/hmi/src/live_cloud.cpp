#include "stampscan/hmi/live_cloud.hpp"

#include <algorithm>
#include <cmath>

namespace stampscan::hmi {

void LiveCloud::reset(const std::string& run_id) {
  std::lock_guard lock(mutex_);
  state_ = Snapshot{};
  state_.run_id = run_id;
}

void LiveCloud::setRun(const std::string& run_id) {
  std::lock_guard lock(mutex_);
  state_.run_id = run_id;
}

LivePoints LiveCloud::add(const std::vector<registration::GridElement>& elements) {
  std::lock_guard lock(mutex_);
  state_.measured += elements.size();
  ++state_.batches;
  LivePoints kept;
  const std::size_t room = std::min(batch_limit_, total_limit_ - std::min(total_limit_, state_.points.size()));
  if (elements.empty() || room == 0) return kept;
  // Every k-th element: spread over the whole sweep rather than its first part.
  const std::size_t step = (elements.size() + room - 1) / room;
  for (std::size_t i = 0; i < elements.size(); i += step) {
    const auto& g = elements[i];
    for (int k = 0; k < 3; ++k) kept.xyz.push_back(std::round(g.position[k] * 100) / 100);
    kept.thickness.push_back(std::round(g.thickness_strain * 1e5) / 1e5);
  }
  state_.points.xyz.insert(state_.points.xyz.end(), kept.xyz.begin(), kept.xyz.end());
  state_.points.thickness.insert(state_.points.thickness.end(), kept.thickness.begin(), kept.thickness.end());
  return kept;
}

std::pair<std::size_t, std::size_t> LiveCloud::counts() const {
  std::lock_guard lock(mutex_);
  return {state_.measured, state_.points.size()};
}

LiveCloud::Snapshot LiveCloud::snapshot() const {
  std::lock_guard lock(mutex_);
  return state_;
}

}  // namespace stampscan::hmi
