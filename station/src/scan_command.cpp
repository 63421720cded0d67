// `station scan`: a part on the cell, from the interlocks to its measured strain. A thin caller:
// acquisition::ScanRunner plays the plan on the cell into the trace, registration::measureScan
// measures it, fitting fits the surface. Without --cell it hosts the virtual cell in this process
// (the part, sphere and plate in one simulated world) and talks to it only through the drivers on
// loopback, as to a real cell.
#include "stampscan/acquisition/cell_config.hpp"
#include "stampscan/acquisition/scan_runner.hpp"
#include "stampscan/acquisition/trace/mcap_writer.hpp"
#include "stampscan/acquisition/trace/trace_recorder.hpp"
#include "stampscan/fitting/kdtree.hpp"
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/registration/measure_scan.hpp"
#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/virtual_cell.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/station/fit_runner.hpp"
#include "stampscan/station/progress.hpp"
#include "virtual_digitizer_host.hpp"

#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <thread>

namespace stampscan::station {

namespace fs = std::filesystem;

namespace {

struct ScanOptions {
  std::string cell, plan, part = "pan", grid = "circle", part_id = "sample", runs = "stampscan-runs";
  bool dry_run = false, whole_part = false, quiet = false;
  std::uint64_t seed = 1;
};

// Ctrl-C and SIGTERM: the handler only sets a flag; a watcher thread turns it into an operator abort.
std::atomic<int> g_stop_signal{0};
extern "C" void onStopSignal(int sig) { g_stop_signal = sig; }

class TerminalObserver final : public acquisition::ScanObserver {
 public:
  explicit TerminalObserver(bool quiet) : quiet_(quiet) {}
  void checkPassed(const std::string& what) override { std::printf("  check       %s\n", what.c_str()); }
  void progress(const acquisition::ScanProgress& p) override {
    if (quiet_) return;
    char text[160];
    std::snprintf(text, sizeof text, "%s  %llu profiles, ETA %.0f s", p.doing.c_str(),
                  static_cast<unsigned long long>(p.profiles), p.remaining_s);
    bar_.update(text, p.steps ? static_cast<double>(p.step) / static_cast<double>(p.steps) : 0.0);
  }
  void safetyEvent(const std::string& what) override { std::printf("  safety      %s\n", what.c_str()); }
  void finish() { bar_.finish(); }

 private:
  bool quiet_;
  ProgressBar bar_;
};

class PrintingMeasureObserver final : public registration::MeasureObserver {
 public:
  void stageDone(std::string_view stage, const std::string& text) override {
    std::printf("  %-11.*s %s\n", static_cast<int>(stage.size()), stage.data(), text.c_str());
  }
};

std::string runFolderName(const std::string& part_id) {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", &tm);
  std::string id;
  for (char c : part_id) id.push_back(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_');
  return std::string(stamp) + "-" + (id.empty() ? "part" : id);
}

void writeJsonAtomically(const fs::path& file, const nlohmann::json& j) {
  const fs::path tmp = file.string() + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp);
    out << j.dump(2) << "\n";
    if (!out) throw std::runtime_error(file.string() + ": cannot be written");
  }
  fs::rename(tmp, file);
}

struct Accuracy {
  std::size_t matched = 0;
  double position_rms = 0, strain_rms = 0;
};

// Every measured element against the nearest true grid element of the simulated part.
Accuracy accuracyAgainst(const fitting::Cloud& measured, const fitting::Cloud& truth) {
  Accuracy a;
  const fitting::KdTree tree(truth.positions);
  std::vector<fitting::Neighbor> nn;
  double sp = 0, ss = 0;
  const auto& ms = measured.strain;
  const auto& ts = truth.strain;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    tree.knn(measured.positions[i], 1, nn);
    if (nn.empty() || nn[0].distance_sq > 0.5 * 0.5) continue;
    ++a.matched;
    sp += nn[0].distance_sq;
    const double d = ms[i] - ts[nn[0].index];
    ss += d * d;
  }
  if (a.matched) {
    a.position_rms = std::sqrt(sp / static_cast<double>(a.matched));
    a.strain_rms = std::sqrt(ss / static_cast<double>(a.matched));
  }
  return a;
}

}  // namespace

