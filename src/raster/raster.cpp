// Stage "raster": the low mesh's UV triangles into texel samples.
//
// Algorithms:
//   * coverage: the separating axis theorem (Gottschalk, Lin & Manocha,
//     "OBBTree", SIGGRAPH 1996) between a texel square and a triangle, in 2D:
//     the two box axes (the clamped bounding box) and the three edge normals,
//     as in Akenine-Moller, "Fast 3D Triangle-Box Overlap Testing" (JGT 2001)
//     reduced to the plane. Touching is separation: only a nonzero overlap
//     area covers a texel.
//   * inside tests and barycentrics: edge functions (Pineda, "A Parallel
//     Algorithm for Polygon Rasterization", SIGGRAPH 1988). Each edge is
//     evaluated from a canonical endpoint order (lexicographically smaller
//     endpoint first), so two triangles sharing an edge compute exactly
//     opposite values and a sample on the shared edge is never lost.
//   * border samples: the closest point on the triangle (Ericson, "Real-Time
//     Collision Detection", 5.1.5), which for an outside point lies on one of
//     the three edge segments.
//   * sample patterns: rotated-grid supersampling for 4 samples and, for 16
//     and 64, the canonical arrangement of multi-jittered sampling (Chiu,
//     Shirley & Wang, "Multi-Jittered Sampling", Graphics Gems IV, 1994)
//     without its random shuffle; see sample_offsets().
//
// Everything runs in pixel space (px = u * W, py = (1 - v) * H) and in double
// precision: at 16384^2 a float keeps only ~1/1000 texel.
#include "nmbake/raster.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <glm/vec2.hpp>
#include <limits>

#include "base/huge_pages.hpp"
#include "base/shuffle_compat.hpp"
#include "nmbake/common.hpp"

namespace nmbake {

namespace {

// 32x32 texels: at 64 samples the per-thread scratch (9 bytes per sample) is
// ~0.6 MB and stays in L2.
constexpr int tile_size = kRasterTileSize;

// A sample counts as strictly inside when every normalised edge function
// (its barycentric weight) exceeds this; far above double rounding noise
// (~1e-13 for any map size), far below any real overlap.
constexpr double strict_epsilon = 1e-7;

// A triangle whose height is below this fraction of its longest edge is a
// degenerate (collinear) UV triangle. A sliver 0.01 texel thick and 16384
// texels long has a ratio of 6e-7 and is still rasterized.
constexpr double degenerate_epsilon = 1e-10;

// UVs beyond this many pixels from the image are treated as unusable (counted
// with the degenerate triangles): edge functions could overflow.
constexpr double max_pixel_coordinate = 1e12;

// cross(d, p - lo) with lo the canonical first endpoint and d = +-(hi - lo),
// the sign chosen so that the interior of the triangle is positive. Negating
// d is exact, so a shared edge still gives exactly opposite values.
struct EdgeFunction {
  glm::dvec2 lo{0.0};
  glm::dvec2 d{0.0};

