#include "stampscan/results/trend.hpp"

#include "stampscan/results/history_table.hpp"

#include <algorithm>
#include <cstdio>

namespace stampscan::results {

TrendAnalysis analyzeTrend(const std::vector<RunRow>& runs, const TrendParams& params) {
  TrendAnalysis t;
  t.band_percent = params.default_band_percent;
  for (const RunRow& r : runs) {
    if (r.status != RunStatus::Ok) {
      ++t.runs_not_analysed;
      continue;
    }
    t.points.push_back({r.run_id, r.part_id, r.started_utc, r.verdict, r.max_thinning_percent, r.min_margin_percent});
    if (r.marginal_band_percent) t.band_percent = *r.marginal_band_percent;  // the latest part's material
  }
  // The last `window` parts that have a margin (a part whose strain paths never meet the FLC has none).
  std::vector<std::size_t> fitted;
  for (std::size_t k = t.points.size(); k-- > 0 && fitted.size() < params.window;)
    if (t.points[k].min_margin_percent) fitted.push_back(k);
  std::reverse(fitted.begin(), fitted.end());
  char text[320];
  if (fitted.size() < std::max<std::size_t>(params.min_points, 2)) {
    std::snprintf(text, sizeof text, "no trend yet: %zu part(s) with a safety margin, the rule needs %zu",
                  fitted.size(), std::max<std::size_t>(params.min_points, 2));
    t.message = text;
    return t;
  }
  double mean_k = 0, mean_m = 0;
  for (std::size_t k : fitted) {
    mean_k += static_cast<double>(k);
    mean_m += *t.points[k].min_margin_percent;
  }
  const double n = static_cast<double>(fitted.size());
  mean_k /= n;
  mean_m /= n;
  double skk = 0, skm = 0;
  for (std::size_t k : fitted) {
    const double dk = static_cast<double>(k) - mean_k;
    skk += dk * dk;
    skm += dk * (*t.points[k].min_margin_percent - mean_m);
  }
  const double slope = skm / skk;  // skk > 0: at least two distinct indices
  t.slope_per_part = slope;
  t.intercept = mean_m - slope * mean_k;
  t.fit_first = fitted.front();
  t.fit_last = fitted.back();
  t.projected_margin = *t.intercept + slope * static_cast<double>(t.fit_last + params.window);
  t.drifting = slope < 0 && *t.projected_margin < t.band_percent;
  if (t.drifting)
    std::snprintf(text, sizeof text,
                  "WARNING: min safety margin falling %.2f%%/part over the last %zu parts; at this rate it reaches "
                  "%.1f%% within %zu more parts, inside the marginal band (%.1f%%)",
                  -slope, fitted.size(), *t.projected_margin, params.window, t.band_percent);
  else
    std::snprintf(text, sizeof text,
                  "no drift: min safety margin %+.2f%%/part over the last %zu parts, %.1f%% in %zu more parts "
                  "(marginal band %.1f%%)",
                  slope, fitted.size(), *t.projected_margin, params.window, t.band_percent);
  t.message = text;
  return t;
}

std::string describeTrendRule(const TrendParams& params) {
  char text[320];
  std::snprintf(text, sizeof text,
                "rule: least-squares slope of the min safety margin over the last %zu parts (at least %zu); warn when "
                "it falls and the line %zu parts on is below the marginal band",
                params.window, params.min_points, params.window);
  return text;
}

std::string trendTable(const TrendAnalysis& trend) {
  std::string out = "  #  started (UTC)         part                  max thin %  min margin %  verdict\n";
  char line[256];
  for (std::size_t k = 0; k < trend.points.size(); ++k) {
    const TrendPoint& p = trend.points[k];
    std::snprintf(line, sizeof line, "%3zu  %-20s  %-20s  %10s  %12s  %s\n", k + 1, p.started_utc.c_str(),
                  p.part_id.c_str(), formatNumber(p.max_thinning_percent, 1).c_str(),
                  formatNumber(p.min_margin_percent, 1).c_str(), p.verdict.c_str());
    out += line;
  }
  return out;
}

}  // namespace stampscan::results
