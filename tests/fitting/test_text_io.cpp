// Plain-text clouds (.xyz, .txt, .csv) and the reader chosen by file extension.
#include "stampscan/fitting/text_io.hpp"

#include "io_test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

namespace stampscan::fitting {
namespace {

namespace fs = std::filesystem;
using test::contains;
using test::TempDir;
using test::writeFile;

// Checks that parsing `text` as "scan.csv" fails naming the file, the place and the reason.
void expectError(const std::string& text, const std::string& where, const std::string& reason) {
  try {
    parseTextCloud(text, "scan.csv");
    ADD_FAILURE() << "no InputError for:\n" << text;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "scan.csv");
    EXPECT_TRUE(contains(e.what(), "scan.csv: "));
    EXPECT_EQ(e.where(), where);
    EXPECT_TRUE(contains(e.reason(), reason));
  }
}

TEST(TextRead, XyzWithoutHeader) {
  ReadReport report;
  const Cloud cloud = parseTextCloud("# scanner export\n\n1 2 3\n  4.5\t-5e-3   6  \n+7,8;9\n", "a.xyz", &report);
  ASSERT_EQ(cloud.size(), 3u);
  EXPECT_EQ(cloud.positions[1], Vec3(4.5, -5e-3, 6));
  EXPECT_EQ(cloud.positions[2], Vec3(7, 8, 9));
  EXPECT_FALSE(cloud.hasStrain() || cloud.hasNormals() || !cloud.scalars.empty());
  EXPECT_EQ(report.points_read, 3u);
  EXPECT_EQ(report.skipped_nonfinite, 0u);
}

// Without a header, six columns are a point and its normal, seven the same and the strain: the
// common scanner exports (`x y z nx ny nz`), which need no header line to be read.
TEST(TextRead, SixOrSevenColumnsAreNormalsAndStrain) {
  const Cloud normals = parseTextCloud("1 2 3 0 0 1\n4 5 6 0.6 0 0.8\n", "n.xyz");
  ASSERT_EQ(normals.size(), 2u);
  ASSERT_TRUE(normals.hasNormals());
  EXPECT_EQ(normals.normals[1], Vec3(0.6, 0, 0.8));
  EXPECT_FALSE(normals.hasStrain());
  EXPECT_NO_THROW(normals.validate());
  const Cloud both = parseTextCloud("1,2,3,0,1,0,0.05\n4,5,6,1,0,0,-0.01\n", "ns.csv");
  ASSERT_EQ(both.size(), 2u);
  EXPECT_EQ(both.normals[0], Vec3(0, 1, 0));
  EXPECT_EQ(both.strain, (std::vector<double>{0.05, -0.01}));
  EXPECT_NO_THROW(both.validate());
}

TEST(TextRead, FourthColumnIsStrain) {
  const Cloud cloud = parseTextCloud("1 2 3 0.01 # first\r\n4 5 6 -0.02\r\n", "s.xyz");
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.strain, (std::vector<double>{0.01, -0.02}));
}

TEST(TextRead, HeaderNamesColumnsInAnyOrderAndCase) {
  const std::string text =
      "\"Z\",\"X\",Y,Strain,major_strain,NX,ny,nZ\n"
      "3, 1, 2, 0.1, 0.5, 0, 0, 1\n"
      "6, 4, 5, 0.2, 0.6, 0, 1, 0\n";
  const Cloud cloud = parseTextCloud(text, "h.csv");
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.positions[0], Vec3(1, 2, 3));
  EXPECT_EQ(cloud.positions[1], Vec3(4, 5, 6));
  EXPECT_EQ(cloud.strain, (std::vector<double>{0.1, 0.2}));
  EXPECT_EQ(cloud.normals[1], Vec3(0, 1, 0));
  ASSERT_EQ(cloud.scalars.size(), 1u);
  EXPECT_EQ(cloud.scalars.at("major_strain"), (std::vector<double>{0.5, 0.6}));
  EXPECT_NO_THROW(cloud.validate());
}