  double operator()(glm::dvec2 p) const { return d.x * (p.y - lo.y) - d.y * (p.x - lo.x); }
  // Components of the gradient.
  double dx() const { return -d.y; }
  double dy() const { return d.x; }
};

struct SetupTriangle {
  glm::dvec2 corner[3];
  EdgeFunction edge[3];   // edge[i] is opposite corner i: the unnormalised weight of corner i
  double extent[3] = {};  // edge[i] at corner i (twice the area, up to rounding)
  double strict_threshold = 0.0;
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // inclusive texel bounding box, clamped to the image
  // Per edge, the corner of a texel (offsets 0 or 1) where the edge function
  // is highest, and the opposite one where it is lowest (box_overlaps).
  glm::dvec2 high_corner[3], low_corner[3];
};

EdgeFunction make_edge(glm::dvec2 a, glm::dvec2 b, glm::dvec2 opposite) {
  EdgeFunction e;
  const bool a_first = a.x < b.x || (a.x == b.x && a.y < b.y);
  e.lo = a_first ? a : b;
  e.d = (a_first ? b : a) - e.lo;
  if (e(opposite) < 0.0) e.d = -e.d;
  return e;
}

// Builds the pixel-space triangle; false when it is degenerate (zero or
// near-zero UV area, non-finite or absurd coordinates).
bool setup_triangle(const glm::vec2* uv, int width, int height, SetupTriangle& t) {
  for (int i = 0; i < 3; ++i) {
    const double px = static_cast<double>(uv[i].x) * width;
    const double py = (1.0 - static_cast<double>(uv[i].y)) * height;
    if (!std::isfinite(px) || !std::isfinite(py) || std::abs(px) > max_pixel_coordinate ||
        std::abs(py) > max_pixel_coordinate) {
      return false;
    }
    t.corner[i] = {px, py};
  }
  double longest2 = 0.0;
  for (int i = 0; i < 3; ++i) {
    const glm::dvec2 a = t.corner[(i + 1) % 3];
    const glm::dvec2 b = t.corner[(i + 2) % 3];
    const glm::dvec2 d = b - a;
    longest2 = std::max(longest2, d.x * d.x + d.y * d.y);
    t.edge[i] = make_edge(a, b, t.corner[i]);
    t.extent[i] = t.edge[i](t.corner[i]);
    const double hx = t.edge[i].dx() > 0.0 ? 1.0 : 0.0, hy = t.edge[i].dy() > 0.0 ? 1.0 : 0.0;
    t.high_corner[i] = {hx, hy};
    t.low_corner[i] = {1.0 - hx, 1.0 - hy};
  }
  const double smallest = std::min({t.extent[0], t.extent[1], t.extent[2]});
  if (!(smallest > degenerate_epsilon * longest2)) return false;
  const double area2 = (t.extent[0] + t.extent[1] + t.extent[2]) / 3.0;
  t.strict_threshold = strict_epsilon * area2;

  double min_x = t.corner[0].x, max_x = min_x, min_y = t.corner[0].y, max_y = min_y;
  for (int i = 1; i < 3; ++i) {
    min_x = std::min(min_x, t.corner[i].x);
    max_x = std::max(max_x, t.corner[i].x);
    min_y = std::min(min_y, t.corner[i].y);
    max_y = std::max(max_y, t.corner[i].y);
  }
  // Texel x spans [x, x + 1]: a positive overlap needs x < max_x and x + 1 > min_x.
  t.x0 = static_cast<int>(std::clamp(std::floor(min_x), 0.0, static_cast<double>(width)));
  t.x1 = static_cast<int>(std::clamp(std::ceil(max_x) - 1.0, -1.0, static_cast<double>(width - 1)));
  t.y0 = static_cast<int>(std::clamp(std::floor(min_y), 0.0, static_cast<double>(height)));
  t.y1 = static_cast<int>(std::clamp(std::ceil(max_y) - 1.0, -1.0, static_cast<double>(height - 1)));
  return true;
}

// Edge-normal axes of the separating axis test for the box [x, x + size] x
// [y, y + size]; the box axes are handled by the bounding box. On each edge
// axis the triangle projects to [0, extent]. Each edge's highest and lowest
// box corners were chosen at set-up (offsets 0 or 1 times size, exact), so
// the per-texel loops pay for the evaluations only.
[[gnu::always_inline]] inline bool box_overlaps(const SetupTriangle& t, double x, double y, double size) {
  for (int i = 0; i < 3; ++i) {
    const EdgeFunction& e = t.edge[i];
    if (e({x + t.high_corner[i].x * size, y + t.high_corner[i].y * size}) <= 0.0) return false;
    if (e({x + t.low_corner[i].x * size, y + t.low_corner[i].y * size}) >= t.extent[i]) return false;
  }
  return true;
}

// The texels of row y in [x_begin, x_end] that box_overlaps() passes: false
// when none, else [span_begin, span_end], every texel of which passes. They
// are one run: along a row each of box_overlaps()'s six tests compares
// d.x * (py - lo.y) - d.y * (px - lo.x) with a constant, px = x or x + 1,
// and that value is monotone in x even in floating point (a subtraction of
// a constant and a multiplication by one are monotone under rounding), so
// each test holds on a half-line of x and all six on an interval. Only the
// failing texels at either end and the two ends themselves are tested.
inline bool overlap_span(const SetupTriangle& t, int y, int x_begin, int x_end, int& span_begin,
                         int& span_end) {
  int lo = x_begin;
  while (lo <= x_end && !box_overlaps(t, lo, y, 1.0)) ++lo;
  if (lo > x_end) return false;
  int hi = x_end;
  while (hi > lo && !box_overlaps(t, hi, y, 1.0)) --hi;
  span_begin = lo;
  span_end = hi;
  return true;
}

// Nearest point of the triangle to p (p outside it): squared distance and the
// weights of corners 1 and 2. Edges in order 0, 1, 2; a later edge wins only
// when strictly nearer.
double nearest_point(const SetupTriangle& t, glm::dvec2 p, glm::vec2& bary) {
  double best = std::numeric_limits<double>::infinity();
  double weight[3] = {1.0, 0.0, 0.0};
  for (int i = 0; i < 3; ++i) {
    const int ia = (i + 1) % 3;
    const int ib = (i + 2) % 3;
    const glm::dvec2 a = t.corner[ia];
    const glm::dvec2 d = t.corner[ib] - a;
    const glm::dvec2 ap = p - a;
    const double s = std::clamp((ap.x * d.x + ap.y * d.y) / (d.x * d.x + d.y * d.y), 0.0, 1.0);
    const glm::dvec2 q = a + s * d - p;
    const double dist2 = q.x * q.x + q.y * q.y;
    if (dist2 < best) {
      best = dist2;
      weight[i] = 0.0;
      weight[ia] = 1.0 - s;
      weight[ib] = s;
    }
  }
  bary = {static_cast<float>(weight[1]), static_cast<float>(weight[2])};
  return best;
}

// Weights of corners 1 and 2 from the edge functions of an inside sample,
// clamped to the triangle (rounding can leave them a hair outside).
glm::vec2 inside_bary(double e0, double e1, double e2) {
  const double inverse_sum = 1.0 / (e0 + e1 + e2);
  double b1 = std::clamp(e1 * inverse_sum, 0.0, 1.0);
  double b2 = std::clamp(e2 * inverse_sum, 0.0, 1.0);
  if (b1 + b2 > 1.0) {
    const double total = b1 + b2;
    b1 /= total;
    b2 /= total;
  }
  glm::vec2 b{static_cast<float>(b1), static_cast<float>(b2)};
  // Float rounding of the two weights can still push the sum over 1.
  if (b.x + b.y > 1.0f) b.y = 1.0f - b.x;
  return b;
}

// Four samples of one texel in SIMD lanes (GCC vector extensions, two
// lanes of doubles per SSE2 register). Each lane does exactly the
// operations of pass 1's per-sample loop and of inside_bary(), in the same
// order and without fused multiply-adds, so the samples are bit-identical to
// that loop (Raster.FourLanesEqualPerSample).
typedef double d2 __attribute__((vector_size(16)));
typedef std::int64_t l2 __attribute__((vector_size(16)));
typedef float f4 __attribute__((vector_size(16)));
typedef std::int32_t i4 __attribute__((vector_size(16)));

// Lanes 0-1 and 2-3 of a sample group's offsets.
struct LaneOffsets {
  d2 x[2], y[2];
};

inline d2 splat(double v) { return d2{v, v}; }

inline d2 edge2(const EdgeFunction& e, d2 px, d2 py) {
  return splat(e.d.x) * (py - splat(e.lo.y)) - splat(e.d.y) * (px - splat(e.lo.x));
}

// std::clamp(v, 0.0, 1.0) per lane: (v < 0) ? 0 : (1 < v) ? 1 : v.
inline d2 clamp01(d2 v) {
  const d2 zero = splat(0.0), one = splat(1.0);
  return v < zero ? zero : (one < v ? one : v);
}

inline unsigned lane_bits(l2 mask) {
#if defined(__SSE2__)
  return static_cast<unsigned>(__builtin_ia32_movmskpd(reinterpret_cast<d2>(mask)));
#else
  return static_cast<unsigned>((mask[0] & 1) | (mask[1] & 2));
#endif
}

// Lane i's flag as byte i of a little-endian word, for the per-sample byte
// arrays (inside, strict_count) read and written four at a time.
constexpr std::uint32_t lane_bytes(unsigned bits) {
  return (bits & 1u) | (bits & 2u) << 7 | (bits & 4u) << 14 | (bits & 8u) << 21;
}
static_assert(std::endian::native == std::endian::little, "byte i of a word is lane i");

// inside_bary()'s double part for two lanes: the clamped, renormalised
// weights of corners 1 and 2. A lane outside the triangle computes garbage
// that is never stored.
inline void inside_bary2(d2 e0, d2 e1, d2 e2, d2& b1, d2& b2) {
  const d2 inverse_sum = splat(1.0) / (e0 + e1 + e2);
  b1 = clamp01(e1 * inverse_sum);
  b2 = clamp01(e2 * inverse_sum);
  const d2 total = b1 + b2;
  const l2 over = total > splat(1.0);
  if (lane_bits(over) != 0) {  // rare (rounding past 1): the divisions only then
    b1 = over ? b1 / total : b1;
    b2 = over ? b2 / total : b2;
  }
}

inline f4 to_floats(d2 lo, d2 hi) {
  return f4{static_cast<float>(lo[0]), static_cast<float>(lo[1]), static_cast<float>(hi[0]),
            static_cast<float>(hi[1])};
}

[[gnu::always_inline]] inline void inside_four(const SetupTriangle& tri, std::int32_t t, double x, double y,
                                               const LaneOffsets& offsets, std::uint8_t* inside,
                                               std::uint8_t* strict_count, std::uint8_t& inside_count,
                                               std::int32_t* out_triangle, glm::vec2* out_bary) {
  const d2 zero = splat(0.0), threshold = splat(tri.strict_threshold);
  d2 e0[2], e1[2], e2[2];
  unsigned in_bits = 0, strict_bits = 0;
  for (int h = 0; h < 2; ++h) {
    const d2 px = splat(x) + offsets.x[h], py = splat(y) + offsets.y[h];
    e0[h] = edge2(tri.edge[0], px, py);
    e1[h] = edge2(tri.edge[1], px, py);
    e2[h] = edge2(tri.edge[2], px, py);
    const l2 in = (e0[h] >= zero) & (e1[h] >= zero) & (e2[h] >= zero);
    in_bits |= lane_bits(in) << (2 * h);
    strict_bits |= lane_bits(in & (e0[h] > threshold) & (e1[h] > threshold) & (e2[h] > threshold)) << (2 * h);
  }
  if (in_bits == 0) return;
  // strict_count saturates at 2: a byte c in {0, 1, 2} grows by one when bit 1 is clear.
  std::uint32_t counts;
  std::memcpy(&counts, strict_count, 4);
  counts += ~counts >> 1 & lane_bytes(strict_bits);
  std::memcpy(strict_count, &counts, 4);
  std::uint32_t taken;
  std::memcpy(&taken, inside, 4);
  const std::uint32_t fresh = lane_bytes(in_bits) & ~taken;
  if (fresh == 0) return;
  const std::uint32_t now = taken | fresh;
  std::memcpy(inside, &now, 4);
  // The sum of fresh's four 0/1 bytes lands in its top byte (no popcnt on baseline x86-64).
  inside_count = static_cast<std::uint8_t>(inside_count + ((fresh * 0x01010101u) >> 24));

  d2 b1[2], b2[2];
  inside_bary2(e0[0], e1[0], e2[0], b1[0], b2[0]);
  inside_bary2(e0[1], e1[1], e2[1], b1[1], b2[1]);
  const f4 bx = to_floats(b1[0], b1[1]);
  f4 by = to_floats(b2[0], b2[1]);
  const f4 one = {1.0f, 1.0f, 1.0f, 1.0f};
  by = (bx + by > one) ? one - bx : by;  // float rounding can still push the sum over 1
  if (fresh == 0x01010101u) {
    const i4 tri4 = {t, t, t, t};
    std::memcpy(out_triangle, &tri4, sizeof tri4);
    const f4 lo = __builtin_shuffle(bx, by, i4{0, 4, 1, 5}), hi = __builtin_shuffle(bx, by, i4{2, 6, 3, 7});
    std::memcpy(&out_bary[0].x, &lo, sizeof lo);
    std::memcpy(&out_bary[2].x, &hi, sizeof hi);
    return;
  }
  for (int lane = 0; lane < 4; ++lane) {
    if (!(fresh >> (8 * lane) & 1u)) continue;
    out_triangle[lane] = t;
    out_bary[lane] = glm::vec2(bx[lane], by[lane]);
  }
}

using detail::size_output;

struct TileScratch {
  std::vector<double> best_distance2;      // per sample of the tile, border candidates only
  std::vector<std::uint8_t> inside;        // per sample: a containing triangle was found
  std::vector<std::uint8_t> strict_count;  // per sample: strictly containing triangles, saturates at 2
  std::vector<std::uint8_t> covered;       // per texel of the tile
  std::vector<std::uint8_t> inside_count;  // per texel of the tile: samples with a containing triangle
};

struct TileCounts {
  std::uint64_t covered_texels = 0;
  std::uint64_t border_samples = 0;
  std::uint64_t overlapping_samples = 0;
};

}  // namespace

bool is_supported_sample_count(int samples) {
  return samples == 1 || samples == 4 || samples == 16 || samples == 64;
}

// One family for 4, 16 and 64 samples: a k x k grid of cells, the sample of
// cell (column i, row j) at
//   x = (i + (k - 1 - j + 0.5) / k) / k,   y = (j + (i + 0.5) / k) / k,
// listed row by row. Every one of the k^2 fine columns and k^2 fine rows
// holds exactly one sample (n-rooks) and every cell one (stratified); for
// k = 2 this is exactly the RGSS pattern (0.375, 0.125), (0.875, 0.375),
// (0.125, 0.625), (0.625, 0.875). All offsets are dyadic fractions, exact in
// float. 1 sample: the texel centre.
std::vector<glm::vec2> sample_offsets(int samples) {
  NMBAKE_CHECK(is_supported_sample_count(samples), "unsupported sample count");
  if (samples == 1) return {glm::vec2(0.5f, 0.5f)};
  const int k = samples == 4 ? 2 : samples == 16 ? 4 : 8;
  std::vector<glm::vec2> offsets;
  offsets.reserve(static_cast<std::size_t>(samples));
  const double kd = k;
  for (int j = 0; j < k; ++j) {
    for (int i = 0; i < k; ++i) {
      const double x = (i + (k - 1 - j + 0.5) / kd) / kd;
      const double y = (j + (i + 0.5) / kd) / kd;
      offsets.emplace_back(static_cast<float>(x), static_cast<float>(y));
    }
  }
  return offsets;
}

namespace {

// Texels chosen for a compact raster (rasterize_selected): `slot` holds, per
// texel of the band, its index in the output or kNotSelected.
constexpr std::uint32_t kNotSelected = 0xffffffffu;
struct Selection {
  const std::uint32_t* slot = nullptr;  // null: every texel, in image order
  std::size_t count = 0;
};

void rasterize_impl(const LowSurface& surface, int width, int height, int samples, TexelSamples& out,
                    RasterStats& stats, int row_begin, int row_end, bool per_sample,
                    const Selection& selection = {}) {
  NMBAKE_CHECK(width > 0 && height > 0, "raster size must be positive");
  if (row_end < 0) row_end = height;
  NMBAKE_CHECK(row_begin >= 0 && row_begin < row_end && row_end <= height && row_begin % kRasterTileSize == 0,
               "row band must lie in the image and start on a tile row");
  NMBAKE_CHECK(is_supported_sample_count(samples), "unsupported sample count");
  NMBAKE_CHECK(surface.uv.size() % 3 == 0, "LowSurface::uv must hold three corners per triangle");
  const std::size_t triangle_count = surface.uv.size() / 3;
  NMBAKE_CHECK(triangle_count <= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()),
               "too many triangles for 32-bit triangle ids");

