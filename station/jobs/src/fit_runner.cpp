// The fit as the station's commands and jobs run it (fit_runner.hpp): parameters from command-line
// words, the fit with a progress bar, the shape-and-strain fit of a scan, the printed summaries.
#include "stampscan/jobs/fit_runner.hpp"

#include "stampscan/jobs/colormap.hpp"
#include "stampscan/jobs/progress.hpp"

#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <string>

namespace stampscan::jobs {

using namespace stampscan::fitting;

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

FitOutcome runFit(const Cloud& input, FitParams params, const FitRun& run) {
  std::unique_ptr<ProgressBar> bar;
  if (run.show_progress) {
    bar = std::make_unique<ProgressBar>();
    params.progress = [&bar](const std::string& stage, double f) { bar->update(stage, f); };
  }
  FitOutcome outcome;
  FittedSurface fitted(input, params);
  outcome.surface = fitted.projectAll(&outcome.stats);
  if (run.with_mesh) {
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

std::unique_ptr<ShapeSurface> runShapeFit(std::vector<std::vector<Vec3>> sweeps, bool show_progress) {
  std::unique_ptr<ProgressBar> bar;
  ShapeAndStrainParams params;
  if (show_progress) bar = std::make_unique<ProgressBar>();
  std::vector<std::unique_ptr<ShapePiece>> pieces;
  for (std::size_t k = 0; k < sweeps.size(); ++k) {
    if (sweeps[k].empty()) continue;
    FitParams piece_params = params.shape;
    const std::string prefix = "sweep " + std::to_string(k + 1) + " of " + std::to_string(sweeps.size()) + ": ";
    if (bar) piece_params.progress = [&bar, prefix](const std::string& stage, double f) { bar->update(prefix + stage, f); };
    pieces.push_back(std::make_unique<ShapePiece>(std::exchange(sweeps[k], {}), piece_params));
  }
  if (bar) params.shape.progress = [&bar](const std::string& stage, double f) { bar->update(stage, f); };
  auto shape = std::make_unique<ShapeSurface>(std::move(pieces), params);
  if (bar) bar->finish();
  return shape;
}

ShapeAndStrain runStrainOnShape(const ShapeSurface& shape, const Cloud& elements) {
  ShapeAndStrain fit = strainOnShape(shape, elements);
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

}  // namespace stampscan::jobs
