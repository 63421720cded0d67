// What `station scan` shows on a terminal: the checks, a progress bar with the step, the live
// counts and the ETA, the scan's summary and each measuring stage; the dry run's plan; a replay's
// comparison with its recording.
#pragma once

#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/part_planner.hpp"
#include "stampscan/jobs/progress.hpp"
#include "stampscan/jobs/scan_job.hpp"

#include <string>
#include <vector>

namespace stampscan::station {

class TerminalObserver final : public jobs::ScanJobObserver {
 public:
  explicit TerminalObserver(bool quiet) : quiet_(quiet) {}
  void runFolder(const std::filesystem::path& dir) override {
    std::printf("  run folder  %s\n", dir.c_str());
    std::fflush(stdout);
  }
  void checkPassed(const std::string& what) override { std::printf("  check       %s\n", what.c_str()); }
  void progress(const acquisition::ScanProgress& p) override {
    if (quiet_) return;
    char text[160];
    std::snprintf(text, sizeof text, "%s  %llu profiles, ETA %.0f s", p.doing.c_str(),
                  static_cast<unsigned long long>(p.profiles), p.remaining_s);
    bar_.update(text, p.steps ? static_cast<double>(p.step) / static_cast<double>(p.steps) : 0.0);
  }
  void safetyEvent(acquisition::FaultKind, const std::string& what) override { std::printf("  safety      %s\n", what.c_str()); }
  void scanDone(const acquisition::ScanRunResult& r) override {
    bar_.finish();
    std::printf("  scan        %zu sweeps and %zu stereo views in %.1f s (the plan's motion: %.1f s); %llu profiles "
                "(%llu lost), %llu positions%s\n",
                r.sweeps_done, r.views_done, r.wall_seconds, r.motion_seconds, static_cast<unsigned long long>(r.profiles),
                static_cast<unsigned long long>(r.lost_profiles), static_cast<unsigned long long>(r.positions),
                r.views_missing ? (", " + std::to_string(r.views_missing) + " views missing").c_str() : "");
    const acquisition::ScanRunResult::TimeSpent& t = r.spent;
    std::printf("  time        moving %.1f s, settling %.1f s, waiting for frames %.1f s, clock pairs %.1f s, digitizer "
                "start/drain/stop %.1f s, other %.1f s\n",
                t.moving, t.settling, t.frames, t.clock_sync, t.digitizer, t.other);
  }
  void stageDone(std::string_view stage, const std::string& text) override {
    bar_.finish();
    std::printf("  %-11.*s %s\n", static_cast<int>(stage.size()), stage.data(), text.c_str());
  }

 private:
  bool quiet_;
  jobs::ProgressBar bar_;
};

// `coverage`: what the plan's part steps are predicted to see of the program's model; null without a
// program (a plan file alone has no model, so neither coverage nor collisions are checked).
inline void printDryRun(const acquisition::ScanPlan& plan, const acquisition::CellConfig& cell,
                        const acquisition::MachineLimits& limits, const std::vector<std::string>& problems,
                        const acquisition::Coverage* coverage) {
  std::printf("station scan --dry-run: plan '%s' on %s\n", plan.name.c_str(), cell.name.c_str());
  std::printf("  part        %s, %s grid\n", plan.part.kind.c_str(), plan.part.grid.c_str());
  std::printf("  steps       %zu sweeps (%zu on the part, %zu on the reference sphere), %zu stereo views\n",
              plan.sweepCount(), plan.sweepCount(acquisition::Scene::Part), plan.sweepCount(acquisition::Scene::ReferenceSphere),
              plan.stereoCount());
  std::printf("  motion      %.1f s\n", acquisition::motionSeconds(plan, limits));
  if (coverage)
    std::printf("  clearance   the head's body checked against the part's model and the fixture along every step and move\n");
  if (coverage)
    std::printf("  coverage    predicted of the model's grid area (%.0f mm^2): laser %.1f %%, stereo %.1f %%, either %.1f %% "
                "(`station plan` says where the rest is)\n",
                coverage->grid_area, 100 * coverage->share(coverage->laser_area),
                100 * coverage->share(coverage->stereo_area), 100 * coverage->share(coverage->either_area));
  else
    std::printf("  coverage    not predicted: no part program, so no nominal model\n");
  for (const std::string& p : problems) std::printf("  problem     %s\n", p.c_str());
  std::printf("  %s\n", problems.empty() ? "the plan can run on this cell" : "the plan cannot run on this cell");
}

}  // namespace stampscan::station
