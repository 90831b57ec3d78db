// Flattening of the low mesh into per-corner arrays, plus the cage.
#include "nmbake/surface.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numeric>
#include <string>
#include <tuple>

namespace nmbake {

namespace {
std::vector<std::uint32_t> position_identity(const Mesh& mesh);

// Hard corners and hard edges (surface.hpp) from the corners' normals.
void find_hard_edges(const Mesh& low, LowSurface& s) {
  const std::size_t corner_count = s.position.size();
  const std::vector<std::uint32_t> id = position_identity(low);
  const float cos_limit = std::cos(kHardEdgeDegrees * 3.14159265358979f / 180.0f);
  const auto differ = [&](std::uint32_t a, std::uint32_t b) {
    return glm::dot(s.normal[a], s.normal[b]) < cos_limit;
  };
  // Corners grouped by position, in corner order.
  std::vector<std::uint32_t> order(corner_count);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::uint32_t a, std::uint32_t b) { return id[a] < id[b]; });
  std::vector<std::uint8_t> hard(corner_count, 0);
  for (std::size_t i = 0; i < corner_count;) {
    std::size_t j = i;
    while (j < corner_count && id[order[j]] == id[order[i]]) ++j;
    for (std::size_t a = i; a < j; ++a) {
      for (std::size_t b = i; b < j && !hard[order[a]]; ++b)
        hard[order[a]] = differ(order[a], order[b]) ? 1 : 0;
    }
    i = j;
  }
  // None: left empty, so the banded cage costs nothing on a smooth mesh.
  if (std::find(hard.begin(), hard.end(), 1) == hard.end()) return;
  s.hard_corners.assign(s.triangle_count(), 0);
  for (std::size_t c = 0; c < corner_count; ++c)
    s.hard_corners[c / 3] |= static_cast<std::uint8_t>(hard[c] << (c % 3));
  // Edges between two hard corners, keyed by their positions: hard where the
  // triangles on the two sides disagree at either end.
  struct Side {
    std::uint32_t lo, hi;  // position identities, lo < hi
    std::uint32_t corner_lo, corner_hi;
  };
  std::vector<Side> sides;
  for (std::size_t c = 0; c < corner_count; ++c) {
    const std::uint32_t d = static_cast<std::uint32_t>(c - c % 3 + (c + 1) % 3);
    if (!hard[c] || !hard[d] || id[c] == id[d]) continue;
    const bool forward = id[c] < id[d];
    sides.push_back({forward ? id[c] : id[d], forward ? id[d] : id[c],
                     forward ? static_cast<std::uint32_t>(c) : d,
                     forward ? d : static_cast<std::uint32_t>(c)});
  }
  std::stable_sort(sides.begin(), sides.end(),
                   [](const Side& a, const Side& b) { return a.lo != b.lo ? a.lo < b.lo : a.hi < b.hi; });
  for (std::size_t i = 0; i < sides.size();) {
    std::size_t j = i;
    while (j < sides.size() && sides[j].lo == sides[i].lo && sides[j].hi == sides[i].hi) ++j;
    bool is_hard = false;
    for (std::size_t a = i; a < j && !is_hard; ++a) {
      for (std::size_t b = a + 1; b < j && !is_hard; ++b) {
        is_hard =
            differ(sides[a].corner_lo, sides[b].corner_lo) || differ(sides[a].corner_hi, sides[b].corner_hi);
      }
    }
    if (is_hard) {
      s.hard_edge_a.push_back(s.position[sides[i].corner_lo]);
      s.hard_edge_b.push_back(s.position[sides[i].corner_hi]);
    }
    i = j;
  }
}
}  // namespace

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
  find_hard_edges(low, s);
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
  std::stable_sort(order.begin(), order.end(),
                   [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b); });
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
