// Adaptive sampling (`--samples adaptive`): spend rays only where the detail
// is. Every texel is first baked with one sample (its centre). Texels where
// that pass says the stored value varies within a texel are baked again with
// the fixed 4-sample pattern; of those, the texels whose four samples still
// disagree are baked with the fixed pattern of `max_samples` (16 or 64; with
// max_samples 4 there is no second level). Each level's value replaces the
// one before, so a texel holds exactly what the fixed 1-, 4- or max-sample
// bake gives it.
//
// Level 1 reads the first pass of the texel and its eight neighbours, and
// nothing else, so the choice does not depend on the thread count, the band
// size or tiles (the bake keeps the first pass of the row above and below
// each band; a tile of rows traces the rows just outside it):
//   * a miss next to a hit, or a texel whose centre ray missed;
//   * the second difference of the stored vector (the map's own value: in
//     tangent space, so the low surface's curvature is not counted) along a
//     row, a column or a diagonal, |v(-1) + v(+1) - 2 v(0)|, above
//     `normal_threshold`: a one-sample texel is exact where the value is
//     linear across it (the box filter of a linear function is its centre
//     value), so curvature counts, not slope;
//   * the same second difference of the hit distance, in texels of the low
//     surface, above `depth_threshold`: steps and silhouettes where
//     neighbouring texels see different surfaces;
//   * at a chart border (one neighbour of a pair without a sample), the first
//     difference of the stored vector above `border_threshold`.
// Level 2 reads the texel's own four samples: the largest angle (radians)
// between a sample's high normal and their mean above `spread_threshold`.
// A threshold of 0 refines every covered texel at its level.
// Measured on the accuracy lab's scenes (README, "Adaptive sampling"):
// second differences of world normals instead of stored vectors picked the
// low mesh's curvature and missed the detail; one level of `max_samples`
// spent four times the rays of a 4-sample level for the same error on all but
// the hard edges.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <vector>

#include "nmbake/mesh.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/trace.hpp"

namespace nmbake {

struct AdaptiveOptions {
  int max_samples = 16;  // 4, 16 or 64: the pattern of the last level
  float normal_threshold = 0.003f;
  float depth_threshold = 0.25f;
  float border_threshold = 0.02f;
  float spread_threshold = 0.02f;
};

// The samples of each level: 4, then max_samples when it is larger.
std::vector<int> adaptive_levels(const AdaptiveOptions& options);

// What the first pass leaves per texel of a band for level 1: the state of
// the centre sample, the encoded texel (rgb = 0.5 v + 0.5, the stored vector
// v) and the hit distance in texels of the low surface.
struct FirstPass {
  enum State : std::uint8_t { none = 0, hit = 1, miss = 2 };
  int width = 0;
  int rows = 0;
  std::vector<std::uint8_t> state;
  std::vector<float> rgb;  // three a texel
  std::vector<float> depth;
};

// Scene units per texel for each low triangle of a width x height map: the
// square root of its world area over its UV area in texels (0 for a
// degenerate one, whose depth differences are then not used).
std::vector<float> texel_sizes(const LowSurface& surface, int width, int height);

// The first-pass values of a band baked with one sample per texel; out.rgb
// must hold the band's encoded rows already.
void first_pass_values(const TexelSamples& samples, const Hits& hits, const std::vector<float>& texel_size,
                       FirstPass& out);

// Row `row` of `from` as a one-row FirstPass (the next band's `above`).
FirstPass first_pass_row(const FirstPass& from, int row);

// Level 1: the texels of `band` to refine, as indices into the band
// (y * width + x, ascending). `above` and `below` are the rows just outside
// the band (their first row is used; an empty FirstPass: the map's edge).
void refine_texels(const FirstPass& above, const FirstPass& band, const FirstPass& below,
                   const AdaptiveOptions& options, std::vector<std::uint32_t>& refined);

// Level 2: of the texels of a compact band (`samples`: one row of texels,
// `texels[i]` the band index of texel i), those whose samples' high normals
// spread more than options.spread_threshold, appended to `out` in order. A
// sample that missed while another hit counts as spread.
void spread_texels(const TexelSamples& samples, const Hits& hits, const Mesh& high, bool smooth_high,
                   const std::uint32_t* texels, const AdaptiveOptions& options,
                   std::vector<std::uint32_t>& out);

}  // namespace nmbake
