// PLY reading and writing: round trips, the variants real files use, and every malformed input the
// reader must reject with a message naming the file and the place.
#include "stampscan/fitting/ply_io.hpp"

#include "io_test_support.hpp"

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <tuple>
#include <vector>

namespace stampscan::fitting {
namespace {

namespace fs = std::filesystem;
using test::Bytes;
using test::contains;
using test::expectSameCloud;
using test::readFile;
using test::sampleCloud;
using test::TempDir;
using test::writeFile;

// The InputError that parsing `bytes` as "test.ply" throws; fails the test if there is none.
InputError parseError(const std::string& bytes) {
  try {
    parsePly(bytes, "test.ply");
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no InputError for input:\n" << bytes.substr(0, 300);
  return InputError("", "", "");
}

// Checks the error names the file, the place and the reason.
void expectError(const std::string& bytes, const std::string& where, const std::string& reason) {
  const InputError e = parseError(bytes);
  EXPECT_EQ(e.file(), "test.ply");
  EXPECT_TRUE(contains(e.what(), "test.ply: "));
  EXPECT_TRUE(contains(e.where(), where));
  EXPECT_TRUE(contains(e.reason(), reason));
}

const std::string kXyzHeader =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n";

// ---- Round trips ----------------------------------------------------------------------------------

class PlyRoundTrip : public ::testing::TestWithParam<std::tuple<PlyFormat, PlyPrecision>> {};

TEST_P(PlyRoundTrip, CloudWithAllAttributes) {
  const auto [format, precision] = GetParam();
  TempDir dir;
  const Cloud cloud = sampleCloud(300);
  const fs::path file = dir.path() / "cloud.ply";
  writePly(file, cloud, {format, precision, "round trip test"});
  ReadReport report;
  const Cloud back = readPly(file, &report);
  expectSameCloud(cloud, back, precision);
  EXPECT_EQ(report.points_read, 300u);
  EXPECT_EQ(report.skipped_nonfinite, 0u);
  EXPECT_TRUE(contains(readFile(file), "comment round trip test\n"));
}

TEST_P(PlyRoundTrip, Mesh) {
  const auto [format, precision] = GetParam();
  TempDir dir;
  Mesh mesh;
  mesh.vertices = sampleCloud(5);
  mesh.triangles = {{{0, 1, 2}}, {{2, 3, 4}}, {{4, 0, 1}}};
  const fs::path file = dir.path() / "mesh.ply";
  writePly(file, mesh, {format, precision, ""});
  ReadReport report;
  const Mesh back = readPlyMesh(file, &report);
  expectSameCloud(mesh.vertices, back.vertices, precision);
  ASSERT_EQ(back.triangles.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(back.triangles[i].v, mesh.triangles[i].v);
  EXPECT_EQ(report.faces_read, 3u);
  // Reading it as a cloud just ignores the faces.
  EXPECT_EQ(readPly(file).size(), 5u);
}

TEST_P(PlyRoundTrip, PositionsOnly) {
  const auto [format, precision] = GetParam();
  TempDir dir;
  Cloud cloud;
  cloud.positions = {Vec3(0.1, 0.2, 0.3), Vec3(-1e-7, 1e7, 123.456789012345)};
  const fs::path file = dir.path() / "xyz.ply";
  writePly(file, cloud, {format, precision, ""});
  const Cloud back = readPly(file);
  expectSameCloud(cloud, back, precision);
  EXPECT_FALSE(back.hasNormals() || back.hasStrain() || back.hasColors() || !back.scalars.empty());
}

INSTANTIATE_TEST_SUITE_P(FormatsAndPrecisions, PlyRoundTrip,
                         ::testing::Combine(::testing::Values(PlyFormat::Ascii, PlyFormat::BinaryLittleEndian),
                                            ::testing::Values(PlyPrecision::Float, PlyPrecision::Double)),
                         [](const auto& test) {
                           return std::string(std::get<0>(test.param) == PlyFormat::Ascii ? "Ascii" : "Binary") +
                                  (std::get<1>(test.param) == PlyPrecision::Float ? "Float" : "Double");
                         });

TEST(PlyWrite, HeaderListsPropertiesInOrder) {
  TempDir dir;
  Mesh mesh;
  mesh.vertices = sampleCloud(3);
  mesh.triangles = {{{0, 1, 2}}};
  writePly(dir.path() / "m.ply", mesh, {PlyFormat::Ascii, PlyPrecision::Double, "two\nlines"});
  const std::string text = readFile(dir.path() / "m.ply");
  const std::string expected =
      "ply\nformat ascii 1.0\ncomment two lines\nelement vertex 3\n"
      "property double x\nproperty double y\nproperty double z\n"
      "property double nx\nproperty double ny\nproperty double nz\nproperty double strain\n"
      "property double major_strain\nproperty double minor_strain\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  EXPECT_EQ(text.substr(0, expected.size()), expected);
  EXPECT_TRUE(contains(text, "\n3 0 1 2\n"));
}

TEST(PlyWrite, LeavesNoFileWhenTheDirectoryIsMissing) {
  TempDir dir;
  const fs::path file = dir.path() / "missing" / "out.ply";
  try {
    writePly(file, sampleCloud(3));
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_TRUE(contains(e.what(), file.string()));
  }
  EXPECT_FALSE(fs::exists(dir.path() / "missing"));
  EXPECT_TRUE(dir.entries().empty());
}

TEST(PlyWrite, LeavesNoTemporaryFileBehind) {
  TempDir dir;
  const fs::path file = dir.path() / "out.ply";
  writePly(file, sampleCloud(50));
  writePly(file, sampleCloud(2), {PlyFormat::Ascii, PlyPrecision::Float, ""});  // replaces the first
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"out.ply"});
  EXPECT_EQ(readPly(file).size(), 2u);
}

TEST(PlyWrite, FailedRenameRemovesTheTemporaryFile) {
  TempDir dir;
  const fs::path target = dir.path() / "taken.ply";
  fs::create_directories(target / "inside");  // a non-empty directory cannot be replaced by a file
  EXPECT_THROW(writePly(target, sampleCloud(3)), std::runtime_error);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"taken.ply"});
  EXPECT_TRUE(fs::is_directory(target));
}

