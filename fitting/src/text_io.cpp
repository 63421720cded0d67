// Plain-text clouds: one point a line, columns split by spaces, tabs, commas or semicolons, `#`
// starting a comment. An optional first line of column names says what each column holds; without
// one, the count of columns does, as the common exports write them: x y z, x y z strain,
// x y z nx ny nz, x y z nx ny nz strain.
#include "stampscan/fitting/text_io.hpp"

#include "io_detail.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <optional>
#include <string_view>
#include <unordered_set>
#include <vector>

namespace stampscan::fitting {

using detail::excerpt;
using detail::parseNumber;
using detail::readWholeFile;

namespace {

bool isSeparator(char c) {
  return c == ' ' || c == '\t' || c == ',' || c == ';' || c == '\r' || c == '\v' || c == '\f';
}

// Runs of separators count as one, so "1, 2, 3" and aligned columns both work.
void splitColumns(std::string_view line, std::vector<std::string_view>& tokens) {
  tokens.clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && isSeparator(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !isSeparator(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
}

std::string lowercase(std::string_view text) {
  std::string out(text);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); });
  return out;
}

enum class Role { X, Y, Z, NX, NY, NZ, Strain, Scalar };

struct Column {
  std::string name;
  Role role = Role::Scalar;
  std::vector<double>* scalar = nullptr;  // for Role::Scalar: its entry in Cloud::scalars
};

struct Layout {
  std::vector<Column> columns;
  std::array<std::size_t, 3> position{};
  std::optional<std::array<std::size_t, 3>> normal;
  std::optional<std::size_t> strain;
};

std::string describeColumns(const Layout& layout) {
  std::string names;
  for (const Column& column : layout.columns) names += (names.empty() ? "" : " ") + column.name;
  return names;
}

Layout layoutFromRoles(std::vector<Column> columns, const std::string& file, const std::string& where) {
  Layout layout;
  std::array<std::optional<std::size_t>, 7> found;  // indexed by Role, up to Strain
  for (std::size_t i = 0; i < columns.size(); ++i) {
    if (columns[i].role == Role::Scalar) continue;
    auto& slot = found[static_cast<std::size_t>(columns[i].role)];
    if (slot) throw InputError(file, where, "column " + excerpt(columns[i].name) + " appears twice");
    slot = i;
  }
  for (const auto& [role, axis] : {std::pair{Role::X, "x"}, std::pair{Role::Y, "y"}, std::pair{Role::Z, "z"}}) {
    const auto& slot = found[static_cast<std::size_t>(role)];
    if (!slot) throw InputError(file, where, std::string("header line has no column '") + axis + "'");
    layout.position[static_cast<std::size_t>(role)] = *slot;
  }
  const auto& nx = found[static_cast<std::size_t>(Role::NX)];
  const auto& ny = found[static_cast<std::size_t>(Role::NY)];
  const auto& nz = found[static_cast<std::size_t>(Role::NZ)];
  if (nx && ny && nz) {
    layout.normal = std::array<std::size_t, 3>{*nx, *ny, *nz};
  } else if (nx || ny || nz) {
    throw InputError(file, where, "columns nx, ny and nz must be given all three or not at all");
  }
  layout.strain = found[static_cast<std::size_t>(Role::Strain)];
  layout.columns = std::move(columns);
  return layout;
}

// The first non-comment line either names the columns (no token is a number) or is the first point.
// Returns the layout, and whether that line was a header.
std::pair<Layout, bool> layoutFromFirstLine(const std::vector<std::string_view>& tokens, Cloud& cloud,
                                            const std::string& file, const std::string& where) {
  const auto numeric = std::count_if(tokens.begin(), tokens.end(), [](std::string_view token) {
    double ignored = 0.0;
    return parseNumber(token, ignored);
  });
  if (numeric == static_cast<std::ptrdiff_t>(tokens.size())) {
    const std::size_t n = tokens.size();
    if (n != 3 && n != 4 && n != 6 && n != 7) {
      throw InputError(file, where,
                       "expected 3, 4, 6 or 7 columns (x y z [nx ny nz] [strain]), found " + std::to_string(n) +
                           "; for other columns, start the file with a line naming them");
    }
    std::vector<Column> columns{{"x", Role::X}, {"y", Role::Y}, {"z", Role::Z}};
    if (n >= 6) {
      columns.push_back({"nx", Role::NX});
      columns.push_back({"ny", Role::NY});
      columns.push_back({"nz", Role::NZ});
    }
    if (n == 4 || n == 7) columns.push_back({"strain", Role::Strain});
    return {layoutFromRoles(std::move(columns), file, where), false};
  }
  if (numeric > 0) {
    double ignored = 0.0;
    const auto bad = std::find_if(tokens.begin(), tokens.end(), [&](std::string_view t) { return !parseNumber(t, ignored); });
    throw InputError(file, where,
                     "bad number " + excerpt(*bad) + " in column " + std::to_string(bad - tokens.begin() + 1) +
                         " (a header line must name every column)");
  }
  static constexpr std::array<std::pair<std::string_view, Role>, 7> kKnown{{{"x", Role::X},
                                                                            {"y", Role::Y},
                                                                            {"z", Role::Z},
                                                                            {"nx", Role::NX},
                                                                            {"ny", Role::NY},
                                                                            {"nz", Role::NZ},
                                                                            {"strain", Role::Strain}}};
  std::vector<Column> columns;
  std::unordered_set<std::string> scalarNames;
  for (std::string_view token : tokens) {
    if (token.size() >= 2 && (token.front() == '"' || token.front() == '\'') && token.back() == token.front()) {
      token = token.substr(1, token.size() - 2);  // CSV writers often quote names
    }
    Column column{std::string(token), Role::Scalar, nullptr};
    const std::string key = lowercase(token);
    for (const auto& [known, role] : kKnown) {
      if (key == known) column.role = role;
    }
    if (column.role == Role::Scalar && !scalarNames.insert(column.name).second) {
      throw InputError(file, where, "column " + excerpt(column.name) + " appears twice");
    }
    columns.push_back(std::move(column));
  }
  Layout layout = layoutFromRoles(std::move(columns), file, where);
  for (Column& column : layout.columns) {
    if (column.role == Role::Scalar) column.scalar = &cloud.scalars[column.name];  // map nodes do not move
  }
  return {std::move(layout), true};
}

}  // namespace

