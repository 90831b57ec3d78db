// Deterministic scene generators: the demo moon and the analytic scenes whose
// true normal is known at every point (used by tests, the demo and the lab).
//
// Every generator is a pure function of its parameters: the same parameters
// give the same meshes, bit for bit, on every machine and thread count (own
// integer hash noise, no std:: random distributions).
#pragma once

#include <cstdint>
#include <functional>
#include <glm/ext/vector_double3.hpp>
#include <glm/vec3.hpp>
#include <memory>

#include "nmbake/mesh.hpp"

namespace nmbake::scenes {

struct ScenePair {
  Mesh low;   // with UVs and normals
  Mesh high;  // positions, normals, no UVs
};

// --- Heightfield over a plane -------------------------------------------
// Surface z = h(x, y) over [0, size]^2. The low mesh is a flat grid of
// low_cells x low_cells quads at z = 0 with u = x / size, v = y / size and
// normal +z (so its MikkTSpace frame is T = +x, B = +y, N = +z). The high
// mesh is a high_cells x high_cells grid of the heightfield with analytic
// vertex normals.
struct HeightfieldParams {
  float size = 1.0f;
  int low_cells = 4;
  int high_cells = 512;
  float amplitude = 0.02f;  // of the bumps, in scene units
};
float heightfield_height(const HeightfieldParams& p, float x, float y);
glm::vec3 heightfield_normal(const HeightfieldParams& p, float x, float y);  // unit, analytic
ScenePair make_heightfield(const HeightfieldParams& p);

// --- Displaced sphere ----------------------------------------------------
// Radius r(d) = radius * (1 + amplitude * f(d)) for unit directions d, f a
// smooth fixed function (a sum of a few smooth lobes). Meshes are cube
// spheres: each cube face (s, t) in [-1, 1]^2 is mapped to d = normalize(s, t, 1)
// (rotated to the face). The low mesh is the undisplaced sphere of radius
// `radius` with low_cells x low_cells quads per face, one UV chart per face in
// a 3 x 2 atlas with a gutter; the high mesh has high_cells per face, is
// displaced, and carries analytic normals.
struct SphereParams {
  float radius = 1.0f;
  int low_cells = 8;
  int high_cells = 256;
  float amplitude = 0.03f;
};
float sphere_radius(const SphereParams& p, const glm::vec3& unit_direction);
// Unit outward normal of the displaced surface at direction d:
// normalize(d - grad_s r / r), grad_s the gradient tangent to the unit sphere.
glm::vec3 sphere_normal(const SphereParams& p, const glm::vec3& unit_direction);
ScenePair make_displaced_sphere(const SphereParams& p);

// Cube sphere with a given radius function (used by the sphere and the moon).
// UVs: face f occupies cell (f % 3, f / 3) of a 3 x 2 grid, inset by
// `uv_gutter` (in UV units) on every side. `with_uvs` false: no UVs.
//
// Faces in order +X, -X, +Y, -Y, +Z, -Z; on each, u grows with s and v with t
// and cross(dP/ds, dP/dt) points outward, so charts are not mirrored and the
// winding is counter-clockwise seen from outside. Cube points come from an
// integer lattice shared by all faces, so seam vertices of neighbouring faces
// have bitwise-identical positions. With UVs every face has its own vertices
// (split along the seams); without UVs the seam vertices are shared, giving a
// closed manifold (what area-weighted normals need). Normals are the unit
// directions d (exact for a constant radius). `radius_of_direction` is called
// in parallel and must be pure; its result only depends on d, so the mesh is
// the same whatever the thread count. Requires 1 <= cells_per_face <= 8192 and
// 0 <= uv_gutter < 1/6.
Mesh make_cube_sphere(int cells_per_face, const std::function<float(const glm::vec3&)>& radius_of_direction,
                      bool with_uvs, float uv_gutter);

// The moon's radius always stays within radius * (1 +- moon_relief_limit):
// crater and terrain heights are summed and then softly limited (tanh).
inline constexpr float moon_relief_limit = 0.02f;
// UV gutter of the low meshes of the sphere and the moon (UV units per side).
inline constexpr float sphere_uv_gutter = 0.01f;

// --- The demo moon -------------------------------------------------------
// "Making Worlds"-style moon: crater brushes (bowl, raised rim, ejecta)
// stamped at fixed pseudo-random places, the brush's radial coordinate
// distorted with fractal noise so no two craters are alike, on top of a low
// fractal terrain. High: cube sphere with high_cells per face (408 gives
// ~2.0M triangles), area-weighted normals computed from the mesh. Low: the
// plain sphere with low_cells per face, one UV chart per face. Both high
// meshes (sphere and moon) share their seam vertices (closed, welded); the low
// meshes are split per face (UV charts) with bitwise-equal seam positions.
struct MoonParams {
  float radius = 1.0f;
  int low_cells = 16;
  int high_cells = 408;
  int crater_count = 300;
  std::uint32_t seed = 1;
};
ScenePair make_moon(const MoonParams& p);

// --- Many parts ----------------------------------------------------------
// `count` heightfield plates (make_heightfield, size 1) side by side in a
// square grid with gaps of `gap`, each its own named part: p<i>_low in the
// low mesh, p<i>_high in the high mesh (bake groups, parts.hpp). Part i's
// UVs fill cell i of a square grid of the map with a margin of 4% of a cell.
// About `high_triangles` high triangles in all.
struct PartsParams {
  int count = 8;
  std::uint64_t high_triangles = 2'000'000;
  int low_cells = 4;
  float gap = 0.05f;
};
ScenePair make_parts(const PartsParams& p);

// The moon's radius function (what make_moon samples at the high vertices),
// for tests and tools that need the surface between vertices. Building it
// places the craters; radius() is pure and thread-safe.
class MoonSurface {
 public:
  explicit MoonSurface(const MoonParams& p);
  ~MoonSurface();
  MoonSurface(const MoonSurface&) = delete;
  MoonSurface& operator=(const MoonSurface&) = delete;
  float radius(const glm::vec3& direction) const;  // any non-zero direction
  // Relative height (radius / p.radius - 1) before rounding to float, in
  // [-moon_relief_limit, moon_relief_limit].
  double relative_height(const glm::dvec3& unit_direction) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace nmbake::scenes