  stats = RasterStats{};
  const int rows = row_end - row_begin;
  const bool compact = selection.slot != nullptr;
  // A compact output is one row of the selected texels.
  const std::size_t texel_count =
      compact ? selection.count : static_cast<std::size_t>(width) * static_cast<std::size_t>(rows);
  const std::size_t sample_total = texel_count * static_cast<std::size_t>(samples);
  out.width = compact ? static_cast<int>(selection.count) : width;
  out.height = compact ? 1 : rows;
  out.row_begin = compact ? 0 : row_begin;
  out.samples = samples;
  // A reused `out` keeps its allocation; every element is rewritten by its
  // tile below.
  size_output(out.triangle, sample_total);
  size_output(out.bary, sample_total);
  size_output(out.coverage, texel_count);

  const std::vector<glm::vec2> offsets = sample_offsets(samples);
  // 4, 16 and 64 samples: four at a time, lanes in sample order.
  const bool four_lanes = !per_sample && samples % 4 == 0;
  std::vector<LaneOffsets> lane_offsets(static_cast<std::size_t>(samples) / 4);
  for (std::size_t g = 0; g < lane_offsets.size(); ++g) {
    for (int lane = 0; lane < 4; ++lane) {
      lane_offsets[g].x[lane / 2][lane % 2] = static_cast<double>(offsets[4 * g + lane].x);
      lane_offsets[g].y[lane / 2][lane % 2] = static_cast<double>(offsets[4 * g + lane].y);
    }
  }

