// Texture sets: one map set per material of the low mesh, as Substance
// Painter and Marmoset name them. An output path with the token <SET>
// (`hero_<SET>_<MAP>.png`) bakes one map set per low material, each from
// that material's triangles alone; the other triangles are left out of the
// map as another UDIM tile's are (their texels are empty, and padding
// fills them from the set's charts as at any chart border). A set's map is
// therefore byte for byte the map of the same low mesh with the other
// sets' triangles moved to another UV tile.
//
// Path tokens resolved with the low mesh's file name: <LOW> is the low
// file's stem (`<LOW>_<MAP>.png` next to `hero_low.fbx` gives
// `hero_low_normal.png`).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/mesh.hpp"

namespace nmbake {

inline constexpr const char* kSetToken = "<SET>";
inline constexpr const char* kLowToken = "<LOW>";

bool has_set_token(const std::string& path);
// `path` with every `token` replaced by `value`.
std::string replace_token(const std::string& path, const std::string& token, const std::string& value);

// One texture set: a low material's name, the name it takes in a path
// (characters other than letters, digits, '.', '-' and '_' become '_'; the
// triangles without a material are the set "default"), and its triangles.
struct LowSet {
  std::string name;                     // the material's name as the file gives it ("" for none)
  std::string path_name;                // what <SET> becomes
  std::vector<std::uint8_t> triangles;  // 1 per triangle of the set, else 0
};

// The sets of `low`, in order of the materials' first use. A low mesh
// without named materials, or two sets whose path names are the same
// ("Metal/1" and "Metal_1"), is bad_input naming `low_path`.
Status find_low_sets(const Mesh& low, const std::string& low_path, std::vector<LowSet>& sets);

}  // namespace nmbake
