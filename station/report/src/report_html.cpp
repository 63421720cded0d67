// The report as one self-contained HTML page: the same facts, verdict and tables as the PDF, the
// images embedded as data URIs so that the page can be mailed or filed on its own.
#include "report_document.hpp"
#include "stampscan/report/fld_plot.hpp"

#include <cstdio>

namespace stampscan::report::draw {

namespace {

std::string escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (const char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string base64(const std::string& bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const auto n = static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])) << 16 |
                   static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 1])) << 8 |
                   static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 2]));
    out += kAlphabet[n >> 18 & 63];
    out += kAlphabet[n >> 12 & 63];
    out += kAlphabet[n >> 6 & 63];
    out += kAlphabet[n & 63];
  }
  if (i < bytes.size()) {
    std::uint32_t n = static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])) << 16;
    if (i + 1 < bytes.size()) n |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 1])) << 8;
    out += kAlphabet[n >> 18 & 63];
    out += kAlphabet[n >> 12 & 63];
    out += i + 1 < bytes.size() ? kAlphabet[n >> 6 & 63] : '=';
    out += '=';
  }
  return out;
}

std::string cssColour(const Rgb& c) {
  char text[16];
  std::snprintf(text, sizeof text, "#%02x%02x%02x", c[0], c[1], c[2]);
  return text;
}

}  // namespace

std::string html(const ReportContent& c, const std::vector<std::pair<std::string, const std::string*>>& images) {
  const StrainAnalysis& a = *c.analysis;
  const Rgb verdict = verdictColour(a.verdict);
  std::string h;
  h += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  h += "<title>Forming analysis, part " + escape(c.run->part_id) + "</title>\n";
  h += "<style>\n"
       "body{font-family:'DejaVu Sans',Arial,sans-serif;margin:2em;color:#1a1a1a;max-width:1100px}\n"
       "table{border-collapse:collapse;margin:0.5em 0}td,th{padding:0.25em 0.7em;border-bottom:1px solid #ddd;"
       "text-align:left}th{background:#eee}\n"
       ".facts th{background:none;color:#555}\n"
       ".verdict{color:#fff;padding:0.8em 1em;font-size:1.1em;margin:1em 0}\n"
       ".verdict b{font-size:1.4em;text-transform:uppercase}\n"
       ".maps{display:grid;grid-template-columns:repeat(2,1fr);gap:0.5em}img{max-width:100%}\n"
       ".zone{display:inline-block;width:0.9em;height:0.9em;vertical-align:middle;margin-right:0.3em}\n"
       "</style>\n</head>\n<body>\n";
  h += "<h1>Forming analysis: part " + escape(c.run->part_id) + "</h1>\n<table class=\"facts\">\n";
  for (const auto& [label, value] : runFacts(c))
    h += "<tr><th>" + escape(label) + "</th><td>" + escape(value) + "</td></tr>\n";
  h += "</table>\n";
  h += "<div class=\"verdict\" style=\"background:" + cssColour(verdict) + "\">Verdict: <b>" + toString(a.verdict) +
       "</b><br>" + escape(a.verdict_reason) + "</div>\n";
  h += "<p>Max thinning " + formatPercent(a.max_thinning_percent) + "%, min safety margin " +
       formatPercent(a.min_margin_percent) + "%.</p>\n<p>";
  for (std::size_t z = 0; z < kZoneCount; ++z) {
    const Zone zone = static_cast<Zone>(z);
    h += "<span class=\"zone\" style=\"background:" + cssColour(zoneColour(zone)) + "\"></span>" + toString(zone) +
         ": " + std::to_string(a.count(zone)) + (z + 1 < kZoneCount ? " &nbsp; " : "");
  }
  h += "</p>\n";
  const auto image = [&](const std::string& name) -> std::string {
    for (const auto& [file, bytes] : images)
      if (file == name)
        return "<img alt=\"" + escape(name) + "\" src=\"data:image/png;base64," + base64(*bytes) + "\">";
    return "";
  };
  h += "<h2>Forming-limit diagram</h2>\n" + image("fld.png") + "\n";
  h += "<h2>Worst spots</h2>\n<p>Lowest safety margin first; marked by number on the maps.</p>\n<table>\n<tr>";
  for (const std::string& col : worstSpotHeader()) h += "<th>" + escape(col) + "</th>";
  h += "</tr>\n";
  for (const auto& row : worstSpotRows(a)) {
    h += "<tr>";
    for (const std::string& cell : row) h += "<td>" + escape(cell) + "</td>";
    h += "</tr>\n";
  }
  h += "</table>\n";
  for (const MapQuantity q : kMapQuantities) {
    h += std::string("<h2>") + caption(q) + "</h2>\n<div class=\"maps\">\n";
    for (const View& v : standardViews()) h += image(strainMapFileName(q, v)) + "\n";
    h += "</div>\n";
  }
  h += "<p><small>StampScan forming analysis, " + escape(c.generated) + "</small></p>\n</body>\n</html>\n";
  return h;
}

}  // namespace stampscan::report::draw
