// `station fit IN -o OUT`: fit the WLS surface to a cloud and write one projected point per input
// point (contract in ARCHITECTURE.md), optionally a viewing mesh.
#include "stampscan/fitting/mesh.hpp"
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/fitting/surface_fit.hpp"
#include "stampscan/fitting/text_io.hpp"
#include "stampscan/station/colormap.hpp"
#include "stampscan/station/commands.hpp"
#include "stampscan/station/fit_runner.hpp"
#include "stampscan/station/progress.hpp"

#include <tbb/global_control.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <cstdio>
#include <map>
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

FitParams fitParamsFrom(const std::string& method, const std::string& bandwidth, const std::string& kernel,
                        const std::string& scalar, int sig_r, const std::vector<double>& viewpoint) {
  FitParams params;
  params.method = parseFitMethod(method);
  if (bandwidth != "auto") {
    std::size_t used = 0;
    double h = 0;
    try {
      h = std::stod(bandwidth, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != bandwidth.size() || !(h > 0) || !std::isfinite(h))
      throw std::invalid_argument("--bandwidth must be 'auto' or a positive length in mm, got '" + bandwidth + "'");
    params.bandwidth = h;
  }
  params.kernel = parseKernelType(kernel);
  params.scalar = parseScalarFieldType(scalar);
  params.sig.r = sig_r;
  if (!viewpoint.empty()) {
    params.orientation.mode = OrientationMode::TowardsViewpoint;
    params.orientation.viewpoint = Vec3(viewpoint[0], viewpoint[1], viewpoint[2]);
  }
  return params;
}

FitOutcome runFit(const Cloud& input, FitParams params, const MeshRequest* mesh_request, bool show_progress) {
  std::unique_ptr<ProgressBar> bar;
  if (show_progress) {
    bar = std::make_unique<ProgressBar>();
    params.progress = [&bar](const std::string& stage, double f) { bar->update(stage, f); };
  }
  FitOutcome outcome;
  FittedSurface fitted(input, params);
  outcome.surface = fitted.projectAll(&outcome.stats);
  if (mesh_request) {
    MeshParams mp;
    mp.progress = params.progress;
    const auto t0 = std::chrono::steady_clock::now();
    outcome.mesh = meshSurface(fitted, outcome.surface, mp, &outcome.mesh_stats);
    outcome.mesh_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  if (bar) bar->finish();
  return outcome;
}

namespace {
// "  time        1.234 s (stage 0.100, ...)", aligned under the summary's other lines.
void printTimes(const char* label, double seconds, const std::map<std::string, double>& stages) {
  std::printf("  %-11s %.3f s (", label, seconds);
  bool first = true;
  for (const auto& [stage, sec] : stages) {
    std::printf("%s%s %.3f", first ? "" : ", ", stage.c_str(), sec);
    first = false;
  }
  std::printf(")\n");
}
}  // namespace

ShapeAndStrain runShapeAndStrainFit(const Cloud& shape, const Cloud& elements, bool show_progress) {
  std::unique_ptr<ProgressBar> bar;
  ShapeAndStrainParams params;
  if (show_progress) {
    bar = std::make_unique<ProgressBar>();
    params.shape.progress = [&bar](const std::string& stage, double f) { bar->update(stage, f); };
  }
  ShapeAndStrain fit = fitShapeAndStrain(shape, elements, params);
  if (bar) bar->finish();
  colorByStrain(fit.surface);
  colorByStrain(fit.mesh.vertices);
  return fit;
}

void printShapeAndStrainSummary(const ShapeAndStrain& fit) {
  const FitStats& s = fit.shape_stats;
  std::printf("  shape       %zu points: bandwidth %.3g .. %.3g mm (median %.3g)%s\n", fit.shape_points, s.bandwidth.min,
              s.bandwidth.max, s.bandwidth.median, s.widened ? ", widened where the shape allows" : "");
  std::printf("  strain      %zu grid elements %.3g mm apart: bandwidth %.3g .. %.3g mm (median %.3g)\n", fit.carriers,
              fit.carrier_spacing, fit.strain_bandwidth.min, fit.strain_bandwidth.max, fit.strain_bandwidth.median);
  std::printf("  surface     %zu points, %zu without strain (beyond the grid), %zu not converged\n", fit.surface.size(),
              fit.without_strain, fit.not_converged);
  if (!fit.mesh.triangles.empty())
    std::printf("  mesh        %zu vertices, %zu triangles, cell %.3g mm\n", fit.mesh_stats.vertices, fit.mesh_stats.triangles,
                fit.mesh_stats.cell_size);
  printTimes("fit time", fit.seconds, s.stage_seconds);
}

void printFitSummary(const ReadReport& read, const FitParams& params, const FitOutcome& o, bool with_mesh) {
  const FitStats& s = o.stats;
  std::printf("  points      %zu read, %zu skipped (non-finite)\n", read.points_read, read.skipped_nonfinite);
  std::printf("  method      %s\n", toString(params.method).c_str());
  std::printf("  bandwidth   %.4g .. %.4g mm (median %.4g)%s\n", s.bandwidth.min, s.bandwidth.max, s.bandwidth.median,
              s.widened ? ", widened where the shape allows" : "");
  std::printf("  iterations  mean %.2f, max %d, not converged %zu\n", s.mean_iterations, s.max_iterations, s.not_converged);
  if (s.invalid) std::printf("  unfitted    %zu points had no weighted neighbours and were left in place\n", s.invalid);
  if (s.anchors) std::printf("  anchors     %zu local fits (bandwidth chosen at %zu probes)\n", s.anchors, s.probes);
  std::printf("  normals     oriented over %zu connected piece(s)\n", s.orientation_components);
  if (params.method == FitMethod::Sig) std::printf("  r-SIG       %zu edges, %zu pruned\n", s.sig_edges, s.sig_pruned);
  printTimes("time", s.seconds, s.stage_seconds);
  if (with_mesh)
    std::printf("  mesh        %zu vertices, %zu triangles, cell %.3g mm, %.3f s\n", o.mesh_stats.vertices,
                o.mesh_stats.triangles, o.mesh_stats.cell_size, o.mesh_seconds);
}

void colorByStrain(Cloud& cloud) {
  if (!cloud.hasStrain()) return;
  // Thickness strain is negative where the sheet thins: map the most thinning to red.
  std::vector<double> thinning(cloud.strain.size());
  for (std::size_t i = 0; i < thinning.size(); ++i) thinning[i] = -cloud.strain[i];
  const auto range = displayRange(thinning);
  cloud.colors = colorize(thinning, range[0], range[1]);
}

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
    FitParams params = fitParamsFrom(opt->method, opt->bandwidth, opt->kernel, opt->scalar, opt->sig_r, opt->viewpoint);
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
    MeshRequest mesh_request;
    FitOutcome outcome = runFit(input, params, opt->mesh.empty() ? nullptr : &mesh_request, !opt->quiet);
    PlyWriteOptions write;
    write.format = opt->ascii ? PlyFormat::Ascii : PlyFormat::BinaryLittleEndian;
    write.precision = opt->doubles ? PlyPrecision::Double : PlyPrecision::Float;
    write.comment = "StampScan fit, method " + toString(params.method);
    if (opt->colors) colorByStrain(outcome.surface);
    else outcome.surface.colors.clear();
    writePly(opt->output, outcome.surface, write);
    if (!opt->mesh.empty()) {
      colorByStrain(outcome.mesh.vertices);
      writePly(opt->mesh, outcome.mesh, write);
    }
    if (!opt->quiet) {
      printFitSummary(read, params, outcome, !opt->mesh.empty());
      std::printf("  wrote       %s%s%s\n", opt->output.c_str(), opt->mesh.empty() ? "" : ", ", opt->mesh.c_str());
    }
    return 0;
  };
}

}  // namespace stampscan::station
