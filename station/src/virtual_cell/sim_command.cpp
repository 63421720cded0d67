// `station sim generate`: simulate a session of the cell (calibration scenes, laser sweeps, stereo
// views of a formed part) and record it as an MCAP trace, as the real devices would have delivered
// it; optionally write the ground truth of every grid element.
#include "stampscan/acquisition/trace/mcap_writer.hpp"
#include "stampscan/acquisition/trace/trace_recorder.hpp"
#include "stampscan/fitting/atomic_file.hpp"
#include "stampscan/sim/grid.hpp"
#include "stampscan/sim/scan_scenario.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/jobs/progress.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <stdexcept>

namespace stampscan::station {

namespace {

struct GenerateOptions {
  std::string output;
  std::string truth;
  std::string part = "dome";
  std::string grid = "circle";
  std::string sensors = "laser,stereo,calibration";
  std::uint64_t seed = 1;
  bool quick = false;
  double image_scale = 0;  // 0: the preset's
  int bits = 8;
  std::string compression = "zstd";
  double scale = 1;     // lateral size factor of the part
  double depth = 0;     // mm; 0: the part's default
  double strain = -1;   // strain level; negative: the part's default
};

void checkOutputFolder(const std::string& file, const char* what) {
  const auto parent = std::filesystem::absolute(file).parent_path();
  if (!std::filesystem::is_directory(parent))
    throw std::runtime_error(std::string(what) + " folder '" + parent.string() + "' does not exist");
}

sim::ScanParams paramsFrom(const GenerateOptions& o) {
  sim::ScanParams p = o.quick ? sim::ScanParams::quick() : sim::ScanParams{};
  if (o.part == "dome") p.part = sim::PartKind::Dome;
  else if (o.part == "pan") p.part = sim::PartKind::Pan;
  else throw std::invalid_argument("unknown part '" + o.part + "' (expected dome or pan)");
  p.grid.kind = sim::gridKindFromString(o.grid);
  p.laser = p.stereo = p.calibration = false;
  std::stringstream list(o.sensors);
  for (std::string item; std::getline(list, item, ',');) {
    if (item == "laser") p.laser = true;
    else if (item == "stereo") p.stereo = true;
    else if (item == "calibration") p.calibration = true;
    else throw std::invalid_argument("unknown sensor set '" + item + "' in --sensors (expected laser, stereo, calibration)");
  }
  if (!p.laser && !p.stereo && !p.calibration) throw std::invalid_argument("--sensors names nothing to simulate");
  // Size, depth and strain level of the part.
  p.dome.blank_half_size *= o.scale;
  p.dome.die_radius *= o.scale;
  p.pan.half_length *= o.scale;
  p.pan.half_width *= o.scale;
  p.pan.pocket_a *= o.scale;
  p.pan.pocket_b *= o.scale;
  p.pan.wall_width *= o.scale;
  p.pan.dome_radius *= o.scale;
  if (o.depth > 0) p.dome.depth = p.pan.depth = o.depth;
  if (o.strain >= 0) p.dome.pole_strain = p.pan.peak_strain = o.strain;
  p.seed = o.seed;
  if (o.image_scale > 0) p.image_scale = o.image_scale;
  p.camera_sensor.bits = o.bits;
  return p;
}

std::string megabytes(std::uintmax_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f MB", static_cast<double>(bytes) / 1e6);
  return buf;
}

}  // namespace

CommandRunner addSimCommand(CLI::App& app) {
  auto opt = std::make_shared<GenerateOptions>();
  CLI::App* sim_cmd = app.add_subcommand("sim", "The simulated cell: generate scan traces with ground truth, serve the virtual devices");
  sim_cmd->require_subcommand(1);
  CLI::App* gen = sim_cmd->add_subcommand(
      "generate", "Simulate a scan session (calibration scenes, laser sweeps, stereo views) into an MCAP trace");
  gen->add_option("-o,--output", opt->output, "Output trace (.mcap)")->required();
  gen->add_option("--part", opt->part, "Formed part: dome (punch-stretched) or pan (stamped, with walls and flange)")
      ->check(CLI::IsMember({"dome", "pan"}));
  gen->add_option("--grid", opt->grid, "Printed grid: circle or square (2.54 mm)")->check(CLI::IsMember({"circle", "square"}));
  gen->add_option("--sensors", opt->sensors, "Comma-separated: laser, stereo, calibration (default: all)");
  gen->add_option("--scale", opt->scale, "Lateral size of the part relative to the default (dome: 150 mm blank)")
      ->check(CLI::Range(0.3, 2.5));
  gen->add_option("--depth", opt->depth, "Depth of the part in mm (dome: 30, pan: 20)")->check(CLI::Range(1.0, 60.0));
  gen->add_option("--strain", opt->strain, "Strain level: the dome's pole strain (0.12) or the pan's peak strain (0.3)")
      ->check(CLI::Range(0.0, 0.5));
  gen->add_option("--truth", opt->truth, "Also write the ground truth of every grid element (PLY)");
  gen->add_option("--seed", opt->seed, "Random seed (default 1); the same seed gives the same trace");
  gen->add_flag("--quick", opt->quick, "A small session: a region of the part, quarter-resolution images, few poses");
  gen->add_option("--image-scale", opt->image_scale, "Camera resolution factor (1 = 2048x1536)")->check(CLI::Range(0.05, 2.0));
  gen->add_option("--bits", opt->bits, "Camera pixel depth: 8 (mono8) or 16 (mono16)")->check(CLI::IsMember({8, 16}));
  gen->add_option("--compression", opt->compression, "Chunk compression: zstd, lz4 or none")
      ->check(CLI::IsMember({"zstd", "lz4", "none"}));
  const CommandRunner serve = addServeSubcommand(sim_cmd);
  const CommandRunner write_part = addSimPartSubcommand(sim_cmd);
  return [opt, serve, write_part, gen, sim_cmd]() {
    if (sim_cmd->got_subcommand("part")) return write_part();
    if (!gen->parsed()) return serve();
    namespace fs = std::filesystem;
    const sim::ScanParams params = paramsFrom(*opt);
    checkOutputFolder(opt->output, "output");
    if (!opt->truth.empty()) checkOutputFolder(opt->truth, "truth");
    // Written under a temporary name of its own and renamed when complete: a failed or interrupted
    // run leaves no trace file that looks whole, and two runs to one output never share a file.
    fitting::AtomicFile output(opt->output);
    const auto start = std::chrono::steady_clock::now();
    sim::ScanSummary summary;
    std::uintmax_t size = 0;
    {
      trace::McapWriterOptions w;
      w.compression = opt->compression == "zstd" ? trace::Compression::Zstd
                      : opt->compression == "lz4" ? trace::Compression::Lz4
                                                  : trace::Compression::None;
      trace::McapWriter writer(output.temporaryPath(), w);
      trace::TraceRecorder recorder(writer);
      jobs::ProgressBar bar;
      summary = sim::generateScan(params, recorder, [&](double f, std::string_view stage) { bar.update(std::string(stage), f); });
      bar.finish();
      writer.close();
      size = fs::file_size(output.temporaryPath());
      output.commit();
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("station sim generate: %s part, %s grid, seed %llu\n", opt->part.c_str(), opt->grid.c_str(),
                static_cast<unsigned long long>(opt->seed));
    std::printf("  session     %.1f s simulated, generated in %.1f s (%.1fx faster than the scan)\n", summary.scan_seconds,
                seconds, summary.scan_seconds / std::max(seconds, 1e-9));
    std::printf("  laser       %zu profiles, %zu points\n", summary.profiles, summary.laser_points);
    std::printf("  cameras     %zu frames (%dx%d)\n", summary.frames, summary.truth.left.width, summary.truth.left.height);
    std::printf("  CMM         %zu position reports\n", summary.positions);
    std::printf("  wrote       %s: %zu messages, %s\n", opt->output.c_str(), summary.messages, megabytes(size).c_str());
    if (!opt->truth.empty()) {
      const std::unique_ptr<sim::FormedPart> part = sim::makePart(params);
      const fitting::Cloud truth = sim::groundTruth(*part, params.grid, sim::machineFromDatum(params));
      sim::writeGroundTruth(opt->truth, truth);
      std::printf("  truth       %s: %zu grid elements\n", opt->truth.c_str(), truth.size());
    }
    return 0;
  };
}

}  // namespace stampscan::station
