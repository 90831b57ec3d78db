// The mesh data model: one plain, indexed struct-of-arrays triangle mesh for
// both the high and the low mesh (DESIGN.md, "Two meshes, two data models").
//
// * A vertex is a unique combination of the attributes that were loaded: for
//   the high mesh that is position (+ normal), never UV, so the high mesh is
//   never split along UV seams; for the low mesh position + normal + UV.
// * `positions` of a high mesh are handed to Embree as a shared buffer;
//   Embree reads 16 bytes for the last float3, so `pad_for_embree()` keeps one
//   spare element of capacity behind the data.
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/material.hpp"

namespace nmbake {

// A named, contiguous range of triangles: a part of a mesh file (OBJ
// `o`/`g`, a glTF node's mesh, an FBX model) or a material range (OBJ
// `usemtl`, a glTF primitive's material, an FBX/Collada mesh's material).
// Bake groups are made of parts (parts.hpp); the id map colours parts or
// materials (maps.hpp); the rest of the pipeline never looks at them.
struct MeshPart {
  std::string name;  // as in the file; may be empty
  std::uint32_t first_triangle = 0;
  std::uint32_t triangle_count = 0;
  friend bool operator==(const MeshPart&, const MeshPart&) = default;
};

struct Mesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;  // empty, or one unit normal per vertex
  std::vector<glm::vec2> uvs;      // empty, or one per vertex (v = 0 at the image bottom)
  // Empty, or one per vertex as the file stored them (glTF TANGENT, FBX
  // tangents): xyz and the bitangent sign in w. Only for --tangents file.
  std::vector<glm::vec4> tangents;
  // Empty, or one RGBA colour per vertex in [0, 1] (PLY red/green/blue/alpha,
  // read when LoadOptions::keep_colors): the vertex-color map (maps.hpp).
  std::vector<glm::vec4> colors;
  std::vector<std::uint32_t> indices;  // three per triangle, counter-clockwise = front
  // Empty (one unnamed part: the whole mesh), or ranges in triangle order
  // that cover every triangle exactly once, without empty parts. A name may
  // appear in several ranges (an OBJ that returns to `g body` later).
  std::vector<MeshPart> parts;
  // The material of every triangle, by the same rules as `parts`: empty (no
  // material: every triangle has the unnamed material ""), or ranges in
  // triangle order covering every triangle exactly once, none empty, a name
  // in as many ranges as the file has runs of it. "" names triangles without
  // a material (before an OBJ's first `usemtl`, a glTF primitive without
  // one). Whatever reorders or drops triangles must update both or clear
  // them (bake groups clear both on the high mesh after the id map took its
  // per-triangle colours).
  std::vector<MeshPart> materials;
  // The texture coordinates of every triangle corner (three per triangle,
  // v = 0 at the image bottom), without splitting vertices: the high mesh of
  // a texture bake (LoadOptions::corner_uvs). Empty otherwise. A corner the
  // file gave no UV has (0, 0) (counted in LoadStats::corners_without_uvs).
  std::vector<glm::vec2> corner_uvs;
  // What the file says of its materials (LoadOptions::material_defs): at
  // most one per name in `materials`, in order of first use; a range whose
  // name has none here has no definition (factors as Material{}).
  std::vector<Material> material_defs;
  // Images stored in the file that a TextureRef of `material_defs` points at
  // (TextureRef::embedded indexes here; material.hpp). Empty otherwise.
  std::vector<EmbeddedImage> embedded_images;

  std::size_t vertex_count() const { return positions.size(); }
  std::size_t triangle_count() const { return indices.size() / 3; }
  bool has_normals() const { return !normals.empty(); }
  bool has_uvs() const { return !uvs.empty(); }
  bool has_tangents() const { return !tangents.empty(); }
  bool has_colors() const { return !colors.empty(); }
  bool has_corner_uvs() const { return !corner_uvs.empty(); }
  // The definition of material `name`, or null.
  const Material* material_def(const std::string& name) const;
  // Some triangle has a material with a name (the id map's auto source).
  bool has_named_materials() const;
};

// Counts of the numerical fallbacks taken while preparing a mesh.
struct MeshStats {
  std::uint64_t zero_area_triangles = 0;  // position area ~ 0: contribute no normal weight
  std::uint64_t zero_length_normals = 0;  // file normal or accumulated normal of length ~0
  std::uint64_t normals_computed = 0;     // vertices whose normal was computed, not loaded
};

// Rejects a mesh no later stage can use: NaN/Inf in any attribute, an index
// out of range, attribute arrays of the wrong size, no triangles, parts or
// materials that do not tile the triangles. `name` is used in the message (the file path).
Status validate_mesh(const Mesh& mesh, const std::string& name);

// The largest |coordinate| a baked or unwrapped mesh may hold (README,
// "Limits"). Below it any two points are at most 3.5e9 apart, and an edge
// length to the fourth power (a squared cross product, as tangents, normals
// and areas compute in float) stays below FLT_MAX, so every derived length,
// area and ray stays finite; Embree aborts on a ray that is not (Debian
// builds it with assertions on). load_mesh() reads any finite float; bake()
// and unwrap check this on top.
constexpr float kMaxCoordinate = 1e9f;
// bad_input naming `name`, the first vertex beyond kMaxCoordinate and the limit.
Status check_coordinate_range(const Mesh& mesh, const std::string& name);

// Area-weighted vertex normals (the cross product of two edges, unnormalised,
// summed over the triangles around the vertex). A vertex whose sum has zero
// length (only degenerate triangles around it) gets (0, 0, 1) and is counted.
// A triangle is degenerate (no weight, counted in zero_area_triangles) when
// |cross| <= 1e-7 * (longest edge)^2: its direction is float noise.
// Replaces mesh.normals; normals_computed += vertex count.
void compute_vertex_normals(Mesh& mesh, MeshStats& stats);

// Normalises loaded normals; zero-length ones are replaced by the computed
// area-weighted normal of the vertex (or (0, 0, 1)) and counted (both in
// zero_length_normals; normals_computed when a computed one was used).
// A mesh without normals gets compute_vertex_normals().
void normalize_normals(Mesh& mesh, MeshStats& stats);

// Normals averaged over all vertices that share a position (bitwise equal
// coordinates), weighted by corner angle (not by area, which would follow the
// triangulation): the direction the default cage is pushed along,
// so that hard edges (split normals) do not open gaps in the cage.
// -0 and +0 count as equal. Where the sum at a position cancels (e.g. the
// two sides of a sheet) each vertex keeps its own normalised normal (the
// mesh's, else its own angle-weighted one, else (0, 0, 1)), counted in
// zero_length_normals.
std::vector<glm::vec3> averaged_normals(const Mesh& mesh, MeshStats& stats);

// Prepares a loaded low mesh's normals the one way every tool must (bake,
// preview, height2normal, evaluators): file normals are normalised, missing
// ones are averaged over coincident positions (averaged_normals), because a
// low mesh's vertices are split at UV seams and a seam must not become a
// shading crease. Missing normals are counted in normals_computed.
void prepare_low_normals(Mesh& low, MeshStats& stats);

// Makes sure Embree may read 4 bytes past the last position (see above).
void pad_for_embree(Mesh& mesh);

// Axis-aligned bounds of the positions.
struct Bounds {
  glm::vec3 min{0.0f};
  glm::vec3 max{0.0f};
  float diagonal() const;
};
Bounds compute_bounds(const Mesh& mesh);

}  // namespace nmbake
