// The accuracy lab's analytic scenes (besides the heightfield and the
// displaced sphere of scenes.hpp): each knows its true surface as a signed
// field (> 0 outside, < 0 inside, |gradient| about 1 near the surface) and its
// true unit normal at any surface point, so a bake can be scored texel by
// texel (eval.hpp). Every generator is a pure function of its parameters.
//
//   torus    a torus whose tube radius carries smooth periodic bumps;
//   craters  the cube-sphere moon with craters as C1-smooth radial profiles
//            (analytic gradient, no noise: the demo moon's crater brushes are
//            only C0 at the rim);
//   box      a hard-edged cube (split normals) over a bevelled high cube
//            (a rounded box: the points at distance `bevel` from a core box);
//   slot     a U-shaped groove (two walls and a floor, inner faces only, hard
//            concave edges) with compact bump functions on each face: a ray
//            longer than the groove is wide crosses the opposite wall.
#pragma once

#include <cstdint>
#include <glm/ext/vector_double3.hpp>
#include <memory>
#include <string>

#include "scenes.hpp"

namespace nmbake::scenes {

// --- Torus ---------------------------------------------------------------
// Centre circle of radius `major` in the z = 0 plane; a point at angles
// (phi around z, theta around the tube) is C(phi) + rho(phi, theta) e_r with
// rho = minor * (1 + amplitude * f(phi, theta)), f smooth and periodic. The
// low mesh is the plain torus (rho = minor) with 3 * low_cells x low_cells
// quads, u = phi / 2 pi, v = theta / 2 pi (one chart, seams at u, v = 0 | 1);
// the high mesh is welded, 3 * high_cells x high_cells quads, analytic normals.
struct TorusParams {
  float major = 1.0f;
  float minor = 0.35f;
  float amplitude = 0.08f;  // relative to minor
  int low_cells = 12;
  int high_cells = 192;
};
double torus_field(const TorusParams& p, const glm::dvec3& point);
glm::dvec3 torus_normal(const TorusParams& p, const glm::dvec3& point);
ScenePair make_torus(const TorusParams& p);

// --- Smooth-crater moon ----------------------------------------------------
// Radius R(d) = radius * (1 + H(d)), H = sum of craters c_k(d) =
// P(angle(d, centre_k) / size_k): bowl -depth + (depth + rim) s(x) for
// x < 1, ejecta rim (1 - s(t)), t = (x - 1) / (reach - 1), up to x = reach,
// s the smoothstep 3x^2 - 2x^3: C1 everywhere. Normal = normalize(d -
// grad_s H / (1 + H)). Meshes as the displaced sphere (cube spheres).
struct CraterParams {
  float radius = 1.0f;
  int crater_count = 40;
  std::uint32_t seed = 7;
  int low_cells = 8;
  int high_cells = 192;
};
class CraterSurface {
 public:
  explicit CraterSurface(const CraterParams& p);
  ~CraterSurface();
  CraterSurface(const CraterSurface&) = delete;
  CraterSurface& operator=(const CraterSurface&) = delete;
  // H(d) and, when `tangential_gradient` is not null, grad_s H (tangent to
  // the unit sphere at d). d must be a unit vector.
  double relative_height(const glm::dvec3& d, glm::dvec3* tangential_gradient) const;
  double field(const glm::dvec3& point) const;   // |p| - R(p / |p|)
  glm::dvec3 normal(const glm::dvec3& d) const;  // at direction d
  const CraterParams& params() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};
ScenePair make_craters(const CraterParams& p);

// --- Bevelled box ------------------------------------------------------------
// Low: the cube [-half_extent, half_extent]^3 with low_cells x low_cells
// quads per face, split (face) normals, one UV chart per face (3 x 2 atlas).
// High: the rounded box with the same extent and edge radius `bevel`, a
// welded cube sphere of high_cells per face projected onto it, analytic
// normals.
struct BoxParams {
  float half_extent = 1.0f;
  float bevel = 0.2f;
  int low_cells = 4;
  int high_cells = 160;
};
double box_field(const BoxParams& p, const glm::dvec3& point);  // exact signed distance
glm::dvec3 box_normal(const BoxParams& p, const glm::dvec3& point);
ScenePair make_box(const BoxParams& p);

// --- Slot (concave) ----------------------------------------------------------
// Three patches: left wall x = -width/2 + h_0(y, z) (normal about +x), floor
// y = h_1(x, z) (normal about +y), right wall x = width/2 - h_2(y, z) (normal
// about -x); y in [0, depth], x in [-width/2, width/2], z in [0, length].
// Each h is a sum of compact bump functions exp(1 - 1 / (1 - s^2)) that
// vanish at the patch borders, so the high patches meet on the low edges.
// Low and high are open meshes: the three inner faces only, each its own UV
// chart (charts side by side, uniform texel density).
struct SlotParams {
  float width = 0.4f;
  float depth = 0.6f;
  float length = 1.0f;
  float amplitude = 0.03f;
  int low_cells = 4;
  int high_cells = 128;  // across the widest patch side
};
inline constexpr int slot_patch_count = 3;
double slot_field(const SlotParams& p, int patch, const glm::dvec3& point);
glm::dvec3 slot_normal(const SlotParams& p, int patch, const glm::dvec3& point);
bool slot_in_patch(const SlotParams& p, int patch, const glm::dvec3& point);
ScenePair make_slot(const SlotParams& p);

// --- Cage --------------------------------------------------------------------
// The low mesh pushed out along its averaged normals (averaged_normals()) by
// `offset`: an explicit cage with the low mesh's topology (same vertices,
// UVs and triangles; normals dropped).
Mesh make_offset_cage(const Mesh& low, float offset);

// The ray distances the lab uses for a scene (front also = cage offset):
// enough for the relief, and for "slot" deliberately longer than the groove
// is wide. Unknown names give 0, 0.
struct LabDistances {
  float front = 0.0f, back = 0.0f;
};
LabDistances lab_distances(const std::string& scene);

}  // namespace nmbake::scenes
