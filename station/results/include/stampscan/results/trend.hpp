// The trend of one press program: max thinning, min safety margin and verdict per part over time,
// and a warning when the last parts drift towards the marginal band.
//
// The drift rule (stated here because an operator acts on it): over the last `window` analysed parts
// that have a safety margin (at least `min_points` of them), fit the min safety margin against the
// part's position in the sequence by least squares. Warn when the slope is negative and the fitted
// line, carried `window` parts beyond the last part, is below the marginal band (the material's
// safety margin from the report; `default_band_percent` when the report gave none). That is: at the
// present rate, the parts reach the marginal zone within as many parts again.
#pragma once

#include "stampscan/results/results_store.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::results {

struct TrendParams {
  std::size_t window = 5;
  std::size_t min_points = 3;
  double default_band_percent = 10.0;
};

struct TrendPoint {
  std::string run_id, part_id, started_utc, verdict;
  std::optional<double> max_thinning_percent, min_margin_percent;
};

struct TrendAnalysis {
  std::vector<TrendPoint> points;  // the analysed (ok) runs, oldest first
  std::size_t runs_not_analysed = 0;  // failed or aborted runs of the program, not in the points
  double band_percent = 10.0;         // the marginal band the rule compares with
  // The least-squares line of the min margin over the last window: margin = intercept + slope * k,
  // k the index into `points`; empty when fewer than min_points parts have a margin.
  std::optional<double> slope_per_part, intercept;
  std::size_t fit_first = 0, fit_last = 0;  // indices into points of the fitted window
  std::optional<double> projected_margin;   // the line at fit_last + window
  bool drifting = false;
  std::string message;  // the warning, or what the trend says when there is none
};

TrendAnalysis analyzeTrend(const std::vector<RunRow>& runs, const TrendParams& params = {});
// The rule above, in one line, for the command's output.
std::string describeTrendRule(const TrendParams& params);
// One line per part: time, part, max thinning, min margin, verdict.
std::string trendTable(const TrendAnalysis& trend);
// The trend as a PNG: min safety margin (with the marginal band and the fitted line) and max
// thinning per part, points coloured by verdict. Written under a temporary name and renamed into
// place; throws std::runtime_error naming the file when it cannot be written.
void writeTrendImage(const TrendAnalysis& trend, const std::string& program, const std::filesystem::path& png);

}  // namespace stampscan::results
