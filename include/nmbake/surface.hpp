// The low mesh flattened for raster, trace and encode: per-corner arrays,
// three entries per triangle in triangle order (DESIGN.md: "flattened to
// per-corner arrays (position, normal, uv, tangent)").
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <vector>

#include "nmbake/mesh.hpp"
#include "nmbake/tangents.hpp"

namespace nmbake {

struct LowSurface {
  std::vector<glm::vec3> position;
  std::vector<glm::vec3> normal;  // unit shading normal
  std::vector<glm::vec2> uv;
  std::vector<glm::vec4> tangent;  // MikkTSpace: xyz, sign in w
  // sign cross(normal, tangent.xyz) per corner: the bitangent a renderer
  // that computes B per vertex interpolates (NormalDecode, encode.hpp).
  std::vector<glm::vec3> bitangent;
  std::vector<glm::vec3> cage_normal;    // unit averaged normal: where the default cage is pushed
  std::vector<glm::vec3> cage_position;  // explicit cage mesh corners; empty without --cage
  std::vector<std::uint32_t> group;      // bake group per triangle (parts.hpp); empty: one group
  // Hard edges: low edges whose two triangles' normals differ at an end (split
  // normals, more than kHardEdgeDegrees apart), as segments; per triangle, bit
  // k set when corner k's position carries more than one normal (empty when
  // no position does).
  std::vector<glm::vec3> hard_edge_a, hard_edge_b;
  std::vector<std::uint8_t> hard_corners;
  // The banded cage's search structure (trace.hpp, prepare_edge_band): per
  // triangle, the hard edges within band_reach of it, band_edges[band_first[t]
  // .. band_first[t + 1]). band_reach < 0: not prepared.
  std::vector<std::uint32_t> band_first, band_edges;
  float band_reach = -1.0f;

  std::size_t triangle_count() const { return position.size() / 3; }
  bool has_cage_mesh() const { return !cage_position.empty(); }
};

// Normals of one position further apart than this make a hard edge.
constexpr float kHardEdgeDegrees = 1.0f;

struct SurfaceStats {
  MeshStats mesh;
  TangentStats tangents;
};

// Builds the per-corner arrays from a low mesh with UVs and unit normals:
// tangents (MikkTSpace) and averaged cage normals. `cage`, when not null,
// must have the low mesh's triangle count; its positions are taken corner by
// corner (checked by check_cage_topology first).
LowSurface build_low_surface(const Mesh& low, const Mesh* cage, SurfaceStats& stats);
// The same with another tangent basis (tangents.hpp), for the accuracy lab.
LowSurface build_low_surface(const Mesh& low, const Mesh* cage, TangentBasis basis, SurfaceStats& stats);

// Fills surface.bitangent from its normals and tangents (build_low_surface
// does; for surfaces made by hand).
void fill_corner_bitangents(LowSurface& surface);

// A cage mesh must have the same triangles as the low mesh: same triangle
// count and, corner by corner, the same vertex identity pattern (two corners
// share a low vertex position exactly when they share a cage position).
Status check_cage_topology(const Mesh& low, const Mesh& cage, const std::string& cage_name);

}  // namespace nmbake