TEST(PlyWrite, RejectsInconsistentInputBeforeTouchingTheDisk) {
  TempDir dir;
  Cloud cloud = sampleCloud(4);
  cloud.strain.pop_back();
  EXPECT_THROW(writePly(dir.path() / "a.ply", cloud), std::invalid_argument);
  Cloud badName = sampleCloud(2);
  badName.scalars["two words"] = {1.0, 2.0};
  EXPECT_THROW(writePly(dir.path() / "b.ply", badName), std::invalid_argument);
  Mesh mesh;
  mesh.vertices = sampleCloud(3);
  mesh.triangles = {{{0, 1, 3}}};
  EXPECT_THROW(writePly(dir.path() / "c.ply", mesh), std::invalid_argument);
  EXPECT_TRUE(dir.entries().empty());
}

// ---- Variants real files use ----------------------------------------------------------------------

TEST(PlyRead, SkipsOtherElementsBeforeAndAfterTheVertices) {
  const std::string ascii =
      "ply\nformat ascii 1.0\ncomment made by hand\nobj_info scanner 7\n"
      "element camera 1\nproperty float view_px\nproperty float view_py\nproperty list uchar int ids\n"
      "element vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
      "element range_grid 3\nproperty list uchar int vertex_indices\n"
      "end_header\n"
      "1.5 2.5 3 7 8 9\n"
      "1 2 3\n4 5 6\n"
      "1 0\n0\n2 0 1\n";
  const Mesh ascii_mesh = parsePly(ascii, "a.ply");
  ASSERT_EQ(ascii_mesh.vertices.size(), 2u);
  EXPECT_EQ(ascii_mesh.vertices.positions[1], Vec3(4, 5, 6));
  EXPECT_TRUE(ascii_mesh.triangles.empty());

  Bytes body;
  body.put(1.5f).put(2.5f).put(std::uint8_t{3}).put(7).put(8).put(9);
  body.put(1.0f).put(2.0f).put(3.0f).put(4.0f).put(5.0f).put(6.0f);
  body.put(std::uint8_t{1}).put(0).put(std::uint8_t{0}).put(std::uint8_t{2}).put(0).put(1);
  std::string binary = ascii.substr(0, ascii.find("end_header\n") + 11);
  binary.replace(binary.find("ascii"), 5, "binary_little_endian");
  const Mesh binary_mesh = parsePly(binary + body.str(), "b.ply");
  ASSERT_EQ(binary_mesh.vertices.size(), 2u);
  EXPECT_EQ(binary_mesh.vertices.positions[0], Vec3(1, 2, 3));
  EXPECT_EQ(binary_mesh.vertices.positions[1], Vec3(4, 5, 6));

  // Data after the last element the header declares means its counts are wrong (a header that
  // declares fewer vertices than the file holds): refused, naming where they start; so is a short element.
  expectError(binary + body.str() + "extra", "byte", "data after the last record the header declares");
  expectError(ascii + "7 8 9\n", "line 22", "data after the last record the header declares");
  EXPECT_NO_THROW(parsePly(ascii + "\n \n", "a.ply"));  // blank lines are no data
  expectError(binary + body.str().substr(0, body.str().size() - 1), "byte",
              "truncated range_grid data: expected 3 'range_grid' records, got 2");
}