Cloud parseTextCloud(const std::string& text, const std::string& name, ReadReport* report) {
  Cloud cloud;
  std::optional<Layout> layout;
  std::vector<std::string_view> tokens;
  std::vector<double> row;
  std::size_t skippedNonfinite = 0;
  std::size_t lineNumber = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    ++lineNumber;
    std::string_view line(text.data() + pos, end - pos);
    pos = end + 1;
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    splitColumns(line, tokens);
    if (tokens.empty()) continue;

    if (!layout) {
      auto [firstLayout, isHeader] = layoutFromFirstLine(tokens, cloud, name, "line " + std::to_string(lineNumber));
      layout = std::move(firstLayout);
      row.assign(layout->columns.size(), 0.0);
      if (isHeader) continue;
    }
    if (tokens.size() != layout->columns.size()) {
      throw InputError(name, "line " + std::to_string(lineNumber),
                       "expected " + std::to_string(layout->columns.size()) + " columns (" + describeColumns(*layout) +
                           "), found " + std::to_string(tokens.size()));
    }
    for (std::size_t i = 0; i < tokens.size(); ++i) {
      if (!parseNumber(tokens[i], row[i])) {
        throw InputError(name, "line " + std::to_string(lineNumber),
                         "bad number " + excerpt(tokens[i]) + " in column " + std::to_string(i + 1) + " (" +
                             layout->columns[i].name + ")");
      }
    }
    const Vec3 position(row[layout->position[0]], row[layout->position[1]], row[layout->position[2]]);
    if (!position.allFinite()) {  // dropped with all its attributes, so the vectors stay aligned
      ++skippedNonfinite;
      continue;
    }
    cloud.positions.push_back(position);
    if (const auto& n = layout->normal) cloud.normals.emplace_back(row[(*n)[0]], row[(*n)[1]], row[(*n)[2]]);
    if (layout->strain) cloud.strain.push_back(row[*layout->strain]);
    for (std::size_t i = 0; i < layout->columns.size(); ++i) {
      if (layout->columns[i].scalar) layout->columns[i].scalar->push_back(row[i]);
    }
  }
  if (cloud.empty() && skippedNonfinite == 0) throw InputError(name, "", "no points");
  if (cloud.empty()) {
    throw InputError(name, "",
                     "no finite points: all " + std::to_string(skippedNonfinite) + " points have a non-finite coordinate");
  }
  if (report) {
    report->points_read = cloud.size();
    report->skipped_nonfinite = skippedNonfinite;
    report->faces_read = 0;
  }
  return cloud;
}

Cloud readTextCloud(const std::filesystem::path& file, ReadReport* report) {
  return parseTextCloud(readWholeFile(file), file.string(), report);
}

Cloud readCloud(const std::filesystem::path& file, ReadReport* report) {
  const std::string extension = lowercase(file.extension().string());
  if (extension == ".ply") return readPly(file, report);
  if (extension == ".xyz" || extension == ".txt" || extension == ".csv") return readTextCloud(file, report);
  throw InputError(file.string(), "",
                   "unsupported file type " + excerpt(file.extension().string()) + " (expected .ply, .xyz, .txt or .csv)");
}

}  // namespace stampscan::fitting
