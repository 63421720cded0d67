#include "stop_signals.hpp"

#include <atomic>
#include <chrono>
#include <csignal>

namespace stampscan::station {

namespace {

std::atomic<int> g_stop_signal{0};
extern "C" void onStopSignal(int sig) { g_stop_signal = sig; }

}  // namespace

StopSignalGuard::StopSignalGuard(std::function<void(const std::string& reason)> abort) {
  g_stop_signal = 0;
  previous_int_ = std::signal(SIGINT, onStopSignal);
  previous_term_ = std::signal(SIGTERM, onStopSignal);
  watcher_ = std::jthread([abort = std::move(abort)](std::stop_token stop) {
    while (!stop.stop_requested()) {
      if (const int sig = g_stop_signal.load()) {
        abort(sig == SIGINT ? "operator abort (Ctrl-C)" : "stopped (SIGTERM)");
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
}

StopSignalGuard::~StopSignalGuard() {
  watcher_.request_stop();
  watcher_.join();
  std::signal(SIGINT, previous_int_);
  std::signal(SIGTERM, previous_term_);
}

}  // namespace stampscan::station
