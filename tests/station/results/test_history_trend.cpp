// The history's table and CSV, and the trend: the drift rule on synthetic sequences, and the image
// checked by content.
#include "results_test_support.hpp"
#include "stampscan/results/history_table.hpp"
#include "stampscan/results/trend.hpp"

#include <cairo.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <sstream>

namespace stampscan::results {
namespace {

using test::makeRun;

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

TEST(HistoryOutput, CsvHasEveryColumnAndQuotesWhatNeedsIt) {
  RunRow failed = makeRun("P2", "hood", 2, 8);
  failed.status = RunStatus::Failed;
  failed.reason = "cloud4d.ply: damaged, \"vertex 12\"";
  failed.min_margin_percent.reset();
  const auto csv = lines(historyCsv({makeRun("P1", "hood", 1, 8), failed}));
  ASSERT_EQ(csv.size(), 3u);
  EXPECT_EQ(csv[0],
            "run_id,part_id,program,plan,cell,started_utc,material,verdict,max_thinning_percent,min_margin_percent,"
            "marginal_band_percent,elements,position_rms_mm,strain_rms,data_loss,run_dir,status,reason");
  EXPECT_EQ(csv[1],
            "20261101-080000-P1,P1,hood,pan,virtual,2026-11-01T08:00:00Z,DC04,good,12.500000,20.000000,10.000000,1200,"
            ",,,runs/20261101-080000-P1,ok,");
  EXPECT_EQ(csv[2],
            "20261102-080000-P2,P2,hood,pan,virtual,2026-11-02T08:00:00Z,DC04,good,12.500000,,10.000000,1200,,,,"
            "runs/20261102-080000-P2,failed,\"cloud4d.ply: damaged, \"\"vertex 12\"\"\"");
}

TEST(HistoryOutput, TableShowsOneAlignedLinePerRun) {
  RunRow failed = makeRun("P2", "hood", 2, 8);
  failed.status = RunStatus::Failed;
  failed.reason = "no report.json";
  const auto table = lines(historyTable({makeRun("P1", "hood", 1, 8), failed}));
  ASSERT_EQ(table.size(), 3u);
  EXPECT_EQ(table[0].find("started (UTC)"), 0u);
  EXPECT_NE(table[1].find("2026-11-01T08:00:00Z  P1"), std::string::npos) << table[1];
  EXPECT_NE(table[1].find("20.0"), std::string::npos);
  EXPECT_NE(table[2].find("failed: no report.json"), std::string::npos) << table[2];
  // The verdict column starts at the same place on every line.
  EXPECT_EQ(table[0].find("verdict"), table[1].find("good"));
}

// Parts with the given min margins, one a day (good above 10 %, marginal below).
std::vector<RunRow> partsWithMargins(const std::vector<double>& margins) {
  std::vector<RunRow> runs;
  for (std::size_t k = 0; k < margins.size(); ++k)
    runs.push_back(makeRun(test::numbered("P", k + 1), "hood", static_cast<int>(k + 1), 8,
                           margins[k] < 10 ? "marginal" : "good", margins[k]));
  return runs;
}

TEST(Trend, SteadyPartsGiveNoWarning) {
  const TrendAnalysis t = analyzeTrend(partsWithMargins({21, 20, 21.5, 20.5, 21, 20.8}));
  ASSERT_TRUE(t.slope_per_part.has_value());
  EXPECT_FALSE(t.drifting) << t.message;
  EXPECT_EQ(t.points.size(), 6u);
}

TEST(Trend, PartsFallingTowardsTheBandWarn) {
  // Falling 2 %/part from 22: the last part (k = 5) at 12; five parts on, 2 < 10.
  const TrendAnalysis t = analyzeTrend(partsWithMargins({30, 30, 20, 18, 16, 14, 12}));
  ASSERT_TRUE(t.slope_per_part.has_value());
  EXPECT_NEAR(*t.slope_per_part, -2.0, 1e-9);
  EXPECT_NEAR(*t.projected_margin, 2.0, 1e-9);  // 12 - 2 * 5
  EXPECT_EQ(t.fit_first, 2u);                    // the last five parts only
  EXPECT_TRUE(t.drifting);
  EXPECT_NE(t.message.find("WARNING"), std::string::npos) << t.message;
}

TEST(Trend, ASlowFallFarFromTheBandDoesNotWarn) {
  // Falling 0.5 %/part at 30: five parts on, 27.5, far above the band.
  const TrendAnalysis t = analyzeTrend(partsWithMargins({32, 31.5, 31, 30.5, 30}));
  EXPECT_NEAR(*t.slope_per_part, -0.5, 1e-9);
  EXPECT_FALSE(t.drifting) << t.message;
}

TEST(Trend, TooFewPartsGiveNoTrendAndFailedRunsAreLeftOut) {
  std::vector<RunRow> runs = partsWithMargins({20, 12});
  RunRow failed = makeRun("P9", "hood", 9, 8);
  failed.status = RunStatus::Failed;
  failed.reason = "no report.json";
  runs.push_back(failed);
  const TrendAnalysis t = analyzeTrend(runs);
  EXPECT_FALSE(t.slope_per_part.has_value());
  EXPECT_FALSE(t.drifting);
  EXPECT_EQ(t.points.size(), 2u);
  EXPECT_EQ(t.runs_not_analysed, 1u);
  EXPECT_NE(t.message.find("no trend yet"), std::string::npos) << t.message;
}

TEST(Trend, TheImageShowsThePartsInTheirVerdictColours) {
  test::TempDir dir;
  const TrendAnalysis t = analyzeTrend(partsWithMargins({30, 30, 20, 18, 16, 14, 12, 8}));
  const auto png = dir.path() / "trend.png";
  writeTrendImage(t, "hood", png);
  cairo_surface_t* image = cairo_image_surface_create_from_png(png.c_str());
  ASSERT_EQ(cairo_surface_status(image), CAIRO_STATUS_SUCCESS);
  EXPECT_EQ(cairo_image_surface_get_width(image), 960);
  EXPECT_EQ(cairo_image_surface_get_height(image), 640);
  // Count pixels in the verdict colours: green parts and the one marginal (orange) part are drawn.
  const unsigned char* data = cairo_image_surface_get_data(image);
  const int stride = cairo_image_surface_get_stride(image);
  int green = 0, orange = 0;
  const auto near = [](const unsigned char* p, int r, int g, int b) {
    return std::abs(p[2] - r) <= 3 && std::abs(p[1] - g) <= 3 && std::abs(p[0] - b) <= 3;
  };
  for (int y = 0; y < 640; ++y)
    for (int x = 0; x < 960; ++x) {
      const unsigned char* p = data + y * stride + 4 * x;  // B, G, R, A
      if (near(p, 41, 148, 61)) ++green;    // verdictColour("good")
      if (near(p, 242, 153, 18)) ++orange;  // verdictColour("marginal")
    }
  cairo_surface_destroy(image);
  EXPECT_GT(green, 7 * 2 * 20);  // 7 good parts in two panels, ~60 px per dot, plus the legend
  EXPECT_GT(orange, 2 * 20);
  EXPECT_FALSE(std::filesystem::exists(png.string() + ".tmp-trend"));
}

}  // namespace
}  // namespace stampscan::results
