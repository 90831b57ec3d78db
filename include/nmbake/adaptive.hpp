// Adaptive sampling (`--samples adaptive`): spend rays only where the detail
// is. A first pass bakes every texel with one sample (its centre); then the
// texels where that pass says the normal varies within a texel are baked
// again with the fixed pattern of `max_samples` (4, 16 or 64, the same
// pattern a fixed bake uses), and their value replaces the first one. A texel
// not refined holds exactly the 1-sample bake's value, a refined one exactly
// the `max_samples` bake's value for that texel.
//
// "Varies within the texel" is read from the first pass of the texel and its
// eight neighbours, and nothing else, so the choice does not depend on the
// thread count, the band size or tiles (the bake keeps the first-pass values
// of the row above and below each band):
//   * a miss next to a hit, or a texel whose centre ray missed: refine;
//   * the world-space high normal's second difference along a row, a column
//     or a diagonal, |n(-1) + n(+1) - 2 n(0)|, above `normal_threshold`
//     (about radians): a one-sample texel is exact where the normal is
//     linear across it (the box filter of a linear function is its centre
//     value), so only the curvature the centre sample cannot see counts, not
//     the slope;
//   * the same second difference of the hit distance, in texels of the low
//     surface, above `depth_threshold`: steps and silhouettes where two
//     texels see different surfaces;
//   * at a chart border (a neighbour without a sample), the first difference
//     of the normal above `border_threshold`.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "nmbake/mesh.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/trace.hpp"

namespace nmbake {

struct AdaptiveOptions {
  int max_samples = 16;  // 4, 16 or 64: the pattern of a refined texel
  float normal_threshold = 0.01f;
  float depth_threshold = 0.25f;
  float border_threshold = 0.05f;
  float turn_threshold = 1e9f;
};

// What the first pass leaves per texel of a band: the state of the centre
// sample and, for a hit, the unit world-space high normal (smooth or face,
// as the encode reads it) and the hit distance in texels of the low surface.
struct FirstPass {
  enum State : std::uint8_t { none = 0, hit = 1, miss = 2 };
  int width = 0;
  int rows = 0;
  std::vector<std::uint8_t> state;
  std::vector<glm::vec3> normal;
  std::vector<float> depth;
  // How much the hit triangle's interpolated normal turns across one texel
  // of the low surface: the largest |n_i - n_j| / |p_i - p_j| over its
  // edges times the texel size (about radians).
  std::vector<float> turn;
};

// Scene units per texel for each low triangle of a width x height map: the
// square root of its world area over its UV area in texels (0 for a
// degenerate one, whose depth differences are then not used).
std::vector<float> texel_sizes(const LowSurface& surface, int width, int height);

// The first-pass values of a band baked with one sample per texel.
void first_pass_values(const TexelSamples& samples, const Hits& hits, const Mesh& high, bool smooth_high,
                       const std::vector<float>& texel_size, FirstPass& out);

// The texels of `band` to refine, as indices into the band (y * width + x,
// ascending). `above` and `below` are the rows just outside the band (their
// first row is used; empty FirstPass: the map's edge).
void refine_texels(const FirstPass& above, const FirstPass& band, const FirstPass& below,
                   const AdaptiveOptions& options, std::vector<std::uint32_t>& refined);

// Row `row` of `from` as a one-row FirstPass (for the next band's `above`).
FirstPass first_pass_row(const FirstPass& from, int row);

}  // namespace nmbake