TEST(PlyRead, SkipsListPropertiesOnVertices) {
  const std::string header =
      "element vertex 2\nproperty float x\nproperty float y\nproperty list uchar float texcoord\n"
      "property float z\nproperty float quality\nend_header\n";
  const Cloud ascii = parsePly("ply\nformat ascii 1.0\n" + header + "1 2 2 0.5 0.5 3 9\n4 5 0 6 8\n", "a").vertices;
  ASSERT_EQ(ascii.size(), 2u);
  EXPECT_EQ(ascii.positions[0], Vec3(1, 2, 3));
  EXPECT_EQ(ascii.positions[1], Vec3(4, 5, 6));
  EXPECT_EQ(ascii.scalars.at("quality"), (std::vector<double>{9, 8}));
  EXPECT_FALSE(ascii.scalars.count("texcoord"));

  Bytes body;
  body.put(1.0f).put(2.0f).put(std::uint8_t{2}).put(0.5f).put(0.5f).put(3.0f).put(9.0f);
  body.put(4.0f).put(5.0f).put(std::uint8_t{0}).put(6.0f).put(8.0f);
  const Cloud binary = parsePly("ply\nformat binary_little_endian 1.0\n" + header + body.str(), "b").vertices;
  ASSERT_EQ(binary.size(), 2u);
  EXPECT_EQ(binary.positions[1], Vec3(4, 5, 6));
  EXPECT_EQ(binary.scalars.at("quality"), (std::vector<double>{9, 8}));
}

TEST(PlyRead, ReadsBigEndianFiles) {
  const std::string header =
      "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty float y\n"
      "property int z\nproperty short strain\nproperty uint16 red\nproperty uchar green\nproperty float blue\n"
      "element face 1\nproperty list uint8 uint32 vertex_indices\nend_header\n";
  Bytes body(true);
  for (int i = 0; i < 3; ++i) {
    body.put(0.25 + i).put(-1.5f * static_cast<float>(i)).put(std::int32_t{-100000 * i}).put(std::int16_t(-3 * i));
    body.put(std::uint16_t(i == 2 ? 1000 : 10)).put(std::uint8_t(200)).put(i == 1 ? -4.0f : 127.6f);
  }
  body.put(std::uint8_t{3}).put(std::uint32_t{2}).put(std::uint32_t{0}).put(std::uint32_t{1});
  const Mesh mesh = parsePly(header + body.str(), "be.ply");
  const Cloud& cloud = mesh.vertices;
  ASSERT_EQ(cloud.size(), 3u);
  EXPECT_EQ(cloud.positions[2], Vec3(2.25, -3.0, -200000.0));
  EXPECT_EQ(cloud.strain, (std::vector<double>{0, -3, -6}));
  // Colours of other types are clamped to 0..255 and rounded.
  EXPECT_EQ(cloud.colors[0], (std::array<std::uint8_t, 3>{10, 200, 128}));
  EXPECT_EQ(cloud.colors[1], (std::array<std::uint8_t, 3>{10, 200, 0}));
  EXPECT_EQ(cloud.colors[2], (std::array<std::uint8_t, 3>{255, 200, 128}));
  ASSERT_EQ(mesh.triangles.size(), 1u);
  EXPECT_EQ(mesh.triangles[0].v, (std::array<std::uint32_t, 3>{2, 0, 1}));
}

