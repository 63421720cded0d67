// `station sample`: write the synthetic sample pan as a scanned-looking Cloud4D PLY (a cloud for
// trying `station fit` and the fitter's benchmark without a cell).
// `station demo`: the fitter alone on that sample: make it, fit it, write the fitted cloud and a
// strain-coloured mesh, and report the error against the known true surface.
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/sim/sample_cloud.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/jobs/fit_runner.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

namespace stampscan::station {

using namespace stampscan::fitting;

namespace {
struct SampleOptions {
  std::string output;
  std::size_t points = 200000;
  std::uint64_t seed = 1;
  double noise = 0.05;
  bool ascii = false;
};

sim::SampleCloud makeSample(const SampleOptions& o) {
  sim::SampleCloudParams sp;
  sp.target_points = o.points;
  sp.seed = o.seed;
  sp.noise_sigma = o.noise;
  return sim::makeSampleCloud(sim::PanPart{}, sp);
}

void addSampleOptions(CLI::App* cmd, SampleOptions& o) {
  cmd->add_option("--points", o.points, "Approximate number of points (default 200000)")->check(CLI::Range(1000, 50000000));
  cmd->add_option("--seed", o.seed, "Random seed (default 1)");
  cmd->add_option("--noise", o.noise, "Noise standard deviation in mm (default 0.05)")->check(CLI::Range(0.0, 5.0));
}

double strainRms(const std::vector<double>& a, const std::vector<double>& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]) * (a[i] - b[i]);
  return a.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(a.size()));
}
}  // namespace

CommandRunner addSampleCommand(CLI::App& app) {
  auto opt = std::make_shared<SampleOptions>();
  CLI::App* cmd = app.add_subcommand("sample", "Write the synthetic sample part as a scanned-looking Cloud4D PLY");
  cmd->add_option("-o,--output", opt->output, "Output PLY")->required();
  addSampleOptions(cmd, *opt);
  cmd->add_flag("--ascii", opt->ascii, "Write ASCII PLY");
  return [opt]() {
    const sim::SampleCloud sample = makeSample(*opt);
    PlyWriteOptions w;
    w.format = opt->ascii ? PlyFormat::Ascii : PlyFormat::BinaryLittleEndian;
    w.comment = "StampScan sample pan, seed " + std::to_string(opt->seed);
    writePly(opt->output, sample.cloud, w);
    std::printf("wrote %s: %zu points (%zu laser, %zu stereo, %zu outliers)\n", opt->output.c_str(), sample.cloud.size(),
                sample.laser_points, sample.stereo_points, sample.outliers);
    return 0;
  };
}

CommandRunner addDemoCommand(CLI::App& app) {
  auto opt = std::make_shared<SampleOptions>();
  opt->output = "stampscan-demo";
  CLI::App* cmd = app.add_subcommand("demo", "Fit the built-in sample part and write a strain-coloured result to look at");
  cmd->add_option("-o,--output", opt->output, "Output folder (default ./stampscan-demo)");
  addSampleOptions(cmd, *opt);
  return [opt]() {
    namespace fs = std::filesystem;
    fs::create_directories(opt->output);
    const fs::path dir(opt->output);
    std::printf("station demo: sample stamped pan, about %zu points\n", opt->points);
    const sim::PanPart part;
    const sim::SampleCloud sample = makeSample(*opt);
    PlyWriteOptions w;
    w.comment = "StampScan sample pan, seed " + std::to_string(opt->seed);
    writePly(dir / "sample.ply", sample.cloud, w);

    ReadReport read;
    read.points_read = sample.cloud.size();
    const FitParams params;
    jobs::FitOutcome outcome = jobs::runFit(sample.cloud, params, jobs::FitRun{.with_mesh = true, .show_progress = true});
    jobs::colorByStrain(outcome.surface);
    jobs::colorByStrain(outcome.mesh.vertices);
    w.comment = "StampScan fit of the sample pan, method auto";
    writePly(dir / "fitted.ply", outcome.surface, w);
    writePly(dir / "mesh.ply", outcome.mesh, w);
    jobs::printFitSummary(read, params, outcome, true);

    const sim::SurfaceError before = sim::surfaceError(part, sample.cloud.positions);
    const sim::SurfaceError after = sim::surfaceError(part, outcome.surface.positions);
    std::printf("  accuracy    distance to the true surface: RMS %.4f mm -> %.4f mm (max %.3f -> %.3f)\n", before.rms,
                after.rms, before.max, after.max);
    std::printf("              thickness strain RMS error: %.4f -> %.4f\n", strainRms(sample.cloud.strain, sample.true_strain),
                strainRms(outcome.surface.strain, sample.true_strain));
    std::printf("  wrote       %s, %s, %s (open them in MeshLab or CloudCompare)\n", (dir / "sample.ply").c_str(),
                (dir / "fitted.ply").c_str(), (dir / "mesh.ply").c_str());
    return 0;
  };
}

}  // namespace stampscan::station
