// The material library: the built-in file, lookups, and errors that name the file and the entry.
#include "stampscan/report/material.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace stampscan::report {
namespace {

TEST(Materials, BuiltInLibraryHasTheDefaultAndBothFamilies) {
  const MaterialLibrary& library = builtInMaterials();
  const Material& dc04 = library.find(kDefaultMaterial);
  EXPECT_EQ(dc04.family, MaterialFamily::Steel);
  EXPECT_DOUBLE_EQ(dc04.safety_margin_percent, 10.0);
  EXPECT_FALSE(dc04.flc.isMeasured());
  EXPECT_NEAR(dc04.flc.flc0(), keelerBrazierFlc0(dc04.thickness_mm, dc04.n), 1e-12);
  const Material& aluminium = library.find("aa5182-o");  // names are matched without case
  EXPECT_EQ(aluminium.family, MaterialFamily::Aluminium);
  EXPECT_DOUBLE_EQ(aluminium.safety_margin_percent, 8.0);
  EXPECT_TRUE(aluminium.flc.isMeasured());
  EXPECT_DOUBLE_EQ(library.find("DP600").safety_margin_percent, 8.0);  // set per material
}

TEST(Materials, UnknownMaterialNamesTheKnownOnes) {
  try {
    builtInMaterials().find("unobtainium");
    FAIL() << "no error";
  } catch (const MaterialError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("unobtainium"), std::string::npos) << what;
    EXPECT_NE(what.find("DC04"), std::string::npos) << what;
    EXPECT_NE(what.find("AA6016-T4"), std::string::npos) << what;
  }
}

TEST(Materials, ParsesEntriesWithAndWithoutMeasuredCurves) {
  const MaterialLibrary library = parseMaterials(R"(
[[material]]
name = "Test steel"
family = "steel"
thickness_mm = 2
n = 0.18

[[material]]
name = "Test alu"
family = "aluminium"
thickness_mm = 1.2
n = 0.27
safety_margin_percent = 6.5
flc_engineering_percent = [[-10, 30], [0, 22], [10, 26]]
)",
                                                 "test.toml");
  ASSERT_EQ(library.materials().size(), 2u);
  EXPECT_NEAR(library.find("Test steel").flc.flc0(), (23.3 + 14.13 * 2) * 0.18 / 0.21, 1e-9);
  EXPECT_DOUBLE_EQ(library.find("Test steel").safety_margin_percent, 10.0);
  EXPECT_DOUBLE_EQ(library.find("Test alu").safety_margin_percent, 6.5);
  EXPECT_DOUBLE_EQ(library.find("Test alu").flc.flc0(), 22.0);
  // A cell config's entry replaces the built-in one of the same name.
  MaterialLibrary merged = builtInMaterials();
  Material mine = library.find("Test steel");
  mine.name = "dc04";
  merged.add(mine);
  EXPECT_EQ(merged.materials().size(), builtInMaterials().materials().size());
  EXPECT_DOUBLE_EQ(merged.find("DC04").thickness_mm, 2.0);
}

void expectError(const std::string& toml, const std::string& expected) {
  try {
    parseMaterials(toml, "cell.toml");
    FAIL() << "no error for:\n" << toml;
  } catch (const MaterialError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cell.toml"), std::string::npos) << what;
    EXPECT_NE(what.find(expected), std::string::npos) << what;
  }
}

TEST(Materials, ErrorsNameTheFileTheEntryAndTheField) {
  expectError("[[material]\nname = 1", "cell.toml:1");  // TOML syntax: file and line
  expectError("[[material]]\nname = \"X\"\nfamily = \"steel\"\nn = 0.2\n", "thickness_mm");
  expectError("[[material]]\nname = \"X\"\nfamily = \"brass\"\nthickness_mm = 1\nn = 0.2\n", "brass");
  expectError("[[material]]\nname = \"X\"\nfamily = \"steel\"\nthickness_mm = -1\nn = 0.2\n", "X");
  expectError(
      "[[material]]\nname = \"X\"\nfamily = \"steel\"\nthickness_mm = 1\nn = 0.2\nflc_engineering_percent = [[0, "
      "20]]\n",
      "at least two points");
  expectError("[[material]]\nname = \"X\"\nfamily = \"steel\"\nthickness_mm = 1\nn = 0.2\ncolour = \"red\"\n",
              "colour");
  expectError(
      "[[material]]\nname = \"X\"\nfamily = \"steel\"\nthickness_mm = 1\nn = 0.2\n"
      "[[material]]\nname = \"x\"\nfamily = \"steel\"\nthickness_mm = 1\nn = 0.2\n",
      "twice");
  expectError("title = \"materials\"\n", "title");
}

TEST(Materials, LoadsAFileAndNamesAMissingOne) {
  const auto file = std::filesystem::temp_directory_path() / "stampscan_materials_test.toml";
  {
    std::ofstream out(file);
    out << "[[material]]\nname = \"Plate\"\nfamily = \"steel\"\nthickness_mm = 1.5\nn = 0.2\n";
  }
  EXPECT_TRUE(loadMaterials(file).contains("plate"));
  std::filesystem::remove(file);
  try {
    loadMaterials(file);
    FAIL() << "no error";
  } catch (const MaterialError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace stampscan::report