  // Set-up and binning, serial and in triangle order so every tile list is
  // in triangle order. Tiles whose box the triangle does not overlap are left
  // out (a long diagonal sliver would otherwise visit the whole map).
  const int tiles_x = (width + tile_size - 1) / tile_size;
  const int tile_row0 = row_begin / tile_size;
  const int tiles_y = (row_end - row_begin + tile_size - 1) / tile_size;
  const std::size_t tile_count = static_cast<std::size_t>(tiles_x) * static_cast<std::size_t>(tiles_y);
  std::vector<SetupTriangle> setup(triangle_count);
  std::vector<std::uint8_t> usable(triangle_count, 0);
  std::vector<std::size_t> tile_begin(tile_count + 1, 0);
  for (std::size_t t = 0; t < triangle_count; ++t) {
    SetupTriangle& tri = setup[t];
    if (!setup_triangle(&surface.uv[3 * t], width, height, tri)) {
      ++stats.degenerate_uv_triangles;
      continue;
    }
    // Rows outside the band are someone else's.
    tri.y0 = std::max(tri.y0, row_begin);
    tri.y1 = std::min(tri.y1, row_end - 1);
    if (tri.x0 > tri.x1 || tri.y0 > tri.y1) continue;  // entirely off the map (or the band)
    usable[t] = 1;
    for (int ty = tri.y0 / tile_size; ty <= tri.y1 / tile_size; ++ty) {
      for (int tx = tri.x0 / tile_size; tx <= tri.x1 / tile_size; ++tx) {
        if (box_overlaps(tri, tx * tile_size, ty * tile_size, tile_size)) {
          ++tile_begin[static_cast<std::size_t>(ty - tile_row0) * tiles_x + tx + 1];
        }
      }
    }
  }
  for (std::size_t i = 0; i < tile_count; ++i) tile_begin[i + 1] += tile_begin[i];
  std::vector<std::int32_t> tile_triangles(tile_begin[tile_count]);
  {
    std::vector<std::size_t> fill(tile_begin.begin(), tile_begin.end() - 1);
    for (std::size_t t = 0; t < triangle_count; ++t) {
      if (!usable[t]) continue;
      const SetupTriangle& tri = setup[t];
      for (int ty = tri.y0 / tile_size; ty <= tri.y1 / tile_size; ++ty) {
        for (int tx = tri.x0 / tile_size; tx <= tri.x1 / tile_size; ++tx) {
          if (box_overlaps(tri, tx * tile_size, ty * tile_size, tile_size)) {
            tile_triangles[fill[static_cast<std::size_t>(ty - tile_row0) * tiles_x + tx]++] =
                static_cast<std::int32_t>(t);
          }
        }
      }
    }
  }

