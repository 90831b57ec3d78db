// Height maps to normal maps (`nmbake height2normal`).
//
// Flat maps: central differences in texel units,
//   dh/du = (h[x+1] - h[x-1]) / 2,   dh/dv = (h[y-1] - h[y+1]) / 2
// (v grows upward, image row y = 0 is the top row: the texel above is y - 1),
// N = normalize(-S dh/du, -S dh/dv, 1), stored as rgb = 0.5 N + 0.5 with the
// usual green convention (`down` negates y). Borders either wrap (tiling
// textures) or clamp: the map does not continue past its edge and edge texels
// use one-sided differences h[1] - h[0].
//
// Cube spheres ("Making Worlds 3: That's no Moon", Wittens 2009): a planet's
// height on the six faces of a cube, in one 3 x 2 atlas laid out exactly as
// the low meshes of nmbake-gen's cube spheres: face f (+X, -X, +Y, -Y, +Z, -Z)
// in cell (f % 3, f / 3), cell row 0 at the BOTTOM of the image (v in
// [0, 0.5]), each chart inset by `uv_gutter` UV units on every side; in a
// chart u grows with s and v with t, s, t in [-1, 1], and the cube point is
// s * U_f + t * V_f + N_f with the face frames of kCubeFaces. The surface is
// P(s, t) = k(s, t, r) = r (s, t, 1) / |(s, t, 1)| in face coordinates, with
// radius r = R (1 + S h). R only scales the planet and never changes a normal,
// so the normals are computed for R = 1: S is the relief in planet radii per
// unit of the stored value. The tangents dP/ds and dP/dt are the Jacobian of
// k applied to the flat tangents (1, 0, dr/ds) and (0, 1, dr/dt), not the
// Jacobian applied to the flat normal (J is not orthogonal); N = normalize(
// dP/ds x dP/dt). Every texel of a cell, gutter included, is the point (s, t)
// of its centre under the cell's UV map (|s| or |t| a little above 1 in the
// gutter, where k is still defined), so a generator should fill the gutter
// with the heights of those points; differences stay inside the cell and are
// one-sided on its border.
#pragma once

#include <array>
#include <cstdint>
#include <glm/vec3.hpp>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/dilate.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"

namespace nmbake {

enum class HeightBorder : std::uint8_t { clamp, wrap };
inline constexpr Word<HeightBorder> kHeightBorderWords[] = {
    {"clamp", HeightBorder::clamp, "the edge texel repeats"},
    {"wrap", HeightBorder::wrap, "the map tiles"},
};
NMBAKE_WORDS(HeightBorder, kHeightBorderWords)

struct HeightToNormalOptions {
  float strength = 1.0f;  // S: height units per texel -> slope
  HeightBorder border = HeightBorder::clamp;
  GreenChannel green = GreenChannel::up;
};

struct HeightToNormalStats {
  std::uint64_t one_sided_texels = 0;    // a difference was one-sided (clamped borders, cell borders)
  std::uint64_t flat_texels = 0;         // no neighbour at all along an axis (1 texel wide): slope 0 there
  std::uint64_t clamped_radii = 0;       // cube sphere: 1 + S h <= 1e-6 was raised to 1e-6
  std::uint64_t degenerate_normals = 0;  // cube sphere: dP/ds x dP/dt ~ 0, the radial direction used
  std::uint64_t singular_frames = 0;     // tangent output: world_to_tangent fell back to Gram-Schmidt
  std::uint64_t uncovered_texels = 0;    // tangent output: texels outside every chart, before dilation
  DilateStats dilate;                    // tangent output
};

// Reads the first channel of `height` (any channel count). Returns an RGB
// image of the same size. Non-finite heights are a checked invariant
// (read_image never returns one).
Image height_to_normal(const Image& height, const HeightToNormalOptions& options, HeightToNormalStats& stats);

// --- Cube sphere ---------------------------------------------------------

struct CubeFace {
  glm::vec3 u, v, n;  // cube point = s u + t v + n, cross(u, v) = n
};
// +X, -X, +Y, -Y, +Z, -Z: the frames of nmbake-gen's make_cube_sphere.
extern const std::array<CubeFace, 6> kCubeFaces;

// The default gutter: nmbake-gen's sphere_uv_gutter.
inline constexpr float kCubeAtlasGutter = 0.01f;

// Where texel (x, y) of a width x height atlas lies: its cell (face) and the
// face coordinates (s, t) of its centre.
struct CubeTexel {
  int face = 0;
  double s = 0.0, t = 0.0;
};
CubeTexel cube_atlas_texel(int x, int y, int width, int height, float uv_gutter);
// The same for any UV point: the cell containing (u, v) (clamped to the
// atlas) and its face coordinates.
CubeTexel cube_atlas_point(double u, double v, float uv_gutter);
// The unit direction of face point (s, t): normalize(s u + t v + n).
glm::vec3 cube_direction(int face, double s, double t);

struct CubeSphereOptions {
  float strength = 1.0f;  // S in r = R (1 + S h)
  float uv_gutter = kCubeAtlasGutter;
  NormalSpace space = NormalSpace::object;
  GreenChannel green = GreenChannel::up;  // tangent space only
  int padding = 16;                       // tangent space: dilation past the low mesh's charts
};

// `low` is needed for tangent space (nullptr otherwise): the low cube
// sphere whose UVs use this atlas; texels are rasterized (one sample at the
// centre) and the object-space normal is expressed in the low surface's
// MikkTSpace frame with world_to_tangent (exact inverse), as a bake does.
// Texels outside every chart are dilated by `padding`, the rest hold (0, 0, 1).
// Object space fills every texel. Errors (bad_input): an atlas under 3 x 2
// texels, a gutter outside [0, 1/6), tangent space without a low surface.
Status cube_sphere_height_to_normal(const Image& atlas, const CubeSphereOptions& options,
                                    const LowSurface* low, Image& out, HeightToNormalStats& stats);

// Six square face images of one size (order +X, -X, +Y, -Y, +Z, -Z, row 0 of
// each at t = +1) into a 3N x 2N atlas with no gutter (use uv_gutter = 0 with
// it). Only the first channel is kept. Errors (bad_input): not six, not
// square, sizes that differ.
Status assemble_cube_atlas(const std::vector<Image>& faces, Image& atlas);

}  // namespace nmbake
