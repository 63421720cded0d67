// Part programs: the nominal model's files (STL both ways, STEP through Open CASCADE), the program
// file, a whole program folder, and the mistakes a program's author makes, each refused with one
// line naming the file, the section and the key.
#include "stampscan/acquisition/nominal_model.hpp"
#include "stampscan/acquisition/part_program.hpp"

#include "../fitting/io_test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>

namespace stampscan::acquisition {
namespace {

namespace fs = std::filesystem;
using fitting::test::TempDir;

std::string readFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void writeText(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

// A unit tetrahedron scaled by 1.5, outward normals; coordinates exact in float.
NominalModel tetrahedron() {
  NominalModel m;
  m.vertices = {{0, 0, 0}, {1.5, 0, 0}, {0, 1.5, 0}, {0, 0, 1.5}};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

// Each triangle's corners: what a model is, whatever the order of its vertex list.
std::vector<std::array<std::array<double, 3>, 3>> corners(const NominalModel& m) {
  std::vector<std::array<std::array<double, 3>, 3>> out;
  for (const auto& t : m.triangles) out.push_back({m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]});
  return out;
}

// The message of what `f` throws (a std::runtime_error), or "" when it does not throw.
template <typename F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

// An error message as the brief demands: one line, starting with the file.
void expectOneLineNaming(const std::string& message, const std::string& file, const std::string& what) {
  EXPECT_EQ(message.rfind(file, 0), 0u) << message;
  EXPECT_NE(message.find(what), std::string::npos) << "expected \"" << what << "\" in: " << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
}

TEST(NominalModel, BoundsAndArea) {
  const NominalModel m = tetrahedron();
  const Box3 box = m.bounds();
  EXPECT_EQ(box.min, (std::array<double, 3>{0, 0, 0}));
  EXPECT_EQ(box.max, (std::array<double, 3>{1.5, 1.5, 1.5}));
  // Three right triangles of legs 1.5 and an equilateral one of side 1.5 sqrt(2).
  const double expected = 3 * 1.5 * 1.5 / 2 + std::sqrt(3.0) / 4 * 2 * 1.5 * 1.5;
  EXPECT_NEAR(m.area(), expected, 1e-12);
}

TEST(NominalModel, BinaryStlRoundTrip) {
  TempDir dir;
  const NominalModel m = tetrahedron();
  writeStl(m, dir.path() / "t.stl", true);
  EXPECT_EQ(fs::file_size(dir.path() / "t.stl"), 84u + 50u * 4u);
  const NominalModel back = loadStl(dir.path() / "t.stl");
  EXPECT_EQ(back.vertices.size(), 4u);  // shared corners merged again
  EXPECT_EQ(corners(back), corners(m));
  EXPECT_NEAR(back.area(), m.area(), 1e-6);
  EXPECT_EQ(back.source, (dir.path() / "t.stl").string());
}

TEST(NominalModel, AsciiStlRoundTripKeepsDoubles) {
  TempDir dir;
  NominalModel m = tetrahedron();
  m.vertices[1] = {0.1, 1e-7, -2.0 / 3};  // not representable in float: ASCII keeps them exactly
  writeStl(m, dir.path() / "t.stl", false);
  EXPECT_EQ(readFile(dir.path() / "t.stl").rfind("solid", 0), 0u);
  const NominalModel back = loadNominalModel(dir.path() / "t.stl");
  EXPECT_EQ(back.vertices.size(), 4u);
  EXPECT_EQ(corners(back), corners(m));
}

TEST(NominalModel, BinaryStlWhoseHeaderStartsWithSolid) {
  TempDir dir;
  writeStl(tetrahedron(), dir.path() / "t.stl", true);
  std::string bytes = readFile(dir.path() / "t.stl");
  const char header[] = "solid part exported by a CAD system";
  std::memcpy(bytes.data(), header, sizeof header - 1);
  writeText(dir.path() / "solid.stl", bytes);
  const NominalModel back = loadStl(dir.path() / "solid.stl");
  EXPECT_EQ(corners(back), corners(tetrahedron()));
}

TEST(NominalModel, AsciiStlWithSeveralSolidsAndLooseFormatting) {
  const std::string text =
      "solid a\r\n facet normal 0 0 1\r\n  outer loop\r\n   vertex 0 0 0\r\n   vertex +1e0 0 0\r\n   vertex 0 1 0\r\n"
      "  endloop\r\n endfacet\r\nendsolid a\r\n"
      "solid\nfacet normal 0 0 0 outer loop vertex 1 0 0 vertex 1 1 0 vertex 0 1 0 endloop endfacet endsolid\n";
  const NominalModel m = parseStl(text, "two.stl");
  EXPECT_EQ(m.triangles.size(), 2u);
  EXPECT_EQ(m.vertices.size(), 4u);  // the shared edge's corners merged across the solids
  EXPECT_NEAR(m.area(), 1.0, 1e-12);
}

TEST(NominalModel, BrokenStlFilesAreRefusedNamingTheFileAndTheFault) {
  TempDir dir;
  const fs::path file = dir.path() / "bad.stl";
  writeStl(tetrahedron(), file, true);
  const std::string good = readFile(file);
  const std::string name = file.string();

  writeText(file, good.substr(0, good.size() - 10));
  expectOneLineNaming(errorOf([&] { loadStl(file); }), name, "binary STL truncated: 4 triangles announced, 3 present");

  std::string solid = good.substr(0, good.size() - 10);
  std::memcpy(solid.data(), "solid x", 7);
  writeText(file, solid);
  expectOneLineNaming(errorOf([&] { loadStl(file); }), name, "nor is it a binary STL");

  std::string none = good.substr(0, 84);
  none[80] = none[81] = none[82] = none[83] = 0;
  writeText(file, none);
  expectOneLineNaming(errorOf([&] { loadStl(file); }), name, "no triangles");

  writeText(file, "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 nan 0\nendloop\nendfacet\nendsolid\n");
  expectOneLineNaming(errorOf([&] { loadStl(file); }), name + ":6", "not a finite number");

  writeText(file, "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n");
  expectOneLineNaming(errorOf([&] { loadStl(file); }), name, "found the end of the file");

  std::string nan = good;
  const float bad = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan.data() + 84 + 12 + 4, &bad, sizeof bad);
  writeText(file, nan);
  expectOneLineNaming(errorOf([&] { loadStl(file); }), name, "triangle 1 has a coordinate that is not a finite number");

  writeText(file, "hello");
  expectOneLineNaming(errorOf([&] { loadStl(file); }), name, "not an STL file");

  expectOneLineNaming(errorOf([&] { loadNominalModel(dir.path() / "none.stl"); }), (dir.path() / "none.stl").string(),
                      "does not exist");
  expectOneLineNaming(errorOf([&] { loadNominalModel(dir.path() / "m.obj"); }), (dir.path() / "m.obj").string(),
                      "unknown kind of model file");
}

// z = 0.01 (x^2 + y^2) - 0.002 x y over [-20, 20] x [-15, 15]: smooth, so a B-spline fits it closely.
double bowl(double x, double y) { return 0.01 * (x * x + y * y) - 0.002 * x * y; }

HeightGrid bowlGrid() {
  HeightGrid g;
  g.x0 = -20;
  g.y0 = -15;
  g.dx = g.dy = 1;
  g.columns = 41;
  g.rows = 31;
  for (std::size_t j = 0; j < g.rows; ++j)
    for (std::size_t i = 0; i < g.columns; ++i)
      g.heights.push_back(bowl(g.x0 + static_cast<double>(i), g.y0 + static_cast<double>(j)));
  return g;
}

TEST(NominalModel, StepSurfaceReadsBackOnTheSurface) {
  TempDir dir;
  writeStepSurface(bowlGrid(), dir.path() / "bowl.step");
  const NominalModel m = loadNominalModel(dir.path() / "bowl.step");
  ASSERT_GT(m.triangles.size(), 100u);
  // Every tessellation vertex lies on the B-spline face, which approximates the samples to 0.005 mm.
  double worst = 0;
  for (const auto& v : m.vertices) worst = std::max(worst, std::fabs(v[2] - bowl(v[0], v[1])));
  EXPECT_LT(worst, 0.01);
  const Box3 box = m.bounds();
  EXPECT_NEAR(box.min[0], -20, 1e-6);
  EXPECT_NEAR(box.max[0], 20, 1e-6);
  EXPECT_NEAR(box.min[1], -15, 1e-6);
  EXPECT_NEAR(box.max[1], 15, 1e-6);
  // Facing up, like the height grid: the triangles' normals have positive z.
  std::size_t up = 0;
  for (const auto& t : m.triangles) {
    const auto& a = m.vertices[t[0]];
    const auto& b = m.vertices[t[1]];
    const auto& c = m.vertices[t[2]];
    up += (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) > 0;
  }
  EXPECT_EQ(up, m.triangles.size());
  // The flat projection of the surface covers the rectangle once: the areas agree within the curvature.
  EXPECT_GT(m.area(), 40.0 * 30.0);
  EXPECT_LT(m.area(), 40.0 * 30.0 * 1.2);
}

TEST(NominalModel, BrokenStepFilesAreRefused) {
  TempDir dir;
  const fs::path file = dir.path() / "bad.step";
  writeText(file, "ISO-10303-21;\nHEADER;\nthis is not STEP\n");
  expectOneLineNaming(errorOf([&] { loadNominalModel(file); }), file.string(), "STEP");
  writeText(file, "");
  expectOneLineNaming(errorOf([&] { loadNominalModel(file); }), file.string(), "STEP");
  expectOneLineNaming(errorOf([&] { loadStep(dir.path() / "none.stp"); }), (dir.path() / "none.stp").string(), "does not exist");
}

// ---- The program file ---------------------------------------------------------------------------

const char* kProgram = R"(name = "pan-4711"
description = "Rear pan, left"
model = "model.stl"
plan = "plan.toml"
press_program = "P-88"

[grid]
kind = "circle"
pitch_mm = 2.54
circle_diameter_mm = 2.54
line_width_mm = 0.15

[sheet]
material = "DC04"
thickness_mm = 0.8

[[region]]
name = "corner"
min_mm = [-80, -60]
max_mm = [-40, -20.5]

[simulation]
part = "pan"
)";

ScanPlan smallPlan(double pitch = 2.54) {
  ScanPlan plan;
  plan.name = "pan, one sweep";
  plan.part.kind = "pan";
  plan.part.pitch = pitch;
  SweepStep s;
  s.start.position = {-30, -40, 160};
  s.end.position = {-30, 40, 160};
  plan.steps.emplace_back(s);
  return plan;
}

// A whole program folder: program.toml (kProgram with `program` instead), plan.toml, model.stl.
fs::path writeFolder(const fs::path& dir, const std::string& program = kProgram, const ScanPlan& plan = smallPlan()) {
  fs::create_directories(dir);
  writeText(dir / "program.toml", program);
  writeText(dir / "plan.toml", toToml(plan));
  writeStl(tetrahedron(), dir / "model.stl");
  return dir;
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(PartProgram, ReadsEveryKey) {
  const PartProgram p = parseProgramFile(kProgram, "p/program.toml");
  EXPECT_EQ(p.name, "pan-4711");
  EXPECT_EQ(p.description, "Rear pan, left");
  EXPECT_EQ(p.model_file, "model.stl");
  EXPECT_EQ(p.plan_file, "plan.toml");
  EXPECT_EQ(p.press_program, "P-88");
  EXPECT_EQ(p.grid, (PrintedGrid{"circle", 2.54, 2.54, 0.15}));
  EXPECT_EQ(p.material, "DC04");
  EXPECT_EQ(p.sheet_thickness_mm, 0.8);
  ASSERT_EQ(p.regions.size(), 1u);
  EXPECT_EQ(p.regions[0], (RegionOfInterest{"corner", {-80, -60}, {-40, -20.5}}));
  EXPECT_EQ(p.simulated_part, "pan");
}

TEST(PartProgram, EachMistakeIsRefusedNamingTheFileTheSectionAndTheKey) {
  const std::string file = "parts/pan-4711/program.toml";
  struct Case {
    std::string from, to, message;
  };
  const std::vector<Case> cases = {
      {"name = \"pan-4711\"\n", "", "name is missing"},
      {"name = \"pan-4711\"", "name = 4711", "name must be a string, found an integer"},
      {"model = \"model.stl\"\n", "", "model is missing"},
      {"model = \"model.stl\"", "model = \"model.obj\"", "model must name a .stl, .step or .stp file"},
      {"model = \"model.stl\"", "model = \"/abs/model.stl\"", "model must be a path relative to the program's folder"},
      {"plan = \"plan.toml\"\n", "plan = \"\"\n", "plan must name a file"},
      {"pitch_mm = 2.54", "pitch_mm = -2.54", "[grid] pitch_mm must be a positive number"},
      {"pitch_mm = 2.54", "pitch_mm = \"2.54\"", "[grid] pitch_mm must be a positive number, found a string"},
      {"pitch_mm = 2.54", "pitch_mm = nan", "[grid] pitch_mm must be a positive number"},
      {"pitch_mm = 2.54\n", "", "[grid] pitch_mm is missing"},
      {"pitch_mm = 2.54", "pitch = 2.54", "[grid] pitch is not a known key"},
      {"kind = \"circle\"", "kind = \"hexagon\"", "[grid] kind must be \"circle\" or \"square\""},
      {"circle_diameter_mm = 2.54\n", "", "[grid] circle_diameter_mm is missing"},
      {"line_width_mm = 0.15", "line_width_mm = 3", "[grid] line_width_mm must be less than pitch_mm"},
      {"[grid]\nkind = \"circle\"\npitch_mm = 2.54\ncircle_diameter_mm = 2.54\nline_width_mm = 0.15\n", "", "[grid] is missing"},
      {"[grid]", "[grid_]", "grid_ is not a known key"},
      {"thickness_mm = 0.8", "thickness_mm = 0", "[sheet] thickness_mm must be a positive number"},
      {"thickness_mm = 0.8", "thickness_mm = true", "[sheet] thickness_mm must be a positive number, found a boolean"},
      {"material = \"DC04\"\n", "", "[sheet] material is missing"},
      {"max_mm = [-40, -20.5]", "max_mm = [-90, -20.5]", "[[region]] 1 max_mm must be greater than min_mm"},
      {"min_mm = [-80, -60]", "min_mm = [-80]", "[[region]] 1 min_mm must be a list of 2 numbers"},
      {"part = \"pan\"", "part = \"cube\"", "[simulation] part must be \"dome\" or \"pan\""},
      {"part = \"pan\"", "part = \"pan\"\nscale = 3", "[simulation] scale must be within 0.5 .. 2"},
      {"part = \"pan\"", "part = \"pan\"\ndepth_mm = -4", "[simulation] depth_mm must be a positive number"},
      {"part = \"pan\"", "part = \"pan\"\ndepth = 4", "[simulation] depth is not a known key"},
      {"part = \"pan\"", "part = \"pan\"\npeak_strain = 0.9", "[simulation] peak_strain must be at most 0.5"},
      {"press_program = \"P-88\"", "press_programme = \"P-88\"", "press_programme is not a known key"},
      {"press_program = \"P-88\"", "line_number = 0", "line_number must be a whole number from 1 to 65535"},
      {"press_program = \"P-88\"", "line_number = 70000", "line_number must be a whole number from 1 to 65535"},
      {"press_program = \"P-88\"", "line_number = \"12\"", "line_number must be a whole number from 1 to 65535, found a string"},
      {"press_program = \"P-88\"", "line_number = 1.5", "line_number must be a whole number from 1 to 65535, found a floating-point"},
      {"[sheet]", "[sheet", "program.toml:13:"},  // TOML syntax: the line
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.message);
    expectOneLineNaming(errorOf([&] { parseProgramFile(replaced(kProgram, c.from, c.to), file); }), file, c.message);
  }
  // A program without a plan is one not planned yet: it reads, says so, and is written back without.
  const PartProgram unplanned = parseProgramFile(replaced(kProgram, "plan = \"plan.toml\"\n", ""), file);
  EXPECT_FALSE(unplanned.hasPlan());
  EXPECT_TRUE(checkConsistency(unplanned).empty());
  EXPECT_EQ(toToml(unplanned).find("plan ="), std::string::npos);
  EXPECT_FALSE(parseProgramFile(toToml(unplanned), file).hasPlan());
  // A simulated part family's parameters; those left out are the family's own.
  const PartProgram scaled = parseProgramFile(replaced(kProgram, "part = \"pan\"", "part = \"pan\"\nscale = 0.8\ndepth_mm = 14"), file);
  EXPECT_EQ(scaled.simulation, (SimulationParameters{0.8, 14, 0}));
  EXPECT_EQ(parseProgramFile(toToml(scaled), file).simulation, scaled.simulation);
  EXPECT_EQ(parseProgramFile(kProgram, file).simulation, SimulationParameters{});
  // A square grid needs no circle diameter.
  const std::string square = replaced(replaced(kProgram, "kind = \"circle\"", "kind = \"square\""), "circle_diameter_mm = 2.54\n", "");
  EXPECT_EQ(parseProgramFile(square, file).grid.kind, "square");
}

TEST(PartProgram, AFolderLoadsWithItsPlanAndModel) {
  TempDir dir;
  const fs::path folder = writeFolder(dir.path() / "pan-4711");
  for (const fs::path& given : {folder, folder / "program.toml"}) {
    const PartProgram p = loadPartProgram(given);
    EXPECT_EQ(p.folder, folder);
    EXPECT_EQ(p.plan, smallPlan());
    EXPECT_EQ(p.model.triangles.size(), 4u);
    EXPECT_EQ(p.model.source, (folder / "model.stl").string());
  }
}

TEST(PartProgram, WrittenProgramsRoundTrip) {
  TempDir dir;
  const PartProgram p = loadPartProgram(writeFolder(dir.path() / "a"));
  const fs::path copy = dir.path() / "b";
  writePartProgram(p, copy);
  fs::copy_file(dir.path() / "a" / "plan.toml", copy / "plan.toml");
  fs::copy_file(dir.path() / "a" / "model.stl", copy / "model.stl");
  const PartProgram back = loadPartProgram(copy);
  EXPECT_EQ(back.name, p.name);
  EXPECT_EQ(back.description, p.description);
  EXPECT_EQ(back.model_file, p.model_file);
  EXPECT_EQ(back.plan_file, p.plan_file);
  EXPECT_EQ(back.grid, p.grid);
  EXPECT_EQ(back.material, p.material);
  EXPECT_EQ(back.sheet_thickness_mm, p.sheet_thickness_mm);
  EXPECT_EQ(back.press_program, p.press_program);
  EXPECT_EQ(back.regions, p.regions);
  EXPECT_EQ(back.simulated_part, p.simulated_part);
  EXPECT_EQ(back.simulation, p.simulation);
  EXPECT_EQ(back.plan, p.plan);
  EXPECT_EQ(toToml(back), toToml(p));
  // Nothing but the program file and what was copied: the temporary is gone.
  EXPECT_EQ(std::distance(fs::directory_iterator(copy), fs::directory_iterator()), 3);
}

TEST(PartProgram, TheLineFindsAProgramByItsLineNumber) {
  TempDir dir;
  const fs::path library = dir.path() / "programs";
  writeFolder(library / "a", replaced(kProgram, "press_program = \"P-88\"", "press_program = \"P-88\"\nline_number = 12"));
  writeFolder(library / "b", replaced(replaced(kProgram, "pan-4711", "pan-4712"), "press_program = \"P-88\"",
                                      "press_program = \"P-88\"\nline_number = 13"));
  writeFolder(library / "c", replaced(kProgram, "pan-4711", "pan-4713"));  // no number: the line cannot start it
  fs::create_directories(library / "broken");
  writeText(library / "broken" / "program.toml", "name = ");  // passed over
  EXPECT_EQ(findProgramByLineNumber(library, 12), "pan-4711");
  EXPECT_EQ(findProgramByLineNumber(library, 13), "pan-4712");
  EXPECT_EQ(findProgramByLineNumber(library, 14), std::nullopt);
  EXPECT_EQ(loadPartProgram(library / "a").line_number, 12);
  EXPECT_EQ(parseProgramFile(toToml(loadPartProgram(library / "b")), "b").line_number, 13);
  EXPECT_EQ(loadPartProgram(library / "c").line_number, std::nullopt);
  // Two programs with one number: which one the line means is unknowable; refused naming both.
  writeFolder(library / "d", replaced(replaced(kProgram, "pan-4711", "pan-4714"), "press_program = \"P-88\"",
                                      "press_program = \"P-88\"\nline_number = 13"));
  const std::string error = errorOf([&] { findProgramByLineNumber(library, 13); });
  EXPECT_NE(error.find("two programs have line_number 13"), std::string::npos) << error;
  EXPECT_NE(error.find((library / "d").string()), std::string::npos) << error;
}

TEST(PartProgram, AFolderWithABrokenPartIsRefusedNamingTheFile) {
  TempDir dir;
  const fs::path folder = writeFolder(dir.path() / "p");
  const std::string program = (folder / "program.toml").string();

  fs::remove(folder / "plan.toml");
  expectOneLineNaming(errorOf([&] { loadPartProgram(folder); }), program,
                      "plan names \"plan.toml\", which does not exist in " + folder.string());

  writeFolder(folder, kProgram, smallPlan(5.08));
  expectOneLineNaming(errorOf([&] { loadPartProgram(folder); }), program,
                      "[grid] pitch_mm is 2.54 but the plan's [part] pitch is 5.08");

  writeFolder(folder, replaced(kProgram, "part = \"pan\"", "part = \"dome\""));
  expectOneLineNaming(errorOf([&] { loadPartProgram(folder); }), program,
                      "[simulation] part is \"dome\" but the plan's [part] kind is \"pan\"");

  writeFolder(folder);
  const std::string stl = readFile(folder / "model.stl");
  writeText(folder / "model.stl", stl.substr(0, stl.size() - 1));
  expectOneLineNaming(errorOf([&] { loadPartProgram(folder); }), (folder / "model.stl").string(), "binary STL truncated");

  writeText(folder / "model.stl", std::string(200, '\x7f'));
  expectOneLineNaming(errorOf([&] { loadPartProgram(folder); }), (folder / "model.stl").string(), "binary STL");

  fs::remove(folder / "model.stl");
  expectOneLineNaming(errorOf([&] { loadPartProgram(folder); }), program, "model names \"model.stl\", which does not exist");

  writeFolder(folder);
  writeText(folder / "plan.toml", "name = \"x\"\n");
  expectOneLineNaming(errorOf([&] { loadPartProgram(folder); }), (folder / "plan.toml").string(), "step is missing");

  fs::remove(folder / "program.toml");
  expectOneLineNaming(errorOf([&] { loadPartProgram(folder); }), folder.string(), "not a part program folder");
  expectOneLineNaming(errorOf([&] { loadPartProgram(dir.path() / "none"); }), (dir.path() / "none").string(),
                      "no such part program");
}

TEST(PartProgram, TheLibraryListsAndFindsPrograms) {
  TempDir dir;
  writeFolder(dir.path() / "b-folder", replaced(kProgram, "pan-4711", "pan-0815"));
  writeFolder(dir.path() / "a-folder");
  fs::create_directories(dir.path() / "not-a-program");
  const std::vector<fs::path> list = listPrograms(dir.path());
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0], dir.path() / "a-folder");
  EXPECT_EQ(list[1], dir.path() / "b-folder");

  EXPECT_EQ(findProgram(dir.path(), "pan-0815"), dir.path() / "b-folder");
  EXPECT_EQ(findProgram(dir.path(), "pan-4711"), dir.path() / "a-folder");
  const fs::path elsewhere = writeFolder(dir.path() / "not-a-program" / "x");
  EXPECT_EQ(findProgram(dir.path(), elsewhere.string()), elsewhere);
  EXPECT_EQ(findProgram(dir.path(), (elsewhere / "program.toml").string()), elsewhere);

  const std::string message = errorOf([&] { findProgram(dir.path(), "pan-9999"); });
  EXPECT_NE(message.find("no part program \"pan-9999\""), std::string::npos) << message;
  EXPECT_NE(message.find("pan-4711, pan-0815"), std::string::npos) << message;
  EXPECT_NE(errorOf([&] { listPrograms(dir.path() / "none"); }).find("not a folder of part programs"), std::string::npos);
}

}  // namespace
}  // namespace stampscan::acquisition
