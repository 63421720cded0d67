// The panel's analysis and settings parts that need no cell: the live cloud's bounds, a run's
// elements read from its Cloud4D (with and without the major direction), the section profile, the
// comparison of two runs, and the cell settings' ranges and their writing into a cell file.
#include "stampscan/fitting/ply_io.hpp"
#include "stampscan/hmi/cell_settings.hpp"
#include "stampscan/hmi/live_cloud.hpp"
#include "stampscan/hmi/run_files.hpp"
#include "stampscan/hmi/strain_views.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

namespace stampscan::hmi {
namespace {

namespace fs = std::filesystem;
using fitting::Vec3;

class TempDir {
 public:
  TempDir() {
    std::random_device device;
    path_ = fs::temp_directory_path() / ("stampscan_hmi_views_" + std::to_string(device()) + std::to_string(device()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::vector<registration::GridElement> elementsAlongX(std::size_t n) {
  std::vector<registration::GridElement> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    out[i].position = Vec3(static_cast<double>(i), 0, 0);
    out[i].thickness_strain = -0.01;
  }
  return out;
}

TEST(HmiLiveCloud, BatchesAndTheWholeScanStayBounded) {
  LiveCloud cloud(100, 250);
  cloud.reset("run-1");
  const LivePoints first = cloud.add(elementsAlongX(50));
  EXPECT_EQ(first.size(), 50u) << "a small batch is kept whole";
  EXPECT_EQ(first.xyz.size(), 150u);
  const LivePoints second = cloud.add(elementsAlongX(1000));
  EXPECT_LE(second.size(), 100u);
  EXPECT_GE(second.size(), 90u) << "every k-th element, not the first hundred";
  EXPECT_GT(second.xyz[3 * (second.size() - 1)], 900.0) << "the decimation spreads over the whole sweep";
  for (int i = 0; i < 5; ++i) cloud.add(elementsAlongX(1000));
  const LiveCloud::Snapshot s = cloud.snapshot();
  EXPECT_EQ(s.run_id, "run-1");
  EXPECT_LE(s.points.size(), 250u);
  EXPECT_EQ(s.measured, 6050u) << "every measured element is counted, shown or not";
  EXPECT_EQ(s.batches, 7u);
  cloud.reset();
  EXPECT_EQ(cloud.snapshot().points.size(), 0u);
}

// A 10 x 8 grid at the 2.54 mm pitch on a slope z = 0.1 x; uniform strains; the major direction x.
fitting::Cloud gridCloud(double thickness, double shift_x, bool directions) {
  fitting::Cloud c;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 8; ++j) {
      const double x = i * 2.54 + shift_x;
      c.positions.emplace_back(x, j * 2.54, 0.1 * x);
      c.normals.emplace_back(0, 0, 1);
      c.strain.push_back(thickness);
      c.scalars["major_strain"].push_back(0.04);
      c.scalars["minor_strain"].push_back(0.01);
      if (directions) {
        c.scalars["major_dir_x"].push_back(2.0);  // not unit: the reader normalises it
        c.scalars["major_dir_y"].push_back(0);
        c.scalars["major_dir_z"].push_back(0);
      }
    }
  return c;
}

TEST(HmiStrainViews, ElementsComeWithTheirMajorDirectionWhenTheCloudHasIt) {
  TempDir dir;
  fitting::writePly(dir.path() / "with.ply", gridCloud(-0.05, 0, true));
  const RunElements e = loadRunElements(dir.path() / "with.ply");
  ASSERT_EQ(e.size(), 80u);
  ASSERT_TRUE(e.hasDirections());
  EXPECT_NEAR(e.directions[5].x(), 1.0, 1e-9);
  EXPECT_NEAR(e.major[5], 0.04, 1e-6);
  EXPECT_NEAR(percentOf(StrainQuantity::Thinning, e, 5), (1 - std::exp(-0.05)) * 100, 1e-4);
  EXPECT_NEAR(percentOf(StrainQuantity::Major, e, 5), (std::exp(0.04) - 1) * 100, 1e-4);

  fitting::writePly(dir.path() / "without.ply", gridCloud(-0.05, 0, false));
  EXPECT_FALSE(loadRunElements(dir.path() / "without.ply").hasDirections());

  fitting::Cloud bare = gridCloud(-0.05, 0, false);
  bare.scalars.erase("major_strain");
  fitting::writePly(dir.path() / "bare.ply", bare);
  try {
    loadRunElements(dir.path() / "bare.ply");
    ADD_FAILURE() << "a cloud without major strain was read";
  } catch (const std::runtime_error& err) {
    EXPECT_NE(std::string(err.what()).find("major_strain"), std::string::npos) << err.what();
  }
  try {
    loadRunElements(dir.path() / "none.ply");
    ADD_FAILURE() << "a missing file was read";
  } catch (const RunFileError& err) {
    EXPECT_EQ(err.status(), 404);
  }
}

TEST(HmiStrainViews, ASectionTakesOneRowOfElementsInOrderWithItsLength) {
  TempDir dir;
  fitting::writePly(dir.path() / "c.ply", gridCloud(-0.05, 0, true));
  const RunElements e = loadRunElements(dir.path() / "c.ply");
  // An x cut through the fourth column: its 8 elements, by y, 7 pitches long.
  const auto x_cut = sectionProfile(e, {0, 3 * 2.54, 1.27});
  ASSERT_EQ(x_cut.size(), 8u);
  for (std::size_t k = 1; k < x_cut.size(); ++k) EXPECT_GT(x_cut[k].position.y(), x_cut[k - 1].position.y());
  EXPECT_NEAR(x_cut.back().along_mm, 7 * 2.54, 1e-6);
  EXPECT_NEAR(x_cut.front().thinning_percent, (1 - std::exp(-0.05)) * 100, 1e-4);
  // A y cut runs up the slope: its length is the slope's, not its plan's.
  const auto y_cut = sectionProfile(e, {1, 2.54, 1.27});
  ASSERT_EQ(y_cut.size(), 10u);
  EXPECT_NEAR(y_cut.back().along_mm, 9 * 2.54 * std::sqrt(1.01), 1e-6);
  // Between two rows with a narrow band: nothing.
  EXPECT_TRUE(sectionProfile(e, {0, 1.27, 0.5}).empty());
  EXPECT_THROW(sectionProfile(e, {3, 0, 1}), std::invalid_argument);
  EXPECT_THROW(sectionProfile(e, {0, 0, 0}), std::invalid_argument);
  EXPECT_THROW(sectionProfile(e, {0, std::nan(""), 1}), std::invalid_argument);
}

TEST(HmiStrainViews, AZCutGoesAroundTheContour) {
  RunElements ring;
  for (int k = 0; k < 12; ++k) {
    const double a = 2 * M_PI * ((k * 5) % 12) / 12.0;  // out of order on purpose
    ring.positions.emplace_back(10 * std::cos(a), 10 * std::sin(a), 5);
    ring.thickness.push_back(-0.01 * k);
    ring.major.push_back(0.02);
    ring.minor.push_back(0);
  }
  const auto cut = sectionProfile(ring, {2, 5, 1});
  ASSERT_EQ(cut.size(), 12u);
  // In order around the ring: each step one twelfth of the circle.
  for (std::size_t k = 1; k < cut.size(); ++k)
    EXPECT_NEAR(cut[k].along_mm - cut[k - 1].along_mm, 2 * 10 * std::sin(M_PI / 12), 1e-9);
}

TEST(HmiStrainViews, TheDifferenceOfTwoRunsIsBMinusAOnTheNearestElements) {
  TempDir dir;
  fitting::writePly(dir.path() / "a.ply", gridCloud(-0.05, 0, true));
  fitting::writePly(dir.path() / "b.ply", gridCloud(-0.08, 0.3, true));
  const RunElements a = loadRunElements(dir.path() / "a.ply"), b = loadRunElements(dir.path() / "b.ply");
  const Comparison c = compareRuns(a, b, StrainQuantity::Thinning, 2.54);
  const double expected = (1 - std::exp(-0.08)) * 100 - (1 - std::exp(-0.05)) * 100;
  EXPECT_EQ(c.matched, 80u);
  EXPECT_NEAR(c.mean, expected, 1e-4);
  EXPECT_NEAR(c.rms, expected, 1e-4);
  EXPECT_NEAR(c.min, expected, 1e-4);
  EXPECT_NEAR(c.max, expected, 1e-4);
  EXPECT_NEAR(compareRuns(a, b, StrainQuantity::Major, 2.54).max, 0, 1e-6) << "the same major strain";
  // With a match distance under B's shift, nothing matches; A against itself is zero everywhere.
  EXPECT_EQ(compareRuns(a, b, StrainQuantity::Thinning, 0.2).matched, 0u);
  const Comparison self = compareRuns(a, a, StrainQuantity::Minor);
  EXPECT_EQ(self.matched, 80u);
  EXPECT_EQ(self.rms, 0);

  // Carried onto surface points: a point near the grid takes its nearest element's value; one far
  // off takes none.
  const auto on = onPoints({Vec3(1.0, 1.0, 0.1), Vec3(100, 100, 0)}, a, c.difference, 2.54);
  ASSERT_TRUE(on[0]);
  EXPECT_NEAR(*on[0], expected, 1e-4);
  EXPECT_FALSE(on[1]);
  EXPECT_THROW(strainQuantityFromString("stress"), std::invalid_argument);
}

TEST(HmiCellSettings, ValuesAreCheckedAgainstTheirRanges) {
  acquisition::CalibrationPolicy p;
  const auto changed = withSettings(p, {{"validity_days", 3}, {"form_mpe_mm", 0.08}});
  EXPECT_EQ(changed.validity_days, 3);
  EXPECT_EQ(changed.form_mpe_mm, 0.08);
  EXPECT_EQ(changed.size_mpe_mm, p.size_mpe_mm) << "what was not asked for stays";
  EXPECT_EQ(settingsOf(changed).at("validity_days"), 3);
  try {
    withSettings(p, {{"validity_days", 7000}});
    ADD_FAILURE() << "7000 days were accepted";
  } catch (const SettingsError& e) {
    EXPECT_NE(std::string(e.what()).find("validity_days"), std::string::npos) << e.what();
  }
  EXPECT_THROW(withSettings(p, {{"results_database", 1}}), SettingsError);
  EXPECT_THROW(withSettings(p, {{"size_mpe_mm", -1}}), SettingsError);
  EXPECT_THROW(withSettings(p, {{"size_mpe_mm", std::nan("")}}), SettingsError);
}

TEST(HmiCellSettings, AChangeIsWrittenIntoTheCellFileKeepingItsComments) {
  TempDir dir;
  const fs::path cell = dir.path() / "cell.toml";
  std::ofstream(cell) << "# our cell\nname = \"press line 4\"\n\n[calibration]  # the rules\n"
                         "validity_days = 7   # a week\nform_mpe_mm = 0.100\n\n[results]\n# database = \"x\"\n";
  writeCellSettings(cell, {{"validity_days", 2.5}, {"size_mpe_mm", 0.02}});
  std::ifstream in(cell);
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  EXPECT_NE(text.find("validity_days = 2.5   # a week"), std::string::npos) << text;
  EXPECT_NE(text.find("size_mpe_mm = 0.02"), std::string::npos) << text;
  EXPECT_NE(text.find("# our cell"), std::string::npos) << text;
  EXPECT_LT(text.find("size_mpe_mm"), text.find("[results]")) << "the new key goes into [calibration]\n" << text;
  const acquisition::CellConfig config = acquisition::loadCellConfig(cell);
  EXPECT_EQ(config.calibration.validity_days, 2.5);
  EXPECT_EQ(config.calibration.size_mpe_mm, 0.02);
  EXPECT_EQ(config.calibration.form_mpe_mm, 0.1);
  EXPECT_EQ(config.name, "press line 4");
  // A file without the table gets one.
  std::ofstream(cell) << "name = \"bare\"\n";
  writeCellSettings(cell, {{"validity_days", 3}});
  EXPECT_EQ(acquisition::loadCellConfig(cell).calibration.validity_days, 3);
  EXPECT_THROW(writeCellSettings(dir.path() / "missing.toml", {{"validity_days", 3}}), std::runtime_error);
  // Nothing but the file is left behind (the temporary is renamed over it).
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir.path())) ++files;
  EXPECT_EQ(files, 1u);
}

}  // namespace
}  // namespace stampscan::hmi