  // Tiles without a selected texel have nothing to do.
  std::vector<std::uint8_t> tile_selected;
  if (compact) {
    tile_selected.assign(tile_count, 0);
    for (int y = row_begin; y < row_end; ++y) {
      for (int x = 0; x < width; ++x) {
        if (selection.slot[static_cast<std::size_t>(y - row_begin) * width + x] == kNotSelected) continue;
        tile_selected[static_cast<std::size_t>(y / tile_size - tile_row0) * tiles_x + x / tile_size] = 1;
      }
    }
  }

  const std::size_t tile_samples = static_cast<std::size_t>(tile_size) * tile_size * samples;
  tbb::enumerable_thread_specific<TileScratch> scratch_pool([tile_samples] {
    TileScratch s;
    s.best_distance2.resize(tile_samples);
    s.inside.resize(tile_samples);
    s.strict_count.resize(tile_samples);
    s.covered.resize(static_cast<std::size_t>(tile_size) * tile_size);
    s.inside_count.resize(static_cast<std::size_t>(tile_size) * tile_size);
    return s;
  });
  std::vector<TileCounts> tile_counts(tile_count);
  const std::size_t sample_stride = static_cast<std::size_t>(samples);

  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, tile_count), [&](const tbb::blocked_range<std::size_t>& r) {
        TileScratch& scratch = scratch_pool.local();
        for (std::size_t tile = r.begin(); tile != r.end(); ++tile) {
          if (compact && !tile_selected[tile]) continue;
          const int tx0 = static_cast<int>(tile % tiles_x) * tile_size;
          const int ty0 = (tile_row0 + static_cast<int>(tile / tiles_x)) * tile_size;
          const int tx1 = std::min(tx0 + tile_size, width) - 1;
          const int ty1 = std::min(ty0 + tile_size, row_end) - 1;
          const auto local_texel = [&](int x, int y) {
            return static_cast<std::size_t>(y - ty0) * tile_size + static_cast<std::size_t>(x - tx0);
          };
          const auto band_texel = [&](int x, int y) {
            return static_cast<std::size_t>(y - row_begin) * width + static_cast<std::size_t>(x);
          };
          const auto selected = [&](int x, int y) {
            return !compact || selection.slot[band_texel(x, y)] != kNotSelected;
          };
          const auto out_texel = [&](int x, int y) {
            return compact ? static_cast<std::size_t>(selection.slot[band_texel(x, y)]) : band_texel(x, y);
          };
          const auto first_sample = [&](int x, int y) { return out_texel(x, y) * sample_stride; };

          std::fill(scratch.best_distance2.begin(), scratch.best_distance2.end(),
                    std::numeric_limits<double>::infinity());
          std::fill(scratch.inside.begin(), scratch.inside.end(), 0);
          std::fill(scratch.strict_count.begin(), scratch.strict_count.end(), 0);
          std::fill(scratch.covered.begin(), scratch.covered.end(), 0);
          std::fill(scratch.inside_count.begin(), scratch.inside_count.end(), 0);

          // Raw pointers: the byte stores below may alias anything reached
          // through a vector, which would reload every data pointer per sample.
          std::uint8_t* const covered = scratch.covered.data();
          std::uint8_t* const inside = scratch.inside.data();
          std::uint8_t* const strict_count = scratch.strict_count.data();
          std::uint8_t* const inside_count = scratch.inside_count.data();
          double* const best_distance2 = scratch.best_distance2.data();
          std::int32_t* const out_triangle = out.triangle.data();
          glm::vec2* const out_bary = out.bary.data();

          // Pass 1: containing triangles, first in order wins; overlap counts.
          for (std::size_t k = tile_begin[tile]; k < tile_begin[tile + 1]; ++k) {
            const std::int32_t t = tile_triangles[k];
            const SetupTriangle& tri = setup[static_cast<std::size_t>(t)];
            const int x_begin = std::max(tri.x0, tx0), x_end = std::min(tri.x1, tx1);
            const int y_begin = std::max(tri.y0, ty0), y_end = std::min(tri.y1, ty1);
            for (int y = y_begin; y <= y_end; ++y) {
              int span_begin, span_end;
              if (!overlap_span(tri, y, x_begin, x_end, span_begin, span_end)) continue;
              for (int x = span_begin; x <= span_end; ++x) {
                if (!selected(x, y)) continue;
                const std::size_t texel = local_texel(x, y);
                covered[texel] = 1;
                const std::size_t local0 = texel * sample_stride;
                const std::size_t global0 = first_sample(x, y);
                if (four_lanes) {
                  for (int g = 0; g < samples; g += 4) {
                    inside_four(tri, t, static_cast<double>(x), static_cast<double>(y), lane_offsets[g / 4],
                                inside + local0 + g, strict_count + local0 + g, inside_count[texel],
                                out_triangle + global0 + g, out_bary + global0 + g);
                  }
                  continue;
                }
                for (int s = 0; s < samples; ++s) {
                  const glm::dvec2 p{x + static_cast<double>(offsets[s].x),
                                     y + static_cast<double>(offsets[s].y)};
                  const double e0 = tri.edge[0](p), e1 = tri.edge[1](p), e2 = tri.edge[2](p);
                  if (!(e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0)) continue;
                  const std::size_t local = local0 + s;
                  if (e0 > tri.strict_threshold && e1 > tri.strict_threshold && e2 > tri.strict_threshold &&
                      strict_count[local] < 2) {
                    ++strict_count[local];
                  }
                  if (!inside[local]) {
                    inside[local] = 1;
                    ++inside_count[texel];
                    out_triangle[global0 + s] = t;
                    out_bary[global0 + s] = inside_bary(e0, e1, e2);
                  }
                }
              }
            }
          }

          // Pass 2, only for texels with samples outside every triangle: the
          // nearest point of the nearest overlapping triangle. Kept apart from
          // pass 1 because it costs three divisions and most outside candidates
          // turn out to lie inside a neighbour.
          for (std::size_t k = tile_begin[tile]; k < tile_begin[tile + 1]; ++k) {
            const std::int32_t t = tile_triangles[k];
            const SetupTriangle& tri = setup[static_cast<std::size_t>(t)];
            const int x_begin = std::max(tri.x0, tx0), x_end = std::min(tri.x1, tx1);
            const int y_begin = std::max(tri.y0, ty0), y_end = std::min(tri.y1, ty1);
            for (int y = y_begin; y <= y_end; ++y) {
              for (int x = x_begin; x <= x_end; ++x) {
                const std::size_t texel = local_texel(x, y);
                if (inside_count[texel] == samples || !selected(x, y) || !box_overlaps(tri, x, y, 1.0))
                  continue;
                const std::size_t local0 = texel * sample_stride;
                const std::size_t global0 = first_sample(x, y);
                for (int s = 0; s < samples; ++s) {
                  const std::size_t local = local0 + s;
                  if (inside[local]) continue;
                  const glm::dvec2 p{x + static_cast<double>(offsets[s].x),
                                     y + static_cast<double>(offsets[s].y)};
                  glm::vec2 b;
                  const double distance2 = nearest_point(tri, p, b);
                  if (distance2 < best_distance2[local]) {
                    best_distance2[local] = distance2;
                    out_triangle[global0 + s] = t;
                    out_bary[global0 + s] = b;
                  }
                }
              }
            }
          }

          std::uint64_t covered_texels = 0;
          for (int y = ty0; y <= ty1; ++y) {
            for (int x = tx0; x <= tx1; ++x) {
              if (!selected(x, y)) continue;
              const std::size_t texel = local_texel(x, y);
              out.coverage[out_texel(x, y)] = covered[texel];
              if (!covered[texel]) {
                // Every sample of a covered texel was written by pass 1 or 2.
                const std::size_t first = first_sample(x, y);
                std::fill_n(out_triangle + first, samples, -1);
                std::fill_n(out_bary + first, samples, glm::vec2(0.0f));
                continue;
              }
              ++covered_texels;
            }
          }
          // Samples are inside a triangle (or strictly inside one) only in
          // covered texels, and the scratch is zero elsewhere: the counts
          // are sums over the whole tile. strict_count is 0, 1 or 2.
          std::uint32_t inside_samples = 0, overlapping = 0;
          for (std::size_t i = 0; i < tile_samples; ++i) {
            inside_samples += inside[i];
            overlapping += strict_count[i] >> 1;
          }
          TileCounts& counts = tile_counts[tile];
          counts.covered_texels = covered_texels;
          counts.border_samples = covered_texels * sample_stride - inside_samples;
          counts.overlapping_samples = overlapping;
        }
      });

  for (const TileCounts& c : tile_counts) {
    stats.covered_texels += c.covered_texels;
    stats.border_samples += c.border_samples;
    stats.overlapping_samples += c.overlapping_samples;
  }
}

}  // namespace

