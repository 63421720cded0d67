// The page's files, built into the program from station/hmi/web/ (embed_web.cmake), so that the
// panel works from the build tree and from an installed program alike, with no step to run.
#pragma once

#include <cstddef>
#include <span>
#include <string_view>

namespace stampscan::hmi {

struct WebAsset {
  std::string_view name;  // "index.html", "app.js", ...
  std::string_view bytes;
};
std::span<const WebAsset> webAssets();

}  // namespace stampscan::hmi
