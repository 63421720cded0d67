// `station fit IN -o OUT`: fit the WLS surface to a cloud and write one projected point per input
// point (contract in ARCHITECTURE.md), optionally a viewing mesh.
// A thin caller of fit_runner.hpp.
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/fitting/text_io.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/jobs/fit_runner.hpp"

#include <tbb/global_control.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>

namespace stampscan::station {

using namespace stampscan::fitting;

namespace {
struct FitOptions {
  std::string input, output, mesh;
  std::string method = "auto", bandwidth = "auto", kernel = "gaussian", scalar = "smooth";
  int sig_r = 7;
  bool ascii = false, doubles = false, colors = false, quiet = false;
  std::string widen = "auto";
  int threads = 0;
  std::vector<double> viewpoint;
};
}  // namespace

CommandRunner addFitCommand(CLI::App& app) {
  auto opt = std::make_shared<FitOptions>();
  CLI::App* cmd = app.add_subcommand("fit", "Fit the WLS implicit surface to a cloud; one output point per input point");
  cmd->add_option("input", opt->input, "Input cloud (.ply, .xyz, .txt, .csv)")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", opt->output, "Output PLY: x y z nx ny nz [strain]")->required();
  cmd->add_option("--method", opt->method,
                  "auto (default: adaptive quadric patches, most accurate) | apss (robust sphere fit at every "
                  "point) | euclidean (paper Sec. 3.2) | sig (r-SIG, Sec. 3.3) | gaussian (Sec. 4)")
      ->check(CLI::IsMember({"auto", "apss", "euclidean", "sig", "gaussian"}));
  cmd->add_option("--bandwidth", opt->bandwidth, "Kernel bandwidth h in mm, or 'auto' (default)");
  cmd->add_option("--sig-r", opt->sig_r, "r of the r-SIG (method sig), default 7")->check(CLI::Range(1, 64));
  cmd->add_option("--kernel", opt->kernel, "gaussian (default) | cubic, for methods euclidean and sig")
      ->check(CLI::IsMember({"gaussian", "cubic"}));
  cmd->add_option("--scalar", opt->scalar, "Strain field: smooth (default) | shepard (paper Eqs. 15-16)")
      ->check(CLI::IsMember({"smooth", "shepard"}));
  cmd->add_option("--viewpoint", opt->viewpoint, "Orient normals towards this point X Y Z (default: propagate, facing +z)")
      ->expected(3);
  cmd->add_option("--mesh", opt->mesh, "Also write a triangle mesh of the surface, coloured by strain");
  cmd->add_option("--widen", opt->widen,
                  "Method auto: widen the bandwidth where the surface allows (auto: when the data are dense against "
                  "the shape, default | always | never)")
      ->check(CLI::IsMember({"auto", "always", "never"}));
  cmd->add_flag("--ascii", opt->ascii, "Write ASCII PLY (default binary little-endian)");
  cmd->add_flag("--double", opt->doubles, "Write double precision (default float)");
  cmd->add_flag("--colors", opt->colors, "Add red green blue from the strain temperature map");
  cmd->add_option("--threads", opt->threads, "Worker threads (default: all cores)")->check(CLI::Range(1, 1024));
  cmd->add_flag("-q,--quiet", opt->quiet, "Print nothing but errors");
  return [opt]() {
    std::unique_ptr<tbb::global_control> threads;
    if (opt->threads > 0)
      threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      static_cast<std::size_t>(opt->threads));
    FitParams params = jobs::fitParamsFrom(opt->method, opt->bandwidth, opt->kernel, opt->scalar, opt->sig_r, opt->viewpoint);
    params.anchored.widen = opt->widen != "never";
    if (opt->widen == "always") params.anchored.widen_min_capped_share = 0.0;
    // Check where the results go before the work: a missing folder should not cost a fit, and a
    // failure after the first file is written would leave half a result.
    for (const std::string& path : {opt->output, opt->mesh}) {
      if (path.empty()) continue;
      const std::filesystem::path parent = std::filesystem::absolute(path).parent_path();
      if (!std::filesystem::is_directory(parent))
        throw std::runtime_error(path + ": cannot write there: folder " + parent.string() + " does not exist");
    }
    ReadReport read;
    const Cloud input = readCloud(opt->input, &read);
    if (!opt->quiet) std::printf("station fit %s\n", opt->input.c_str());
    jobs::FitOutcome outcome = jobs::runFit(input, params, jobs::FitRun{.with_mesh = !opt->mesh.empty(), .show_progress = !opt->quiet});
    PlyWriteOptions write;
    write.format = opt->ascii ? PlyFormat::Ascii : PlyFormat::BinaryLittleEndian;
    write.precision = opt->doubles ? PlyPrecision::Double : PlyPrecision::Float;
    write.comment = "StampScan fit, method " + toString(params.method);
    if (opt->colors) jobs::colorByStrain(outcome.surface);
    else outcome.surface.colors.clear();
    writePly(opt->output, outcome.surface, write);
    if (!opt->mesh.empty()) {
      jobs::colorByStrain(outcome.mesh.vertices);
      writePly(opt->mesh, outcome.mesh, write);
    }
    if (!opt->quiet) {
      jobs::printFitSummary(read, params, outcome, !opt->mesh.empty());
      std::printf("  wrote       %s%s%s\n", opt->output.c_str(), opt->mesh.empty() ? "" : ", ", opt->mesh.c_str());
    }
    return 0;
  };
}

}  // namespace stampscan::station