TEST(PlyRead, ReadsIntegerCoordinateTypes) {
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty uchar x\nproperty short y\n"
      "property int z\nend_header\n";
  Bytes body;
  body.put(std::uint8_t{250}).put(std::int16_t{-300}).put(std::int32_t{70000});
  body.put(std::uint8_t{0}).put(std::int16_t{32767}).put(std::int32_t{-2});
  const Cloud cloud = parsePly(header + body.str(), "int.ply").vertices;
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.positions[0], Vec3(250, -300, 70000));
  EXPECT_EQ(cloud.positions[1], Vec3(0, 32767, -2));
}

TEST(PlyRead, AcceptsEveryTypeName) {
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty char x\nproperty int8 y\nproperty uint8 z\n"
      "property ushort a\nproperty int16 b\nproperty uint16 c\nproperty uint d\nproperty int32 e\n"
      "property uint32 f\nproperty float32 g\nproperty float64 h\nproperty double i\nend_header\n";
  const Cloud cloud = parsePly(header + "1 2 3 4 5 6 7 8 9 10 11 12\n", "types.ply").vertices;
  EXPECT_EQ(cloud.positions[0], Vec3(1, 2, 3));
  EXPECT_EQ(cloud.scalars.size(), 9u);
  EXPECT_EQ(cloud.scalars.at("i")[0], 12.0);
}

TEST(PlyRead, AcceptsCrLfLineEndings) {
  const std::string ascii =
      "ply\r\nformat ascii 1.0\r\ncomment windows\r\nelement vertex 2\r\nproperty float x\r\n"
      "property float y\r\nproperty float z\r\nend_header\r\n1 2 3\r\n4 5 6\r\n";
  EXPECT_EQ(parsePly(ascii, "crlf.ply").vertices.size(), 2u);

  Bytes body;
  body.put(1.0f).put(2.0f).put(3.0f);
  const std::string binary =
      "ply\r\nformat binary_little_endian 1.0\r\nelement vertex 1\r\nproperty float x\r\n"
      "property float y\r\nproperty float z\r\nend_header\r\n";
  EXPECT_EQ(parsePly(binary + body.str(), "crlf.ply").vertices.positions[0], Vec3(1, 2, 3));
}

