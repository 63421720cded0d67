// The simulated parts as part programs: their meshes follow the true surface, the dome's STEP surface
// reads back on the dome, and the program folders the simulator writes load as part programs.
#include "stampscan/sim/part_model.hpp"
#include "stampscan/sim/scan_scenario.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <optional>
#include <random>

namespace stampscan::sim {
namespace {

namespace fs = std::filesystem;
using acquisition::NominalModel;

// A scratch folder, removed with its contents.
struct ScratchDir {
  fs::path path = fs::temp_directory_path() / ("stampscan_part_model_" + std::to_string(std::random_device{}()));
  ScratchDir() { fs::create_directories(path); }
  ~ScratchDir() {
    std::error_code ignored;
    fs::remove_all(path, ignored);
  }
};

// The height of a mesh that covers its xy footprint once (a height field, as both parts are): the
// triangles are binned on an xy grid, and the one holding (x, y) interpolates its corners.
class MeshHeights {
 public:
  explicit MeshHeights(const NominalModel& m, double cell = 2.0) : m_(m), cell_(cell) {
    const acquisition::Box3 box = m.bounds();
    x0_ = box.min[0];
    y0_ = box.min[1];
    nx_ = static_cast<std::size_t>((box.max[0] - x0_) / cell_) + 1;
    ny_ = static_cast<std::size_t>((box.max[1] - y0_) / cell_) + 1;
    bins_.resize(nx_ * ny_);
    for (std::size_t k = 0; k < m.triangles.size(); ++k) {
      double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
      for (const std::uint32_t v : m.triangles[k])
        for (int i = 0; i < 2; ++i) {
          lo[i] = std::min(lo[i], m.vertices[v][static_cast<std::size_t>(i)]);
          hi[i] = std::max(hi[i], m.vertices[v][static_cast<std::size_t>(i)]);
        }
      for (std::size_t j = bin(lo[1], y0_, ny_); j <= bin(hi[1], y0_, ny_); ++j)
        for (std::size_t i = bin(lo[0], x0_, nx_); i <= bin(hi[0], x0_, nx_); ++i) bins_[j * nx_ + i].push_back(k);
    }
  }

