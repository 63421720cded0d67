// The nominal model of a part: the formed part as drawn, a triangle mesh in the part's datum frame
// (millimetres). A part program names it as a file: STL (binary or ASCII) or STEP (AP203/AP214/
// AP242 B-rep, read and tessellated with Open CASCADE). Planning and the comparison of a scan with
// the drawing work on the mesh, whatever file it came from.
//
// Errors throw ModelError (a std::runtime_error) whose message starts with the file and says what
// is wrong: "parts/pan-4711/model.stl: binary STL truncated: 1200 triangles announced, 1199 present".
//
// Thread safety: the STL functions are reentrant on distinct models. Open CASCADE's STEP translation
// keeps process-wide settings (units, schema), which these functions set to the same values on every
// call, and reports through a process-wide messenger, whose printers they hold back while a file is
// translated (so nothing is printed): read or write STEP from one thread at a time.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::acquisition {

class ModelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Box3 {
  std::array<double, 3> min{0, 0, 0}, max{0, 0, 0};
};

struct NominalModel {
  std::vector<std::array<double, 3>> vertices;            // mm, datum frame
  std::vector<std::array<std::uint32_t, 3>> triangles;    // counter-clockwise seen from outside
  std::string source;                                     // the file it came from ("" when made in memory)

  // The vertices' axis-aligned box; all zero for an empty model.
  Box3 bounds() const;
  // The total area of the triangles, mm^2.
  double area() const;
  // Throws ModelError (prefixed with `name`) unless the model has triangles, every index is in
  // range and every coordinate is finite.
  void check(const std::string& name) const;
};

// Reads a model file by its extension: .stl, or .step/.stp (case-insensitive).
NominalModel loadNominalModel(const std::filesystem::path& file);

// STL: binary or ASCII, told apart by the binary layout (84 + 50 n bytes for the n triangles its
// header announces), not by a leading "solid", which many binary writers put in the 80-byte header.
// Shared vertices are merged (bit-identical coordinates). `source_name` prefixes the errors.
NominalModel parseStl(std::string_view bytes, const std::string& source_name);
NominalModel loadStl(const std::filesystem::path& file);
// Writes atomically (a temporary beside the file, renamed when complete). Facet normals are the
// triangles' own.
void writeStl(const NominalModel& model, const std::filesystem::path& file, bool binary = true);
// The model as the bytes of a binary STL (what writeStl writes): e.g. for a browser's 3D view.
std::string binaryStl(const NominalModel& model);

// STEP: every face of the file's shapes, tessellated by BRepMesh_IncrementalMesh with these limits,
// each face's placement and orientation applied.
struct StepTessellation {
  double linear_deflection_mm = 0.01;  // the largest distance between a triangle and its face
  double angular_deflection_rad = 0.1;
};
NominalModel loadStep(const std::filesystem::path& file, const StepTessellation& tessellation = {});

// A surface z = h(x, y) over a rectangle, sampled on a regular grid: heights[j * columns + i] is the
// height at (x0 + i * dx, y0 + j * dy). The STEP writer approximates it with one B-spline face.
struct HeightGrid {
  double x0 = 0, y0 = 0, dx = 1, dy = 1;  // mm
  std::size_t columns = 0, rows = 0;
  std::vector<double> heights;            // mm
};
struct StepSurfaceOptions {
  double tolerance_mm = 0.005;  // the B-spline approximation's 3D tolerance at the samples
  // Up to quintic: at degree 8 the approximation of a smaller dome (scale 0.7) came out with
  // oscillations that Open CASCADE's mesher could not tessellate within gigabytes; more knots of a
  // lower degree meet the tolerance and tessellate in a second.
  int degree_min = 3, degree_max = 5;
};
// Writes the height grid as a STEP file (AP214) holding one face on a B-spline surface, atomically.
// Throws ModelError when the grid is too small or the approximation fails.
void writeStepSurface(const HeightGrid& grid, const std::filesystem::path& file, const StepSurfaceOptions& options = {});

// A regular triangulation of the height grid (two triangles per cell, normals up).
NominalModel meshHeightGrid(const HeightGrid& grid);

}  // namespace stampscan::acquisition