TEST(TextRead, SkipsAndCountsNonFinitePoints) {
  ReadReport report;
  const Cloud cloud =
      parseTextCloud("x;y;z;strain;t\n1;2;3;0.1;10\nnan;2;3;0.2;20\n1;inf;3;0.3;30\n4;5;6;nan;40\n", "n.csv", &report);
  EXPECT_EQ(report.points_read, 2u);
  EXPECT_EQ(report.skipped_nonfinite, 2u);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.scalars.at("t"), (std::vector<double>{10, 40}));
  EXPECT_TRUE(std::isnan(cloud.strain[1]));
}

TEST(TextErrors, WrongColumnCount) {
  expectError("1 2 3\n4 5 6\n7 8\n", "line 3", "expected 3 columns (x y z), found 2");
  expectError("# c\n1 2 3 4\n5 6 7\n", "line 3", "expected 4 columns (x y z strain), found 3");
  expectError("1 2 3 4 5\n", "line 1", "expected 3, 4, 6 or 7 columns (x y z [nx ny nz] [strain]), found 5");
  expectError("1 2 3 4 5 6 7 8\n", "line 1", "expected 3, 4, 6 or 7 columns (x y z [nx ny nz] [strain]), found 8");
  expectError("1 2 3 0 0 1\n4 5 6 0 1\n", "line 2", "expected 6 columns (x y z nx ny nz), found 5");
  expectError("x,y,z,q\n1,2,3\n", "line 2", "expected 4 columns (x y z q), found 3");
}

TEST(TextErrors, BadNumbers) {
  expectError("1 2 3\n4 five 6\n", "line 2", "bad number 'five' in column 2 (y)");
  expectError("1 2 3x\n", "line 1", "bad number '3x' in column 3");
  expectError("x y z\n1 2 0x10\n", "line 2", "bad number '0x10' in column 3 (z)");
}

TEST(TextErrors, BadHeaders) {
  expectError("x,y,depth\n1,2,3\n", "line 1", "header line has no column 'z'");
  expectError("x,y,z,X\n1,2,3,4\n", "line 1", "column 'X' appears twice");
  expectError("x,y,z,nx,ny\n1,2,3,4,5\n", "line 1", "nx, ny and nz must be given all three or not at all");
}

TEST(TextErrors, NoPoints) {
  expectError("", "", "no points");
  expectError("# only a comment\n\n   \n", "", "no points");
  expectError("x y z\n", "", "no points");
  expectError("nan 1 2\n1 -inf 2\n", "", "no finite points: all 2 points have a non-finite coordinate");
}

TEST(TextRead, ReadCloudChoosesByExtension) {
  TempDir dir;
  const std::string xyz = "1 2 3\n4 5 6\n";
  EXPECT_EQ(readCloud(writeFile(dir.path() / "a.XYZ", xyz)).size(), 2u);
  EXPECT_EQ(readCloud(writeFile(dir.path() / "a.txt", xyz)).size(), 2u);
  EXPECT_EQ(readCloud(writeFile(dir.path() / "a.Csv", "x,y,z\n1,2,3\n")).size(), 1u);
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
      "end_header\n1 2 3\n";
  EXPECT_EQ(readCloud(writeFile(dir.path() / "a.Ply", ply)).size(), 1u);

  ReadReport report;
  EXPECT_EQ(readTextCloud(writeFile(dir.path() / "b.xyz", "1 2 3\nnan 0 0\n"), &report).size(), 1u);
  EXPECT_EQ(report.skipped_nonfinite, 1u);

  const fs::path obj = writeFile(dir.path() / "a.obj", "v 1 2 3\n");
  try {
    readCloud(obj);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), obj.string()));
    EXPECT_TRUE(contains(e.reason(), "unsupported file type '.obj'"));
  }
  EXPECT_THROW(readCloud(dir.path() / "no_extension"), InputError);
}

TEST(TextRead, FileErrorsNameTheFile) {
  TempDir dir;
  const fs::path bad = writeFile(dir.path() / "bad.xyz", "1 2 3\n1 2\n");
  try {
    readTextCloud(bad);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), bad.string() + ": line 2: expected 3 columns (x y z), found 2");
  }
  try {
    readTextCloud(dir.path() / "missing.xyz");
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "missing.xyz"));
  }
  EXPECT_THROW(readTextCloud(dir.path()), InputError);
}

}  // namespace
}  // namespace stampscan::fitting