void rasterize(const LowSurface& surface, int width, int height, int samples, TexelSamples& out,
               RasterStats& stats, int row_begin, int row_end) {
  rasterize_impl(surface, width, height, samples, out, stats, row_begin, row_end, false);
}

void rasterize_selected(const LowSurface& surface, int width, int height, int samples, int row_begin,
                        int row_end, const std::uint32_t* texels, std::size_t count, TexelSamples& out,
                        RasterStats& stats, std::vector<std::uint32_t>& slot) {
  NMBAKE_CHECK(row_begin >= 0 && row_begin < row_end && row_end <= height, "row band must lie in the image");
  const std::size_t band_texels =
      static_cast<std::size_t>(width) * static_cast<std::size_t>(row_end - row_begin);
  if (slot.size() != band_texels) slot.assign(band_texels, kNotSelected);
  for (std::size_t i = 0; i < count; ++i) {
    NMBAKE_CHECK(texels[i] < band_texels && (i == 0 || texels[i] > texels[i - 1]),
                 "selected texels lie in the band, ascending");
    slot[texels[i]] = static_cast<std::uint32_t>(i);
  }
  rasterize_impl(surface, width, height, samples, out, stats, row_begin, row_end, false,
                 Selection{slot.data(), count});
  for (std::size_t i = 0; i < count; ++i) slot[texels[i]] = kNotSelected;
}

namespace detail {

void rasterize_per_sample(const LowSurface& surface, int width, int height, int samples, TexelSamples& out,
                          RasterStats& stats, int row_begin, int row_end) {
  rasterize_impl(surface, width, height, samples, out, stats, row_begin, row_end, true);
}

}  // namespace detail

int band_rows(int width, int height, int samples, std::size_t band_samples) {
  if (band_samples == 0) band_samples = std::size_t{1} << 20;
  const std::size_t per_row = static_cast<std::size_t>(width) * static_cast<std::size_t>(samples);
  std::size_t rows = std::max<std::size_t>(1, band_samples / per_row);
  rows = std::max<std::size_t>(kRasterTileSize, rows / kRasterTileSize * kRasterTileSize);
  return static_cast<int>(std::min<std::size_t>(rows, static_cast<std::size_t>(height)));
}

}  // namespace nmbake