  std::optional<double> at(double x, double y) const {
    for (const std::size_t k : bins_[bin(y, y0_, ny_) * nx_ + bin(x, x0_, nx_)]) {
      const auto& a = m_.vertices[m_.triangles[k][0]];
      const auto& b = m_.vertices[m_.triangles[k][1]];
      const auto& c = m_.vertices[m_.triangles[k][2]];
      const double det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
      if (std::fabs(det) < 1e-12) continue;
      const double u = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (y - a[1])) / det;
      const double v = ((b[0] - a[0]) * (y - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
      const double eps = 1e-9;
      if (u >= -eps && v >= -eps && u + v <= 1 + eps) return a[2] + u * (b[2] - a[2]) + v * (c[2] - a[2]);
    }
    return std::nullopt;
  }

 private:
  std::size_t bin(double value, double origin, std::size_t n) const {
    const double i = std::floor((value - origin) / cell_);
    return static_cast<std::size_t>(std::clamp(i, 0.0, static_cast<double>(n - 1)));
  }
  const NominalModel& m_;
  double cell_, x0_ = 0, y0_ = 0;
  std::size_t nx_ = 0, ny_ = 0;
  std::vector<std::vector<std::size_t>> bins_;
};

// The largest vertical distance between the mesh and the part at seeded random points of the
// footprint (a little inside its edge); every point must be covered by the mesh.
double worstDeviation(const NominalModel& model, const FormedPart& part, std::size_t samples = 4000) {
  const MeshHeights mesh(model);
  const BlankRect box = part.footprint();
  std::mt19937_64 rng(20260101);
  std::uniform_real_distribution<double> ux(box.min.x() + 0.01, box.max.x() - 0.01), uy(box.min.y() + 0.01, box.max.y() - 0.01);
  double worst = 0;
  for (std::size_t k = 0; k < samples; ++k) {
    const double x = ux(rng), y = uy(rng);
    const std::optional<double> z = mesh.at(x, y);
    if (!z) {
      ADD_FAILURE() << "the mesh does not cover (" << x << ", " << y << ")";
      return 1e9;
    }
    worst = std::max(worst, std::fabs(*z - part.height(x, y)));
  }
  return worst;
}

TEST(PartModel, TheMeshFollowsTheTrueSurface) {
  for (const PartKind kind : {PartKind::Dome, PartKind::Pan}) {
    const std::unique_ptr<FormedPart> part = makePart(kind);
    SCOPED_TRACE(part->name());
    const NominalModel model = partModel(*part, 0.5);
    const acquisition::Box3 box = model.bounds();
    EXPECT_DOUBLE_EQ(box.min[0], part->footprint().min.x());
    EXPECT_DOUBLE_EQ(box.max[1], part->footprint().max.y());
    EXPECT_NEAR(box.min[2], part->minHeight(), 0.05);
    EXPECT_NEAR(box.max[2], part->maxHeight(), 0.05);
    // The chord error of 0.5 mm triangles on the parts' tightest bends (the pan's punch radius).
    const double worst = worstDeviation(model, *part);
    RecordProperty(part->name() + "_mesh_deviation_mm", std::to_string(worst));
    EXPECT_LT(worst, 0.02);
  }
}

TEST(PartModel, TheDomesStepSurfaceReadsBackOnTheDome) {
  ScratchDir dir;
  const std::unique_ptr<FormedPart> dome = makePart(PartKind::Dome);
  acquisition::writeStepSurface(sampleHeights(*dome, 1.0), dir.path / "dome.step", {0.005});
  const NominalModel model = acquisition::loadNominalModel(dir.path / "dome.step");
  EXPECT_GT(model.triangles.size(), 1000u);
  // Approximation (0.005 mm at the samples, between them where the dome's curvature jumps at the
  // die) plus tessellation (0.01 mm): within 0.03 mm of the true dome everywhere.
  const double worst = worstDeviation(model, *dome);
  RecordProperty("step_deviation_mm", std::to_string(worst));
  EXPECT_LT(worst, 0.03);
}

// A part family with parameters is a new part: its program's model, plan and regions are of that
// part, and the virtual cell simulates that part from the program.
TEST(PartModel, AFamilysParametersMakeANewPartAndItsProgram) {
  ScratchDir dir;
  acquisition::SimulationParameters parameters;
  parameters.scale = 0.8;
  parameters.depth_mm = 14;
  parameters.peak_strain = 0.2;
  SimulatedProgramOptions options;
  options.simulation = parameters;
  options.name = "pan-small-4711";
  const fs::path folder = dir.path / "pan-small";
  const acquisition::PartProgram written = writeSimulatedProgram(PartKind::Pan, GridKind::Square, folder, options);
  const acquisition::PartProgram p = acquisition::loadPartProgram(folder);
  EXPECT_EQ(p.name, "pan-small-4711");
  EXPECT_EQ(p.simulation, parameters);
  // The world the virtual cell builds from the program is that part.
  const ScanParams world = worldForProgram(ScanParams{}, p);
  EXPECT_EQ(world.part, PartKind::Pan);
  EXPECT_EQ(world.grid.kind, GridKind::Square);
  EXPECT_DOUBLE_EQ(world.pan.depth, 14);
  EXPECT_DOUBLE_EQ(world.pan.peak_strain, 0.2);
  EXPECT_DOUBLE_EQ(world.pan.half_length, 0.8 * StampedPanParams{}.half_length);
  const std::unique_ptr<FormedPart> part = makePart(world);
  // The nominal model is of that part: its footprint and depth, within the mesh's sampling.
  const acquisition::Box3 box = p.model.bounds();
  const BlankRect footprint = part->footprint();
  EXPECT_NEAR(box.min[0], footprint.min.x(), 1e-4);  // STL stores floats
  EXPECT_NEAR(box.max[1], footprint.max.y(), 1e-4);
  EXPECT_NEAR(box.min[2], -14, 0.05);
  EXPECT_NEAR(box.max[2], 0, 1e-9);
  EXPECT_LT(box.max[0] - box.min[0], 0.85 * (StampedPanPart{}.footprint().max.x() - StampedPanPart{}.footprint().min.x()));
  // Its plan is generated from that part's model; its strain peaks where asked.
  EXPECT_EQ(acquisition::toToml(p.plan), acquisition::toToml(written.plan));
  EXPECT_GT(p.plan.sweepCount(acquisition::Scene::Part), 0u);
  const auto peakOf = [&](const FormedPart& formed) {
    double peak = 0;
    for (const Vec3& q : groundTruth(formed, world.grid).positions) peak = std::max(peak, formed.deformationAt(q.x(), q.y()).major_strain);
    return peak;
  };
  const double peak = peakOf(*part), family_peak = peakOf(StampedPanPart{});  // the family's own: 0.3
  EXPECT_GE(peak, 0.2);
  EXPECT_LT(peak, family_peak - 0.07) << "the family's own peaks at " << family_peak;
  // Without a simulated part the virtual cell has nothing to put on its fixture.
  acquisition::PartProgram real = p;
  real.simulated_part.clear();
  EXPECT_THROW(worldForProgram(ScanParams{}, real), std::runtime_error);
}

TEST(PartModel, SimulatedProgramsLoadAsPartPrograms) {
  ScratchDir dir;
  for (const PartKind kind : {PartKind::Dome, PartKind::Pan}) {
    for (const GridKind grid : {GridKind::Circle, GridKind::Square}) {
      const std::unique_ptr<FormedPart> part = makePart(kind);
      SCOPED_TRACE(part->name() + ", " + toString(grid));
      const fs::path folder = dir.path / (part->name() + "-" + toString(grid));
      const acquisition::PartProgram written = writeSimulatedProgram(kind, grid, folder);
      const acquisition::PartProgram p = acquisition::loadPartProgram(folder);
      EXPECT_EQ(p.name, written.name);
      EXPECT_EQ(p.simulated_part, part->name());
      EXPECT_EQ(p.grid.kind, toString(grid));
      EXPECT_EQ(p.model_file, kind == PartKind::Dome ? "model.step" : "model.stl");
      EXPECT_EQ(p.regions, written.regions);
      EXPECT_EQ(acquisition::toToml(p), acquisition::toToml(written));
      // The plan is generated from the part's model for the built-in cell: laser and stereo, no
      // calibration scenes, for the program's grid.
      EXPECT_EQ(acquisition::toToml(p.plan), acquisition::toToml(written.plan));
      EXPECT_NE(p.plan.name.find("generated from its nominal model"), std::string::npos) << p.plan.name;
      EXPECT_EQ(p.plan.part.grid, toString(grid));
      EXPECT_GT(p.plan.sweepCount(acquisition::Scene::Part), 0u);
      EXPECT_GT(p.plan.stereoCount(acquisition::Scene::Part), 0u);
      EXPECT_EQ(p.plan.sweepCount(acquisition::Scene::ReferenceSphere), 0u);
      // The model read back is the part (checked loosely here; closely in the tests above).
      EXPECT_LT(worstDeviation(p.model, *part, 300), 0.03);
    }
  }
}

}  // namespace
}  // namespace stampscan::sim
