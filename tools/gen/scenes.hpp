// Deterministic scene generators: the demo moon and the analytic scenes whose
// true normal is known at every point (used by tests, the demo and the lab).
//
// Every generator is a pure function of its parameters: the same parameters
// give the same meshes, bit for bit, on every machine and thread count (own
// integer hash noise, no std:: random distributions).
#pragma once

#include <cstdint>
#include <functional>

#include <glm/vec3.hpp>

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
Mesh make_cube_sphere(int cells_per_face, const std::function<float(const glm::vec3&)>& radius_of_direction,
                      bool with_uvs, float uv_gutter);

// --- The demo moon -------------------------------------------------------
// "Making Worlds"-style moon: crater brushes (bowl, raised rim, ejecta)
// stamped at fixed pseudo-random places, the brush's radial coordinate
// distorted with fractal noise so no two craters are alike, on top of a low
// fractal terrain. High: cube sphere with high_cells per face (408 gives
// ~2.0M triangles), area-weighted normals computed from the mesh. Low: the
// plain sphere with low_cells per face, one UV chart per face.
struct MoonParams {
  float radius = 1.0f;
  int low_cells = 16;
  int high_cells = 408;
  int crater_count = 300;
  std::uint32_t seed = 1;
};
ScenePair make_moon(const MoonParams& p);

}  // namespace nmbake::scenes