CommandRunner addScanCommand(CLI::App& app) {
  auto opt = std::make_shared<ScanOptions>();
  CLI::App* cmd = app.add_subcommand("scan", "Scan a part on the cell: checks, the plan's sweeps, then the measured "
                                             "strain (default: the sample pan on the built-in virtual cell)");
  cmd->add_option("--cell", opt->cell, "Cell configuration (TOML); default: the built-in virtual cell, hosted here");
  cmd->add_option("--plan", opt->plan, "Scan plan (TOML); default: the built-in plan for --part");
  cmd->add_option("--part", opt->part, "Built-in plan and, on the virtual cell, the part on the fixture")
      ->check(CLI::IsMember({"pan", "dome"}));
  cmd->add_option("--grid", opt->grid, "The virtual part's printed grid")->check(CLI::IsMember({"circle", "square"}));
  cmd->add_option("--part-id", opt->part_id, "The part's id, for the run folder and the record");
  cmd->add_option("-o,--runs", opt->runs, "Folder of run folders (created when missing)");
  cmd->add_flag("--whole-part", opt->whole_part, "Scan the whole part (default: a 40 x 30 mm region, about 20 s)");
  cmd->add_option("--seed", opt->seed, "The virtual cell's seed (sensor noise, the digitizer mount's deviation)");
  cmd->add_flag("--dry-run", opt->dry_run, "Check the plan against the cell and print it; nothing moves");
  cmd->add_flag("-q,--quiet", opt->quiet, "No progress bar");
  return [opt]() {
    const bool virtual_cell = opt->cell.empty();
    const acquisition::CellConfig cell = virtual_cell ? acquisition::virtualCell() : acquisition::loadCellConfig(opt->cell);

    // The virtual world, and the plan for its part (or the plan file).
    sim::ScanParams world = opt->whole_part ? sim::ScanParams{} : sim::ScanParams::quick();
    world.part = opt->part == "dome" ? sim::PartKind::Dome : sim::PartKind::Pan;
    world.grid.kind = sim::gridKindFromString(opt->grid);
    world.seed = opt->seed;
    acquisition::ScanPlan plan = opt->plan.empty() ? sim::planScan(world) : acquisition::loadScanPlan(opt->plan);
    if (opt->plan.empty()) {
      // The runner drives the laser sweeps; the stereo pair is not triggered on a cell yet.
      std::erase_if(plan.steps, [](const acquisition::PlanStep& s) { return std::holds_alternative<acquisition::StereoStep>(s); });
      plan.name = plan.part.kind + ", laser" + (world.calibration ? " with the digitizer's calibration sweeps" : "");
    }
    const acquisition::MachineLimits limits;
    if (opt->dry_run) {
      std::printf("station scan --dry-run: plan '%s' on %s\n", plan.name.c_str(), cell.name.c_str());
      std::printf("  part        %s, %s grid\n", plan.part.kind.c_str(), plan.part.grid.c_str());
      std::printf("  steps       %zu sweeps (%zu on the part, %zu on the reference sphere), %zu stereo views\n",
                  plan.sweepCount(), plan.sweepCount(acquisition::kScenePart), plan.sweepCount(acquisition::kSceneSphere),
                  plan.stereoCount());
      std::printf("  motion      %.1f s\n", acquisition::motionSeconds(plan, limits));
      const auto problems = acquisition::checkPlan(plan, limits);
      for (const std::string& p : problems) std::printf("  problem     %s\n", p.c_str());
      std::printf("  %s\n", problems.empty() ? "the plan can run on this cell" : "the plan cannot run on this cell");
      return problems.empty() ? 0 : 1;
    }

    // The embedded virtual cell: the digitizer first (hosting may re-execute this program, and it
    // must be on the bus before any libusb context exists), then the CMM and the PLC on free ports.
    std::unique_ptr<sim::VirtualCell> vcell;
    sim::VirtualCellOptions vopt;
    vopt.world = world;
    vopt.cmm_port = 0;
    vopt.plc_port = 0;
    if (virtual_cell) vcell = std::make_unique<sim::VirtualCell>(vopt);
    const std::unique_ptr<sim::VirtualDigitizer> vdigitizer =
        hostVirtualDigitizer(cell, vcell ? vcell->digitizerOptions() : sim::VirtualDigitizerOptions{});
    if (vcell) {
      vcell->start();
      if (vdigitizer) vdigitizer->setTimedProfileSource(vcell->profileSource());
    }

    drivers::cmm::IppCmmOptions cmm_options;
    cmm_options.host = cell.cmm.host;
    cmm_options.port = vcell ? vcell->cmm().port() : static_cast<std::uint16_t>(cell.cmm.port);
    cmm_options.device_time_in_reports = cell.cmm_device_time;
    drivers::cmm::IppCmm cmm(cmm_options);
    drivers::plc::ModbusPlcOptions plc_options;
    plc_options.host = cell.plc.host;
    plc_options.port = vcell ? vcell->plc().port() : cell.plc.port;
    plc_options.unit_id = cell.plc_unit_id;
    drivers::plc::ModbusPlc plc(plc_options);
    drivers::digitizer::UsbDigitizerOptions digitizer_options;
    digitizer_options.vendor_id = cell.digitizer_vendor;
    digitizer_options.product_id = cell.digitizer_product;
    digitizer_options.serial = cell.digitizer_serial;
    drivers::digitizer::UsbDigitizer digitizer(digitizer_options);

    const fs::path runs(opt->runs);
    fs::create_directories(runs);
    const fs::path dir = runs / runFolderName(opt->part_id);
    fs::create_directory(dir);
    std::printf("station scan: %s on %s%s\n", plan.name.c_str(), cell.name.c_str(),
                vcell ? " (hosted in this process)" : "");
    std::printf("  run folder  %s\n", dir.c_str());
    std::fflush(stdout);

    acquisition::ScanRunParams params;
    params.limits = limits;
    params.session.part_id = opt->part_id;
    params.session.digitizer_standoff_mm = world.digitizer.standoff;
    params.session.digitizer_measuring_range_mm = world.digitizer.measuring_range;
    params.session.head_from_digitizer_nominal = registration::toRigidPose(sim::nominalDigitizerMount());
    params.session.reference_sphere_radius_mm = world.sphere.radius;

    const acquisition::StationClock clock;
    acquisition::ScanRunResult result;
    {
      trace::McapWriter writer(dir / "trace.mcap");
      trace::TraceRecorder recorder(writer);
      TerminalObserver observer(opt->quiet);
      acquisition::ScanRunner runner({cmm, plc, digitizer}, recorder, clock, &observer);
      g_stop_signal = 0;
      std::signal(SIGINT, onStopSignal);
      std::signal(SIGTERM, onStopSignal);
      std::atomic<bool> done{false};
      std::thread watcher([&] {
        while (!done) {
          if (g_stop_signal) {
            runner.abort(g_stop_signal == SIGINT ? "operator abort (Ctrl-C)" : "stopped (SIGTERM)");
            break;
          }
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
      });
      try {
        result = runner.run(plan, params);
      } catch (const acquisition::ScanError&) {
        // Refused before anything moved: no run to keep.
        done = true;
        watcher.join();
        writer.close();
        std::error_code ignored;
        fs::remove_all(dir, ignored);
        throw;
      } catch (...) {
        done = true;
        watcher.join();
        throw;
      }
      done = true;
      watcher.join();
      std::signal(SIGINT, SIG_DFL);
      std::signal(SIGTERM, SIG_DFL);
      observer.finish();
      writer.close();
    }
    digitizer.disconnect();
    plc.disconnect();
    cmm.disconnect();
    std::printf("  scan        %zu sweeps in %.1f s (the plan's motion: %.1f s); %llu profiles (%llu lost), %llu positions\n",
                result.sweeps_done, result.wall_seconds, result.motion_seconds,
                static_cast<unsigned long long>(result.profiles), static_cast<unsigned long long>(result.lost_profiles),
                static_cast<unsigned long long>(result.positions));
    nlohmann::json run = {{"part_id", opt->part_id},
                          {"plan", plan.name},
                          {"cell", cell.name},
                          {"trace", "trace.mcap"},
                          {"completed", result.completed},
                          {"scan", {{"sweeps", result.sweeps_done},
                                    {"wall_seconds", result.wall_seconds},
                                    {"motion_seconds", result.motion_seconds},
                                    {"profiles", result.profiles},
                                    {"lost_profiles", result.lost_profiles},
                                    {"positions", result.positions}}}};
    for (const auto& d : result.devices)
      run["devices"].push_back({{"family", d.family}, {"model", d.model}, {"serial", d.serial}, {"firmware", d.firmware}});
    if (!result.completed) {
      run["abort_reason"] = result.abort_reason;
      writeJsonAtomically(dir / "run.json", run);
      throw std::runtime_error("the scan was aborted: " + result.abort_reason + " (the trace up to here is in " +
                               (dir / "trace.mcap").string() + ")");
    }

    // Measure, fit, write.
    const auto t0 = std::chrono::steady_clock::now();
    const registration::ScanTrace trace = registration::loadScanTrace(dir / "trace.mcap");
    PrintingMeasureObserver measure_observer;
    const registration::ScanMeasurement m = registration::measureScan(trace, {}, &measure_observer);
    fitting::Cloud cloud = registration::toCloud(m.elements);
    fitting::PlyWriteOptions w;
    w.comment = "StampScan Cloud4D, part " + opt->part_id;
    fitting::writePly(dir / "cloud4d.ply", cloud, w);
    MeshRequest mesh_request;
    FitOutcome fit = runFit(cloud, fitting::FitParams{}, &mesh_request, false);
    colorByStrain(fit.surface);
    colorByStrain(fit.mesh.vertices);
    fitting::writePly(dir / "fitted.ply", fit.surface, w);
    fitting::writePly(dir / "mesh.ply", fit.mesh, w);
    const double measure_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("  measured    %zu grid elements; cloud4d.ply, fitted.ply, mesh.ply (%.1f s after the scan)\n",
                cloud.size(), measure_s);
    run["measurement"] = {{"elements", cloud.size()},
                          {"seconds_after_scan", measure_s},
                          {"digitizer_latency_ms", static_cast<double>(m.digitizer.latency_ns) * 1e-6}};
    if (m.sphere) run["measurement"]["sphere_residual_mm"] = m.sphere->rms_mm;
    if (vcell) {
      const fitting::Cloud truth = sim::groundTruth(vcell->part(), world.grid);
      const Accuracy a = accuracyAgainst(cloud, truth);
      std::printf("  accuracy    against the simulated part: %zu of %zu elements matched, position RMS %.4f mm, "
                  "thickness strain RMS %.4f; latency %.3f ms (true %.3f)\n",
                  a.matched, cloud.size(), a.position_rms, a.strain_rms, static_cast<double>(m.digitizer.latency_ns) * 1e-6,
                  static_cast<double>(vcell->truth().digitizer_latency_ns) * 1e-6);
      run["accuracy"] = {{"matched", a.matched}, {"position_rms_mm", a.position_rms}, {"strain_rms", a.strain_rms},
                         {"true_latency_ms", static_cast<double>(vcell->truth().digitizer_latency_ns) * 1e-6}};
    }
    writeJsonAtomically(dir / "run.json", run);
    std::printf("  results     %s\n", dir.c_str());
    return 0;
  };
}

}  // namespace stampscan::station
