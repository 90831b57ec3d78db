// Judging a map by what a renderer shows (the accuracy lab's appearance
// error).
//
// The lab's analytic evaluator proves that the bake's rays are traced and
// encoded right; it cannot say whether they were the right rays to cast.
// This does: from a fixed set of cameras around the object, the high mesh
// is rendered with its interpolated vertex normals and the low mesh with
// the map decoded as `nmbake preview` decodes it (decode_map_normal), and
// every sample where both meshes are hit and their hits lie within
// `depth_tolerance` of each other along the camera ray is compared: the
// angle between the high normal and the decoded one.
//
// Two references come with it, from the same samples:
//   * the low mesh without a map (its own interpolated shading normal);
//   * the consensus floor: every sample is binned to the map texel its low
//     hit falls in (texel x = floor(u W), y = floor((1 - v) H)); per texel
//     the normalised mean of the high normals seen through it from every
//     view is the best single value a texel can hold for these views, and
//     the floor is the error of holding exactly that (per sample, the angle
//     between its texel's consensus and its high normal; no filtering).
// A bilinearly filtered map can beat the floor a little where the normal
// turns within a texel, and pays for filtering elsewhere; a bake within
// ~1.3x of it is as good as a map on that texel grid gets for these views.
//
// Cameras: 14 directions, the 6 axis directions and the 8 cube diagonals
// (yaw 0/90/180/270 at pitch 0, pitch +-89 from above and below, yaw
// 45/135/225/315 at pitch +-35.26), each a 30-degree perspective camera
// framing the bounding sphere of both meshes (preview's camera, up = y).
// Deterministic: the same numbers for any thread count.
#pragma once

#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/surface.hpp"

namespace nmbake {

struct AppearanceOptions {
  int size = 320;       // pixels per side of each view
  int supersample = 2;  // k x k samples per pixel (a fixed grid)
  // Samples whose low and high hits are further apart than this along the
  // camera ray are not compared (silhouettes that differ, a part seen
  // through a gap): a share of the low mesh's bounding-box diagonal.
  float depth_tolerance = 0.05f;
};

// Yaw and pitch (degrees) of the fixed cameras, in order.
const std::vector<glm::vec2>& appearance_views();

// The compared samples of every view, in view order and row-major within a
// view, and the consensus of every texel of a map_width x map_height map.
struct AppearanceSamples {
  int map_width = 0, map_height = 0;
  std::vector<std::int32_t> low_triangle;
  std::vector<glm::vec2> low_bary;
  std::vector<std::uint32_t> texel;    // y * map_width + x
  std::vector<glm::vec3> high_normal;  // unit, world space
  std::vector<std::uint8_t> view;      // the camera (appearance_views() index)
  std::vector<std::uint32_t> pixel;    // row * size * supersample + column in that view's sample grid
  int size = 0, supersample = 0;       // of every view
  std::vector<glm::vec3> consensus;    // per texel: unit, or 0 where no sample fell
  std::uint64_t low_hits = 0;          // samples that hit the low mesh (all views)
  std::uint64_t high_missed = 0;       // of those, the high mesh was not hit
  std::uint64_t depth_rejected = 0;    // of those, the hits were too far apart
  std::uint64_t high_normal_fallbacks = 0;
  float depth_tolerance = 0.0f;  // resolved, scene units
  std::size_t sample_count() const { return texel.size(); }
};

// Renders every view and keeps the samples to compare. `surface` is the low
// mesh's (build_low_surface: MikkTSpace), `high` padded (pad_for_embree)
// with unit normals.
Status render_appearance(const LowSurface& surface, const Mesh& high, int map_width, int map_height,
                         const AppearanceOptions& options, AppearanceSamples& out);

struct AppearanceError {
  std::size_t samples = 0;
  double mean = 0.0, p95 = 0.0, p99 = 0.0, max = 0.0;  // degrees; percentiles nearest-rank
  std::uint64_t decode_fallbacks = 0;
  std::string to_text() const;
};
AppearanceError summarize_appearance(std::vector<float> angles_degrees);

// Per compared sample, the angle in degrees between the high normal and:
// the map decoded on the low mesh (`decode_fallbacks` counts decode_map_normal's
// fallbacks, may be null); the low mesh's own shading normal (no map); the
// consensus of the sample's texel (the floor).
std::vector<float> appearance_angles(const AppearanceSamples& samples, const LowSurface& surface,
                                     const Image& map, NormalSpace space, GreenChannel green,
                                     std::uint64_t* decode_fallbacks);
std::vector<float> appearance_angles_without_map(const AppearanceSamples& samples, const LowSurface& surface);
std::vector<float> appearance_floor_angles(const AppearanceSamples& samples);

// The same, summarised.
AppearanceError appearance_error(const AppearanceSamples& samples, const LowSurface& surface,
                                 const Image& map, NormalSpace space, GreenChannel green);
AppearanceError appearance_without_map(const AppearanceSamples& samples, const LowSurface& surface);
AppearanceError appearance_floor(const AppearanceSamples& samples);

// Where the error is: one row per view, one panel per angle set in
// `columns` (each a value per compared sample), every pixel the mean angle
// of its compared samples on preview's heat ramp (dark blue 0 to red at
// heat_max degrees), the rest dark grey.
Image appearance_heat(const AppearanceSamples& samples, const std::vector<const std::vector<float>*>& columns,
                      float heat_max);

}  // namespace nmbake
