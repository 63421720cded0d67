// Plain text clouds: whitespace- or comma-separated columns, one point a line, `#` comments.
// A file may start with a header line naming the columns (x, y, z and optionally strain, nx, ny,
// nz, other scalars by name, in any order); without one, the count of columns says what they are:
// x y z, x y z strain, x y z nx ny nz, x y z nx ny nz strain.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/ply_io.hpp"

#include <filesystem>
#include <string>

namespace stampscan::fitting {

Cloud readTextCloud(const std::filesystem::path& file, ReadReport* report = nullptr);
Cloud parseTextCloud(const std::string& text, const std::string& name, ReadReport* report = nullptr);

// Chooses the reader by extension (.ply, .xyz, .txt, .csv); throws InputError for others.
Cloud readCloud(const std::filesystem::path& file, ReadReport* report = nullptr);

}  // namespace stampscan::fitting