TEST(PlyRead, TriangulatesPolygonsAndReadsFacesBeforeVertices) {
  const std::string text =
      "ply\nformat ascii 1.0\nelement face 2\nproperty uchar flags\nproperty list uchar int vertex_index\n"
      "element vertex 5\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
      "1 4 0 1 2 3\n"
      "0 2 3 4\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 2 2\n";
  ReadReport report;
  const Mesh mesh = parsePly(text, "quad.ply", &report);
  ASSERT_EQ(mesh.triangles.size(), 2u);  // the quad's fan; the two-corner face adds none
  EXPECT_EQ(mesh.triangles[0].v, (std::array<std::uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(mesh.triangles[1].v, (std::array<std::uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(report.faces_read, 2u);
}

TEST(PlyRead, DropsNonFinitePointsWithTheirAttributesAndFaces) {
  const std::string text =
      "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
      "property float strain\nproperty float thickness\nproperty uchar red\nproperty uchar green\n"
      "property uchar blue\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0 0.1 1.0 1 1 1\n"
      "nan 0 0 0.2 2.0 2 2 2\n"
      "1 1 0 0.3 3.0 3 3 3\n"
      "0 1 inf 0.4 4.0 4 4 4\n"
      "1 0 0 nan 5.0 5 5 5\n"
      "3 0 1 2\n"
      "3 0 2 4\n";
  ReadReport report;
  const Mesh mesh = parsePly(text, "nan.ply", &report);
  const Cloud& cloud = mesh.vertices;
  EXPECT_NO_THROW(cloud.validate());
  EXPECT_EQ(report.points_read, 3u);
  EXPECT_EQ(report.skipped_nonfinite, 2u);
  ASSERT_EQ(cloud.size(), 3u);
  EXPECT_EQ(cloud.scalars.at("thickness"), (std::vector<double>{1, 3, 5}));
  EXPECT_EQ(cloud.colors[1][0], 3);
  EXPECT_TRUE(std::isnan(cloud.strain[2]));  // only coordinates decide whether a point is kept
  ASSERT_EQ(mesh.triangles.size(), 1u);      // the face on the dropped vertex 1 is gone
  EXPECT_EQ(mesh.triangles[0].v, (std::array<std::uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(report.faces_read, 1u);

  Bytes body;
  body.put(std::numeric_limits<double>::quiet_NaN()).put(0.0).put(0.0);
  body.put(1.0).put(2.0).put(3.0);
  const std::string binary =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
      "property double z\nend_header\n";
  ReadReport binaryReport;
  EXPECT_EQ(parsePly(binary + body.str(), "b", &binaryReport).vertices.size(), 1u);
  EXPECT_EQ(binaryReport.skipped_nonfinite, 1u);
}

TEST(PlyRead, ReadsFromDiskAndNamesTheFileInErrors) {
  TempDir dir;
  const fs::path good = dir.path() / "good.ply";
  writeFile(good, kXyzHeader + "1 2 3\n4 5 6\n7 8 9\n");
  EXPECT_EQ(readPly(good).size(), 3u);

  const fs::path bad = dir.path() / "bad.ply";
  writeFile(bad, kXyzHeader + "1 2 3\n4 5 six\n7 8 9\n");
  try {
    readPly(bad);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(bad.string() + ": line 9, byte ", 0), 0u) << e.what();
    EXPECT_TRUE(contains(e.what(), "non-numeric value 'six' for property 'z'"));
  }
  const fs::path missing = dir.path() / "nothere.ply";
  try {
    readPlyMesh(missing);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), missing.string()));
  }
}

TEST(PlyRead, ReadsALargeBinaryCloudQuickly) {
  TempDir dir;
  Cloud cloud;
  const std::size_t n = 500000;
  cloud.positions.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i);
    cloud.positions.emplace_back(t * 0.001, std::sin(t), std::cos(t));
    cloud.strain.push_back(t * 1e-6);
  }
  const fs::path file = dir.path() / "big.ply";
  writePly(file, cloud);
  const auto start = std::chrono::steady_clock::now();
  const Cloud back = readPly(file);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(back.size(), n);
  RecordProperty("read_seconds", std::to_string(seconds));
#if defined(NDEBUG) && !defined(__SANITIZE_ADDRESS__)
  EXPECT_LT(seconds, 1.0);
#endif
}

// ---- Malformed input ------------------------------------------------------------------------------

TEST(PlyErrors, EmptyFile) { expectError("", "byte 0", "empty file"); }

TEST(PlyErrors, NotAPly) {
  expectError("PK\x03\x04 zip archive", "byte 0", "not a PLY file");
  expectError("plywood\nformat ascii 1.0\n", "line 1", "not a PLY file: the first line is 'plywood'");
}

TEST(PlyErrors, UnknownFormatOrVersion) {
  expectError("ply\nformat binary_middle_endian 1.0\nend_header\n", "line 2, byte 4",
              "unknown PLY format 'binary_middle_endian'");
  expectError("ply\nformat ascii 2.0\nend_header\n", "line 2", "unsupported PLY version '2.0'");
  expectError("ply\nelement vertex 1\nproperty float x\nend_header\n1\n", "header", "missing format line");
}

TEST(PlyErrors, MissingOrTruncatedHeader) {
  expectError("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n1 2 3\n",
              "line 7", "unexpected header line '1 2 3' (missing end_header?)");
  expectError("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty fl", "line 5",
              "truncated header: the file ends before end_header");
  expectError("ply", "line 1", "truncated header");
}

TEST(PlyErrors, MissingCoordinate) {
  expectError("ply\nformat ascii 1.0\ncomment c\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n",
              "line 4", "vertex element lacks property 'z'");
  expectError("ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n3 0 1 2\n",
              "header", "no vertex element");
  expectError("ply\nformat binary_little_endian 1.0\nelement vertex 5\nend_header\n", "line 3",
              "vertex element lacks property 'x'");
}

TEST(PlyErrors, BadPropertyLines) {
  expectError("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n", "line 4",
              "unknown property type 'float128'");
  expectError("ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\nend_header\n", "line 4",
              "list length type must be an integer type");
  expectError("ply\nformat ascii 1.0\nproperty float x\nend_header\n", "line 3", "property line before any element");
  expectError("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty double x\nend_header\n", "line 5",
              "second property 'x'");
  expectError(kXyzHeader.substr(0, kXyzHeader.size() - 11) + "property float nx\nproperty float ny\nend_header\n",
              "line 3", "nx, ny and nz must be given all three or not at all");
}

