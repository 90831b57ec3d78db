// Flattening of the low mesh into per-corner arrays, plus the cage.
#include "nmbake/surface.hpp"

#include <algorithm>
#include <numeric>
#include <string>
#include <tuple>

#include <glm/geometric.hpp>

namespace nmbake {

LowSurface build_low_surface(const Mesh& low, const Mesh* cage, SurfaceStats& stats) {
  return build_low_surface(low, cage, TangentBasis::mikktspace, stats);
}

LowSurface build_low_surface(const Mesh& low, const Mesh* cage, TangentBasis basis, SurfaceStats& stats) {
  NMBAKE_CHECK(low.has_uvs() && low.has_normals(), "low mesh needs UVs and normals");
  const std::size_t corner_count = low.indices.size();
  LowSurface s;
  s.position.resize(corner_count);
  s.normal.resize(corner_count);
  s.uv.resize(corner_count);
  s.cage_normal.resize(corner_count);

  const std::vector<glm::vec3> averaged = averaged_normals(low, stats.mesh);
  for (std::size_t c = 0; c < corner_count; ++c) {
    const std::uint32_t v = low.indices[c];
    s.position[c] = low.positions[v];
    s.normal[c] = low.normals[v];
    s.uv[c] = low.uvs[v];
    s.cage_normal[c] = averaged[v];
  }
  compute_tangents(low, basis, s.tangent, stats.tangents);
  NMBAKE_CHECK(s.tangent.size() == corner_count, "one tangent per corner");
  fill_corner_bitangents(s);

  if (cage != nullptr) {
    NMBAKE_CHECK(cage->indices.size() == corner_count, "cage topology checked before");
    s.cage_position.resize(corner_count);
    for (std::size_t c = 0; c < corner_count; ++c) s.cage_position[c] = cage->positions[cage->indices[c]];
  }
  return s;
}

void fill_corner_bitangents(LowSurface& s) {
  NMBAKE_CHECK(s.tangent.size() == s.normal.size(), "one tangent per corner normal");
  s.bitangent.resize(s.tangent.size());
  for (std::size_t c = 0; c < s.tangent.size(); ++c) {
    // What a vertex shader computes from the vertex's attributes: the sign
    // is +-1 (MikkTSpace), a zero w counts as +1 as in the encode.
    const float sign = s.tangent[c].w < 0.0f ? -1.0f : 1.0f;
    s.bitangent[c] = sign * glm::cross(s.normal[c], glm::vec3(s.tangent[c]));
  }
}

namespace {

// For each corner, the index of the first corner with the same position
// (bitwise): the "vertex identity" of the corner, independent of how the
// file split vertices for UVs or normals.
std::vector<std::uint32_t> position_identity(const Mesh& mesh) {
  const std::size_t n = mesh.indices.size();
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  auto key = [&](std::uint32_t c) {
    const glm::vec3& p = mesh.positions[mesh.indices[c]];
    return std::tuple(p.x, p.y, p.z);
  };
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b); });
  std::vector<std::uint32_t> identity(n);
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i;
    std::uint32_t first = order[i];
    while (j < n && key(order[j]) == key(order[i])) {
      first = std::min(first, order[j]);
      ++j;
    }
    for (std::size_t k = i; k < j; ++k) identity[order[k]] = first;
    i = j;
  }
  return identity;
}

}  // namespace

Status check_cage_topology(const Mesh& low, const Mesh& cage, const std::string& cage_name) {
  if (cage.triangle_count() != low.triangle_count()) {
    return Status::bad_input(cage_name + ": the cage has " + std::to_string(cage.triangle_count()) +
                             " triangles, the low mesh " + std::to_string(low.triangle_count()) +
                             ": a cage must have the low mesh's topology");
  }
  const std::vector<std::uint32_t> low_id = position_identity(low);
  const std::vector<std::uint32_t> cage_id = position_identity(cage);
  // Corners that share a cage position must share a low position. The cage
  // may split what the low mesh shares (a cage with hard edges), but two
  // different low points that become one cage point mean another topology.
  for (std::size_t c = 0; c < low_id.size(); ++c) {
    if (low_id[cage_id[c]] != low_id[c]) {
      return Status::bad_input(cage_name + ": triangle " + std::to_string(c / 3) + " corner " +
                               std::to_string(c % 3) +
                               " does not connect like the low mesh's: a cage must have the low mesh's "
                               "topology (same triangles in the same order)");
    }
  }
  return Status::ok();
}

}  // namespace nmbake
