// A synthetic run folder for the report tests: a flat 100 x 60 mm plate in z = 0 with a 2.5 mm grid,
// stretched in plane strain with a major true strain growing along x (eps1 = kPlateGradient * x), so
// that the strain at every place of the maps is known. mesh.ply holds the plate as triangles with
// normals up, cloud4d.ply the grid elements at the same points, run.json the part's facts.
#pragma once

#include "stampscan/fitting/atomic_file.hpp"
#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/ply_io.hpp"

#include <cairo.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <random>
#include <set>
#include <string>

namespace stampscan::report::test {

namespace fs = std::filesystem;

// Up to e1 = exp(0.35) - 1 = 41.9% at x = 100: insufficient stretch at the left edge, failure (over
// the DC04 FLC0 of 37.4%) in the last columns.
inline constexpr double kPlateGradient = 0.0035;
inline constexpr double kPlatePitch = 2.5;

inline double plateMajorTrue(double x) { return kPlateGradient * x; }

struct PlateRun {
  fitting::Mesh mesh;
  fitting::Cloud elements;
};

inline PlateRun makePlate() {
  PlateRun p;
  constexpr int nx = 41, ny = 25;  // 0..100 mm by 0..60 mm
  fitting::Cloud& v = p.mesh.vertices;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const double x = kPlatePitch * i, y = kPlatePitch * j;
      v.positions.emplace_back(x, y, 0);
      v.normals.emplace_back(0, 0, 1);
      v.strain.push_back(-plateMajorTrue(x));
    }
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const auto a = static_cast<std::uint32_t>(j * nx + i);
      p.mesh.triangles.push_back({{a, a + 1, a + nx + 1}});
      p.mesh.triangles.push_back({{a, a + nx + 1, a + nx}});
    }
  p.elements.positions = v.positions;
  p.elements.normals = v.normals;
  p.elements.strain = v.strain;
  for (const auto& pos : v.positions) {
    p.elements.scalars["major_strain"].push_back(plateMajorTrue(pos.x()));
    p.elements.scalars["minor_strain"].push_back(0.0);
  }
  return p;
}

inline void writePlateRun(const fs::path& dir, const PlateRun& p, bool with_mesh = true) {
  fs::create_directories(dir);
  fitting::writePly(dir / "cloud4d.ply", p.elements);
  if (with_mesh) fitting::writePly(dir / "mesh.ply", p.mesh);
  fitting::writeFileAtomically(
      dir / "run.json", R"({"part_id": "plate-7", "plan": "test plan", "cell": "test cell", "program": "OP20"})");
}

// The names in a folder, to check that a failure left it as it was.
inline std::set<std::string> folderEntries(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

// A scratch folder per test, removed afterwards.
class ScratchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device device;
    root_ =
        fs::temp_directory_path() / ("stampscan_report_test_" + std::to_string(device()) + std::to_string(device()));
    fs::create_directories(root_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(root_, ignored);
  }
  const fs::path& root() const { return root_; }

 private:
  fs::path root_;
};

// A PNG read back for pixel checks.
class Png {
 public:
  explicit Png(const fs::path& file)
      : surface_(cairo_image_surface_create_from_png(file.c_str()), cairo_surface_destroy) {
    if (cairo_surface_status(surface_.get()) != CAIRO_STATUS_SUCCESS)
      throw std::runtime_error(file.string() + ": not a PNG");
    cairo_surface_flush(surface_.get());
  }
  int width() const { return cairo_image_surface_get_width(surface_.get()); }
  int height() const { return cairo_image_surface_get_height(surface_.get()); }
  // Red, green, blue of pixel (x, y) (opaque images: no premultiplication to undo).
  std::array<int, 3> at(int x, int y) const {
    const unsigned char* data = cairo_image_surface_get_data(surface_.get());
    const int stride = cairo_image_surface_get_stride(surface_.get());
    const auto word = *reinterpret_cast<const std::uint32_t*>(data + static_cast<std::ptrdiff_t>(y) * stride + 4 * x);
    return {static_cast<int>(word >> 16 & 0xff), static_cast<int>(word >> 8 & 0xff), static_cast<int>(word & 0xff)};
  }

 private:
  std::unique_ptr<cairo_surface_t, void (*)(cairo_surface_t*)> surface_;
};

}  // namespace stampscan::report::test