TEST(PlyErrors, BadElementCount) {
  expectError("ply\nformat ascii 1.0\nelement vertex lots\nend_header\n", "line 3",
              "element count 'lots' is not a non-negative integer");
  expectError("ply\nformat ascii 1.0\nelement vertex -4\nend_header\n", "line 3", "is not a non-negative integer");
  expectError("ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\nend_header\n", "line 3",
              "is not a non-negative integer");
  // A count far beyond what the file holds fails without trying to allocate for it.
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n";
  Bytes body;
  body.put(1.0f).put(2.0f).put(3.0f).put(4.0f).put(5.0f).put(6.0f).put(7.0f);
  expectError(header + body.str(), "byte " + std::to_string(header.size() + 24),
              "truncated vertex data: expected 1000000000000 vertices, got 2");
  expectError("ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n1 2 3\n",
              "line 9", "truncated vertex data: expected 4000000000 vertices, got 1");
}

TEST(PlyErrors, TruncatedBinaryData) {
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n";
  Bytes body;
  for (int i = 0; i < 100; ++i) body.put(1.0f * static_cast<float>(i)).put(2.0f).put(3.0f);
  const std::string truncated = header + body.str().substr(0, 37 * 12 + 5);
  const InputError e = parseError(truncated);
  EXPECT_EQ(std::string(e.what()), "test.ply: byte " + std::to_string(header.size() + 37 * 12) +
                                       ": truncated vertex data: expected 100 vertices, got 37");

  // The same inside a face list, found while reading rather than from the sizes.
  const std::string meshHeader =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";
  Bytes meshBody;
  for (int i = 0; i < 9; ++i) meshBody.put(static_cast<float>(i));
  meshBody.put(std::uint8_t{3}).put(0).put(1).put(2).put(std::uint8_t{3}).put(0).put(1);
  expectError(meshHeader + meshBody.str(), "byte " + std::to_string(meshHeader.size() + 36 + 13),
              "truncated face data: expected 2 faces, got 1");
}

TEST(PlyErrors, BadAsciiRecords) {
  expectError(kXyzHeader + "1 2 3\n4 5\n7 8 9\n", "line 9", "too few values on the line");
  expectError(kXyzHeader + "1 2 3\n4 5 6 7\n7 8 9\n", "line 9", "too many values");
  expectError(kXyzHeader + "1 2 3\n4 5 6\n7 8 z9\n", "line 10, byte " + std::to_string(kXyzHeader.size() + 16),
              "non-numeric value 'z9' for property 'z'");
  expectError(kXyzHeader + "1 2 3\n\n4 5 6\n", "line 11", "truncated vertex data: expected 3 vertices, got 2");
}

TEST(PlyErrors, BadFaces) {
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
  expectError(header + "3 0 1 3\n", "line 13", "face 0: vertex index 3 out of range (the file has 3 vertices)");
  expectError(header + "3 0 -1 2\n", "line 13", "vertex index -1 out of range");
  expectError(header + "-3 0 1 2\n", "line 13", "invalid list length -3");
}

TEST(PlyErrors, GarbageBytes) {
  std::mt19937 random(7);
  std::string garbage(2000, '\0');
  for (char& c : garbage) c = static_cast<char>(random() & 0xff);
  expectError(garbage, "byte 0", "not a PLY file");
  // Garbage after a valid start fails in the header, whatever the bytes are.
  const InputError e = parseError("ply\nformat binary_little_endian 1.0\n" + garbage);
  EXPECT_EQ(e.file(), "test.ply");
  EXPECT_FALSE(e.reason().empty());
  expectError("ply\nformat ascii 1.0\n\x01\x02\xff\n", "line 3", "unexpected header line '\\x01\\x02\\xff'");
}

TEST(PlyErrors, NoPoints) {
  expectError("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
              "end_header\n",
              "line 3", "no points");
  expectError(kXyzHeader + "nan 0 0\n0 inf 0\n0 0 -inf\n", "vertex data",
              "no finite points: all 3 points have a non-finite coordinate");
}

}  // namespace
}  // namespace stampscan::fitting
