// Stage "tangents": MikkTSpace per-corner tangent frames of the low mesh.
//
// Implements the algorithm of Morten S. Mikkelsen's reference implementation
// (mikktspace.c, "Simulation of wrinkled surfaces revisited", 2008) so that a
// renderer that decodes with MikkTSpace sees exactly the frame we baked in:
//   1. corners are welded by identical position, normal and UV;
//   2. per triangle: the UV-gradient directions (vOs, vOt) projected into the
//      plane of each corner normal, their magnitudes, the UV orientation
//      (sign of the UV area) and degeneracy flags;
//   3. per vertex, triangles of the same orientation that are connected
//      through shared edges form a group; the group tangent is the sum of the
//      per-triangle tangents projected onto the vertex normal, weighted by the
//      corner angle, normalised;
//   4. degenerate triangles (repeated vertex, zero UV area) take the frame of
//      a corner of an ordinary triangle at the same vertex, or a fixed
//      fallback.
// Output: one tangent per corner (three per triangle, in triangle order),
// xyz unit length and w = +1 or -1; the bitangent is w * cross(N, T).
#pragma once

#include <cstdint>
#include <glm/vec4.hpp>
#include <string>
#include <vector>

#include "nmbake/mesh.hpp"
#include "nmbake/words.hpp"

namespace nmbake {

struct TangentStats {
  std::uint64_t degenerate_triangles = 0;     // zero position area or repeated vertex
  std::uint64_t degenerate_uv_triangles = 0;  // zero UV area: no UV gradient
  std::uint64_t fallback_tangents = 0;        // corners that got a fixed, orthogonal-to-N tangent
};

// `mesh` must have unit normals and UVs (one per vertex). Writes
// 3 * triangle_count tangents and overwrites `stats`.
// A corner for which the reference finds no tangent (it would write
// (1, 0, 0) with sign -1, or a zero vector) gets instead the world axis least
// aligned with its normal (x, then y, then z on ties), made orthogonal to the
// normal, with sign +1; it is counted in fallback_tangents. Every other corner
// matches the reference (tests/tangents_test.cpp: < 0.01 degrees, same sign).
// degenerate_triangles also counts triangles with three distinct but
// collinear positions (the reference still groups those).
void compute_tangents(const Mesh& mesh, std::vector<glm::vec4>& corner_tangents, TangentStats& stats);

// MikkTSpace tangents of a mesh whose UVs are per corner (Mesh::corner_uvs:
// the high mesh, loaded without splitting its vertices at UV seams), for the
// high's normal textures (encode.hpp, HighNormalMaps). Only the triangles
// with `selected[t]` non-zero take part (all of them when `selected` is
// empty): the frame a renderer computes for the part of the mesh that wears
// a normal texture. Writes 3 * triangle_count tangents, (0, 0, 0, 0) for the
// other triangles' corners. Normals: the mesh's unit vertex normals, or each
// triangle's own when it has none (--high-normals face). The corners are
// compute_tangents()'s vertices (welded there by position, normal and UV).
void compute_corner_uv_tangents(const Mesh& mesh, const std::vector<std::uint8_t>& selected,
                                std::vector<glm::vec4>& corner_tangents, TangentStats& stats);

// Tangent bases other than MikkTSpace, for the accuracy lab (src/mesh/tangents_alt.cpp):
// what a baker that does not follow the renderer's basis stores. A renderer
// decodes with MikkTSpace, so a map baked in another basis is wrong by the
// angle between the two frames.
//   lengyel: per-vertex accumulation of the unnormalised face tangents and
//            bitangents (Lengyel, "Computing Tangent Space Basis Vectors for
//            an Arbitrary Mesh", 2001), Gram-Schmidt against the vertex
//            normal, sign from the accumulated bitangent;
//   face:    each triangle's own UV-gradient tangent at its three corners,
//            made orthogonal to the corner normal.
// Same output contract as compute_tangents: 3 per triangle, xyz unit and
// orthogonal to the corner normal, w = +-1; a corner without a usable
// tangent gets the same fallback axis and is counted in fallback_tangents.
//   file:    the tangents the mesh file carries (Mesh::tangents: glTF
//            TANGENT, FBX tangents; the "synced workflow", where the engine
//            imports tangents instead of computing them): per corner the
//            vertex's tangent, normalised and made orthogonal to the corner
//            normal, its sign from w (w < 0: -1, else +1). The mesh must
//            have tangents (the bake checks first: bad_input).
enum class TangentBasis : std::uint8_t { mikktspace, lengyel, face, file };
inline constexpr Word<TangentBasis> kTangentBasisWords[] = {
    {"mikktspace", TangentBasis::mikktspace, "what renderers decode"},
    {"lengyel", TangentBasis::lengyel, "Lengyel's per-vertex frame (comparison only)"},
    {"face", TangentBasis::face, "each triangle's own frame (comparison only)"},
    {"file", TangentBasis::file, "the low mesh's own tangents"},
};
NMBAKE_WORDS(TangentBasis, kTangentBasisWords)
void compute_tangents_lengyel(const Mesh& mesh, std::vector<glm::vec4>& corner_tangents, TangentStats& stats);
void compute_tangents_face(const Mesh& mesh, std::vector<glm::vec4>& corner_tangents, TangentStats& stats);
void compute_tangents_file(const Mesh& mesh, std::vector<glm::vec4>& corner_tangents, TangentStats& stats);
// Dispatches on `basis`.
void compute_tangents(const Mesh& mesh, TangentBasis basis, std::vector<glm::vec4>& corner_tangents,
                      TangentStats& stats);

// MikkTSpace gives a tangent per corner; glTF stores one per vertex. The
// mesh with Mesh::tangents per vertex: a vertex whose corners got different
// tangents (where MikkTSpace splits its groups) becomes one vertex per
// distinct tangent, so the per-vertex attribute is exact; positions,
// normals and UVs are copied. `low` needs normals and UVs; `corner_tangents`
// has 3 per triangle.
//
// `triangle_tile` (empty, or one UDIM tile per triangle, udim.hpp): vertices
// are also split per tile, each tile's UVs shifted into [0, 1]^2 (exact, as
// the bake shifts them), the triangles of each part ordered by tile (stable:
// within a tile they keep their order; the triangulation is unchanged) and
// Mesh::materials set to one range per (part, tile) named "tile_NNNN".
// Without it the triangles keep their order and their material ranges.
Mesh vertex_tangent_mesh(const Mesh& low, const std::vector<glm::vec4>& corner_tangents,
                         const std::vector<int>& triangle_tile = {});

}  // namespace nmbake
