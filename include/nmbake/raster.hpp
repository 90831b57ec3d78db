// Stage "raster": the low mesh's UV triangles into texel samples.
//
// Conventions (DESIGN.md): texel (x, y), y = 0 the top row of the file, has
// its centre at u = (x + 0.5) / W, v = 1 - (y + 0.5) / H. Each texel holds
// `samples` samples at fixed offsets (sample_offsets()): the same pattern in
// every texel and every run.
//
// A texel is covered when its square overlaps a UV triangle. Each sample of a
// covered texel takes the triangle containing it (the first in triangle order
// when several do); a sample inside none (chart borders) takes the nearest
// point of the nearest triangle that overlaps the texel, so border texels are
// baked from the surface and not left to dilation. A sample strictly inside
// two or more triangles counts as an overlap (mirrored or stacked UVs).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec2.hpp>

#include "nmbake/surface.hpp"

namespace nmbake {

// Offsets in [0, 1)^2 inside a texel, for 1, 4, 16 or 64 samples: centre,
// rotated grid, and stratified grids. Any other count is a usage error caught
// by the caller (is_supported_sample_count).
std::vector<glm::vec2> sample_offsets(int samples);
bool is_supported_sample_count(int samples);

struct TexelSamples {
  int width = 0;
  int height = 0;
  int samples = 1;  // per texel
  // Per sample, index ((y * width) + x) * samples + s:
  std::vector<std::int32_t> triangle;  // low triangle, -1 = no sample
  std::vector<glm::vec2> bary;         // weights of corners 1 and 2 (corner 0: 1 - x - y)
  // Per texel: 1 when covered.
  std::vector<std::uint8_t> coverage;

  std::size_t sample_count() const { return triangle.size(); }
};

struct RasterStats {
  std::uint64_t covered_texels = 0;
  std::uint64_t border_samples = 0;      // samples outside every triangle, snapped to the nearest one
  std::uint64_t overlapping_samples = 0;  // strictly inside two or more UV triangles
  std::uint64_t degenerate_uv_triangles = 0;  // zero UV area: skipped by the rasterizer
};

void rasterize(const LowSurface& surface, int width, int height, int samples, TexelSamples& out,
               RasterStats& stats);

}  // namespace nmbake
