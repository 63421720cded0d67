// The fit as the station runs it, shared by `station fit`, `station process`, `station sample` and the
// scan job: parameters from command-line words, the fit with a progress bar, the shape-and-strain fit
// of a scan (fitting/shape_and_strain.hpp), and the printed summaries.
#pragma once

#include "stampscan/fitting/mesh.hpp"
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/fitting/shape_and_strain.hpp"
#include "stampscan/fitting/surface_fit.hpp"

#include <memory>
#include <string>
#include <vector>

namespace stampscan::jobs {

// What a fit run makes besides the surface, and whether it shows a progress bar.
struct FitRun {
  bool with_mesh = false;
  bool show_progress = false;
};

struct FitOutcome {
  fitting::Cloud surface;
  fitting::FitStats stats;
  fitting::Mesh mesh;
  fitting::MeshStats mesh_stats;
  double mesh_seconds = 0;
};

fitting::FitParams fitParamsFrom(const std::string& method, const std::string& bandwidth, const std::string& kernel,
                                 const std::string& scalar, int sig_r, const std::vector<double>& viewpoint);
FitOutcome runFit(const fitting::Cloud& input, fitting::FitParams params, const FitRun& run);
// The shape from dense points (a laser's returns, one list per sweep: each is fitted as a piece and
// the pieces joined), with a progress bar; then the strain of the grid elements on it
// (fitting/shape_and_strain.hpp), the surface and mesh coloured by strain. A scan fits each sweep
// while the next is scanned; `station process` fits them in a row, with the same parameters, so
// both give the same surface.
std::unique_ptr<fitting::ShapeSurface> runShapeFit(std::vector<std::vector<fitting::Vec3>> sweeps, bool show_progress);
fitting::ShapeAndStrain runStrainOnShape(const fitting::ShapeSurface& shape, const fitting::Cloud& elements);
void printShapeAndStrainSummary(const fitting::ShapeAndStrain& fit);
void printFitSummary(const fitting::ReadReport& read, const fitting::FitParams& params, const FitOutcome& outcome,
                     bool with_mesh);
// Colours a cloud (or mesh vertices) by thinning with the temperature map (no-op without strain).
void colorByStrain(fitting::Cloud& cloud);

}  // namespace stampscan::jobs
