// UDIM tiles: one map per unit square of UV space, as Mari, Blender and
// Arnold number them: tile 1001 + u + 10 v holds UVs in [u, u + 1) x
// [v, v + 1), u = 0..9, v = 0..99. An output path with the token <UDIM>
// (`body_normal.<UDIM>.png`) bakes one map per tile the low mesh uses, each
// from that tile's UVs shifted into [0, 1]^2; a path without it bakes tile
// 1001 only, and a low mesh with UVs in any other tile is an error.
//
// A triangle belongs to the tile of its UV centroid. The shift by whole
// numbers is exact in floating point for UVs inside their tile, so a tile's
// map is byte for byte the map of the same mesh with its UVs moved into
// [0, 1]^2 by hand.
#pragma once

#include <glm/vec2.hpp>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/mesh.hpp"

namespace nmbake {

inline constexpr const char* kUdimToken = "<UDIM>";

bool has_udim_token(const std::string& path);
// `path` with every <UDIM> replaced by the tile number.
std::string udim_path(const std::string& path, int tile);
// UV offset of a tile: (u, v) of its lower left corner.
glm::vec2 udim_offset(int tile);

// The tiles the triangles of `low` (with UVs) use, ascending. `udim` says
// whether the outputs carry the token: without it every triangle must be in
// tile 1001 (bad_input naming the file, the tiles found and the token to use);
// with it a triangle outside every tile (u < 0, u >= 10 or v < 0) is an error.
Status find_udim_tiles(const Mesh& low, const std::string& low_path, bool udim, std::vector<int>& tiles);

}  // namespace nmbake
