// UDIM tiles of a low mesh (udim.hpp).
#include "nmbake/udim.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace nmbake {

bool has_udim_token(const std::string& path) { return path.find(kUdimToken) != std::string::npos; }

std::string udim_path(const std::string& path, int tile) {
  std::string out = path;
  const std::string token = kUdimToken;
  const std::string number = std::to_string(tile);
  for (std::size_t at = out.find(token); at != std::string::npos; at = out.find(token, at + number.size())) {
    out.replace(at, token.size(), number);
  }
  return out;
}

glm::vec2 udim_offset(int tile) {
  const int index = tile - 1001;
  return glm::vec2(static_cast<float>(index % 10), static_cast<float>(index / 10));
}

Status find_udim_tiles(const Mesh& low, const std::string& low_path, bool udim, std::vector<int>& tiles) {
  tiles.clear();
  std::set<int> used;
  for (std::size_t t = 0; t < low.triangle_count(); ++t) {
    const glm::vec2 c =
        (low.uvs[low.indices[3 * t]] + low.uvs[low.indices[3 * t + 1]] + low.uvs[low.indices[3 * t + 2]]) /
        3.0f;
    const double u = std::floor(static_cast<double>(c.x));
    const double v = std::floor(static_cast<double>(c.y));
    if (u < 0.0 || u > 9.0 || v < 0.0 || v > 99.0) {
      return Status::bad_input(low_path + ": triangle " + std::to_string(t) + " has its UVs around (" +
                               std::to_string(c.x) + ", " + std::to_string(c.y) +
                               "), outside every UDIM tile (u 0 to 10, v 0 to 100)");
    }
    used.insert(1001 + static_cast<int>(u) + 10 * static_cast<int>(v));
  }
  tiles.assign(used.begin(), used.end());
  if (!udim && (tiles.size() != 1 || tiles.front() != 1001)) {
    std::string list;
    for (const int tile : tiles) list += (list.empty() ? "" : ", ") + std::to_string(tile);
    return Status::bad_input(
        low_path + ": UVs lie outside [0, 1]^2 (UDIM tiles " + list +
        "): put <UDIM> in the output path to bake one map per tile, e.g. -o normal.<UDIM>.png");
  }
  return Status::ok();
}

}  // namespace nmbake
