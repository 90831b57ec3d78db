// Stage "raster": the low mesh's UV triangles into texel samples.
//
// Conventions (DESIGN.md): texel (x, y), y = 0 the top row of the file, has
// its centre at u = (x + 0.5) / W, v = 1 - (y + 0.5) / H. Each texel holds
// `samples` samples at fixed offsets (sample_offsets()): the same pattern in
// every texel and every run.
//
// In pixel coordinates px = u * W, py = (1 - v) * H, texel (x, y) covers
// [x, x + 1] x [y, y + 1] and its sample s sits at (x, y) + sample_offsets()[s].
//
// A texel is covered when its square overlaps a UV triangle with nonzero area
// (touching along an edge or at a corner does not count). Each sample of a
// covered texel takes the triangle containing it (the first in triangle order
// when several do; edges count as inside, so samples on shared edges are not
// lost); a sample inside none (chart borders) takes the nearest point
// (pixel-space distance) of the nearest triangle that overlaps the texel, the
// lower triangle index on ties, so border texels are baked from the surface
// and not left to dilation. A sample strictly inside two or more triangles
// (every barycentric weight above 1e-7) counts as an overlap (mirrored or
// stacked UVs); a shared edge is not an overlap. Barycentrics are in [0, 1]
// with b.x + b.y <= 1. Uncovered texels hold triangle -1 and bary (0, 0).
//
// Degenerate UV triangles are skipped and counted: zero or near-zero area
// (height below 1e-10 of the longest edge), non-finite UVs, or UVs absurdly
// far (> 1e12 pixels) from the map. Triangles entirely off the map are simply
// not rasterized.
//
// Deterministic: binned into 32x32-texel tiles in triangle order, tiles run in
// parallel (TBB); the output is byte-identical for any thread count.
#pragma once

#include <cstdint>
#include <glm/vec2.hpp>
#include <vector>

#include "nmbake/surface.hpp"

namespace nmbake {

// Offsets in [0, 1)^2 inside a texel, for 1, 4, 16 or 64 samples: centre,
// rotated grid, and stratified grids. Any other count is a usage error caught
// by the caller (is_supported_sample_count). For k x k = 4, 16, 64 samples the
// sample of cell (column i, row j) is at ((i + (k - 1 - j + 0.5) / k) / k,
// (j + (i + 0.5) / k) / k), row by row: one sample per cell and per fine row
// and column (n-rooks); k = 2 is exactly RGSS. Fixed constants, never random.
std::vector<glm::vec2> sample_offsets(int samples);
bool is_supported_sample_count(int samples);

// Rows of texels are rasterized in tiles of this many rows (and columns); a
// band of rows (see rasterize) starts on a multiple of it.
constexpr int kRasterTileSize = 32;

struct TexelSamples {
  int width = 0;
  int height = 0;     // rows held: the whole image, or one band of it
  int row_begin = 0;  // image row of the first row held
  int samples = 1;    // per texel
  // Per sample, index (((y - row_begin) * width) + x) * samples + s:
  std::vector<std::int32_t> triangle;  // low triangle, -1 = no sample
  std::vector<glm::vec2> bary;         // weights of corners 1 and 2 (corner 0: 1 - x - y)
  // Per texel: 1 when covered.
  std::vector<std::uint8_t> coverage;

  std::size_t sample_count() const { return triangle.size(); }
};

struct RasterStats {
  std::uint64_t covered_texels = 0;
  std::uint64_t border_samples = 0;           // samples outside every triangle, snapped to the nearest one
  std::uint64_t overlapping_samples = 0;      // strictly inside two or more UV triangles
  std::uint64_t degenerate_uv_triangles = 0;  // zero UV area: skipped by the rasterizer
};

// Reads surface.uv only (three per triangle). Fills `out` (reusing its
// allocation when large enough) and overwrites `stats`. width, height > 0 and
// a supported sample count are checked invariants.
// Rasterizes image rows [row_begin, row_end) of a width x height map (the
// whole map by default); row_begin must be a multiple of kRasterTileSize.
// The result for a texel does not depend on the band it was rasterized in.
// `stats` is overwritten; degenerate_uv_triangles counts every triangle of
// the mesh, whatever the band.
void rasterize(const LowSurface& surface, int width, int height, int samples, TexelSamples& out,
               RasterStats& stats, int row_begin = 0, int row_end = -1);

// Rasterizes only some texels of rows [row_begin, row_end), compactly: the
// `count` texels listed in `texels` (indices into the band, y * width + x
// with y counted from row_begin, ascending) become one row of `count`
// texels in `out` (out.width = count, out.height = 1, out.row_begin = 0), in
// the order listed, each with `samples` samples bit for bit equal to what
// rasterize() gives that texel. For adaptive sampling (adaptive.hpp): the
// texels the first pass chose get their fixed pattern, without a pass over
// the others. `slot` is scratch (one entry per texel of the band, reused
// between calls). row_begin is a multiple of kRasterTileSize.
void rasterize_selected(const LowSurface& surface, int width, int height, int samples, int row_begin,
                        int row_end, const std::uint32_t* texels, std::size_t count, TexelSamples& out,
                        RasterStats& stats, std::vector<std::uint32_t>& slot);

namespace detail {
// The reference for tests: rasterize() with every sample tested on its own.
// rasterize() tests the samples of a texel four at a time (4, 16 and 64
// samples) with the same arithmetic, and must give the same bytes.
void rasterize_per_sample(const LowSurface& surface, int width, int height, int samples, TexelSamples& out,
                          RasterStats& stats, int row_begin = 0, int row_end = -1);
}  // namespace detail

// Rows per band of a width x height map at `samples` per texel: about
// `band_samples` samples (0: 1M), a multiple of kRasterTileSize so bands
// start on tile rows, at most `height`.
int band_rows(int width, int height, int samples, std::size_t band_samples = 0);

}  // namespace nmbake
