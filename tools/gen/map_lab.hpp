// The map set's analytic scenes and their closed-form answers (maps.hpp):
// what a height, AO, curvature or thickness map of each must hold, so tests
// and the map lab (nmbake-gen maplab) score a bake texel by texel.
//
//   wall    a floor z = 0 (the low mesh: x in [0, 1], y in [0, 1]) at the
//           foot of a wall x = 0 that is, within the AO distance D = 1,
//           infinitely tall and long (height and half-length 1.25 D).
//           Cosine-weighted visibility at distance x from the wall:
//           V = 1 - (acos(a) - a sqrt(1 - a^2)) / pi, a = min(1, x / D)
//           (Malley: cosine-weighted directions are uniform on the unit
//           disk below them; the wall takes the disk's segment d_x > a).
//   bowl    the inside of a hemispherical bowl of radius 1 (low and high:
//           cube-sphere-like grids of the lower hemisphere, normals towards
//           the centre). With D >= 2 every point of the bowl sees exactly
//           half: the form factor from a point of a sphere's inner surface
//           to any part of it is that part's area over the sphere's, and the
//           missing upper half is what the point sees of the sky: V = 0.5.
//   groove  the floor of a long groove of width 1 and depth 1 (walls x = 0
//           and x = 1 up to z = 1, floor z = 0), 60 long; D = 10. In the
//           cross-section (an infinitely long groove: Nusselt, the 2D form
//           factor of the opening) V(x) = ((1 - x) / sqrt((1 - x)^2 + 1) +
//           x / sqrt(x^2 + 1)) / 2; the finite D and length change it by
//           less than 1e-4 (rays that would meet a wall further than D away
//           run within x/D of the groove's axis and 1/D of the horizon).
//   slab    a closed box [0, 1]^2 x [-T, 0], T = 0.1; the low mesh is its
//           top face. Thickness (projected depth) = T exactly, away from
//           the side walls (T tan 15 deg = 0.027).
//   sphere  the plain cube sphere of radius 1 (make_displaced_sphere with
//           amplitude 0, analytic normals): mean curvature 1, thickness
//           2 (1 + c + c^2) / 3 with c = cos 15 deg.
//   torus   the plain torus, major 1, minor 0.35 (make_torus, amplitude 0):
//           mean curvature (1 / a + cos(theta) / (R + a cos(theta))) / 2 at
//           tube angle theta.
// Heights: the heightfield and the displaced sphere of scenes.hpp, whose
// surface is known; the expected height of a sample is the signed distance
// along the bake's own ray from the low surface to the analytic surface.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "nmbake/bake.hpp"
#include "scenes.hpp"

namespace nmbake::scenes {

inline constexpr float kWallDistance = 1.0f;  // the AO distance the wall's answer assumes
inline constexpr float kBowlDistance = 2.5f;  // >= the bowl's diameter
inline constexpr float kGrooveDistance = 10.0f;
inline constexpr float kSlabThickness = 0.1f;

ScenePair make_wall_scene();
ScenePair make_bowl_scene(int low_cells = 8, int high_cells = 96);
ScenePair make_groove_scene();
ScenePair make_slab_scene();

double wall_visibility(double x, double distance);  // x: distance from the wall
double groove_visibility(double x);                 // x in [0, 1] across the floor
// The groove's bent normal (the mean unoccluded direction, cosine-weighted)
// at x: in the cross-section the visible directions are the angles from the
// normal phi in [phi1, phi2] = [-atan(x), atan(1 - x)], every elevation
// beta along the groove; with d = (cos b sin p, sin b, cos b cos p) and the
// weight cos^2 b cos p db dp the mean is proportional to
// ((sin^2 phi2 - sin^2 phi1) / 2, 0, (phi2 - phi1) / 2 + (sin 2 phi2 - sin 2 phi1) / 4).
glm::dvec3 groove_bent_normal(double x);
double sphere_thickness(double radius);  // the cone's mean projected depth
double torus_mean_curvature(double major, double minor, const glm::dvec3& point);

// A texel-by-texel answer for a baked one-channel map (or one channel of a
// three-channel map): the expected value per texel (NaN: not scored).
struct ExpectedMap {
  int width = 0, height = 0;
  std::vector<double> value;
};

// The value per texel of a function of the sample's low surface point,
// averaged over the bake's samples of the texel (raster.hpp's pattern) as the
// baker averages: `of_point(low point)`.
ExpectedMap expected_from_low_points(const Mesh& low, int width, int height, int samples,
                                     const std::function<double(const glm::dvec3&)>& of_point);

// The height along the bake's rays to an analytic surface (eval.hpp's
// TrueSurface, by scene name: "heightfield", "sphere"; "sphere-plain": the
// unit sphere), averaged per texel.
ExpectedMap expected_height(const std::string& scene, const Mesh& low, int width, int height, int samples,
                            const RayOptions& rays);

// f(hit point) where the bake's ray meets the analytic surface ("heightfield",
// "sphere" of eval.hpp; "sphere-plain", "torus-plain"), averaged per texel.
ExpectedMap expected_at_true_hits(const std::string& scene, const Mesh& low, int width, int height,
                                  int samples, const RayOptions& rays,
                                  const std::function<double(const glm::dvec3&)>& f);

// The mean curvature where the bake's rays meet the plain "sphere" (1) or
// "torus" (torus_mean_curvature), averaged per texel.
ExpectedMap expected_curvature(const std::string& scene, const Mesh& low, int width, int height, int samples,
                               const RayOptions& rays);

struct MapError {
  std::size_t texels = 0;  // scored
  double mean_abs = 0.0, mean_signed = 0.0, p99 = 0.0, max = 0.0;
  std::size_t non_finite = 0;
  std::string to_text() const;
};
// |map channel - expected| over the texels with an expected value; `map`
// may have any channel count.
MapError score_map(const Image& map, int channel, const ExpectedMap& expected);

}  // namespace nmbake::scenes
