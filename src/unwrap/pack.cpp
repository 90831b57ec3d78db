// Chart packing into a texel bitmap, as in xatlas's bitmap packer (after the
// chart-packing step of Lévy, Petitjean, Ray and Maillot, "Least Squares
// Conformal Maps for Automatic Texture Atlas Generation", SIGGRAPH 2002,
// which packs the charts' rasters rather than their boxes): each chart is
// rasterized conservatively at the atlas resolution; it may go wherever the
// hull of each of its rows, dilated by the gutter, covers no occupied texel
// (so small charts can fall into the concavities of large ones). Charts are
// placed largest first at the lowest, then leftmost, free position, in 0 or
// 90 degree rotation (whichever ends lower). The scale is the largest for which everything fits:
// first found by stepping down from the 100%-utilization bound, then refined
// by bisection.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>

#include <tbb/parallel_for.h>

#include "unwrap/unwrap_internal.hpp"

namespace nmbake::unwrap_detail {

glm::dvec2 chart_to_texel(const glm::vec2& uv, const Chart& chart, const Placement& p, double scale) {
  glm::dvec2 q = glm::dvec2(uv) * scale;
  if (p.rotated) q = {static_cast<double>(chart.extent.y) * scale - q.y, q.x};
  return q + glm::dvec2(p.x, p.y);
}

namespace {

// A bit per texel, rows of 64-bit words; bit x of a row is texel column x.
class Bitmap {
 public:
  Bitmap(int width, int height)
      : width_(width), words_((width + 63) / 64 + 1), bits_(static_cast<std::size_t>(words_) * height, 0) {}
  int width() const { return width_; }
  void set(int x0, int x1, int y) {  // columns [x0, x1]
    std::uint64_t* row = &bits_[static_cast<std::size_t>(y) * words_];
    for (int x = x0; x <= x1;) {
      const int w = x >> 6, b = x & 63;
      const int n = std::min(64 - b, x1 - x + 1);
      row[w] |= (n == 64 ? ~0ull : ((1ull << n) - 1)) << b;
      x += n;
    }
  }
  // Longest run of clear bits in row y.
  int longest_free_run(int y) const {
    int best = 0;
    for (int x = next(0, y, false); x < width_;) {
      const int end = next(x, y, true);
      best = std::max(best, end - x);
      x = next(end, y, false);
    }
    return best;
  }
  bool get(int x, int y) const { return (bits_[static_cast<std::size_t>(y) * words_ + (x >> 6)] >> (x & 63)) & 1u; }
  // First column >= x in row y whose bit equals `value`, or width() if none.
  int next(int x, int y, bool value) const {
    if (x >= width_) return width_;
    const std::uint64_t* row = &bits_[static_cast<std::size_t>(y) * words_];
    int w = x >> 6;
    std::uint64_t word = (value ? row[w] : ~row[w]) & (~0ull << (x & 63));
    while (word == 0) {
      if (++w >= words_ - 1) return width_;
      word = value ? row[w] : ~row[w];
    }
    return std::min(width_, w * 64 + __builtin_ctzll(word));
  }

 private:
  int width_, words_;
  std::vector<std::uint64_t> bits_;
};

// A chart's conservative raster at one scale and rotation: exact row spans
// (what it occupies) and, per row of the gutter-dilated footprint, the
// hull [lo, hi] that must be free to place it (concavities count as full).
struct Footprint {
  int width = 0, height = 0;
  std::vector<std::vector<std::pair<int, int>>> spans;  // per row, closed column ranges (may overlap)
  std::vector<int> lo, hi;                              // dilated rows [-gutter, height + gutter)
  int widest_row = 0;                                   // index into lo/hi of the widest hull
};

// x range of the triangle within the row band [y0, y1]: the clipped
// polygon's extreme x lies at a vertex inside the band or where an edge
// crosses y0 or y1.
void band_extent(const glm::dvec2 (&t)[3], double y0, double y1, double& x_min, double& x_max) {
  x_min = std::numeric_limits<double>::infinity();
  x_max = -x_min;
  for (int k = 0; k < 3; ++k) {
    const glm::dvec2 a = t[k], b = t[(k + 1) % 3];
    if (a.y >= y0 && a.y <= y1) x_min = std::min(x_min, a.x), x_max = std::max(x_max, a.x);
    for (double y : {y0, y1}) {
      if ((a.y < y && b.y > y) || (a.y > y && b.y < y)) {
        const double x = a.x + (b.x - a.x) * (y - a.y) / (b.y - a.y);
        x_min = std::min(x_min, x), x_max = std::max(x_max, x);
      }
    }
  }
}

constexpr int kNone = std::numeric_limits<int>::max();

Footprint rasterize(const Chart& chart, double scale, bool rotated, int gutter) {
  const Placement origin{0, 0, rotated};
  Footprint f;
  f.width = static_cast<int>(std::floor((rotated ? chart.extent.y : chart.extent.x) * scale)) + 1;
  f.height = static_cast<int>(std::floor((rotated ? chart.extent.x : chart.extent.y) * scale)) + 1;
  f.spans.resize(f.height);
  std::vector<int> row_lo(f.height, kNone), row_hi(f.height, -kNone);
  for (std::size_t i = 0; i < chart.faces.size(); ++i) {
    glm::dvec2 t[3];
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int k = 0; k < 3; ++k) {
      t[k] = chart_to_texel(chart.uv[3 * i + k], chart, origin, scale);
      lo = std::min(lo, t[k].y), hi = std::max(hi, t[k].y);
    }
    // Conservative: every texel whose closed square touches the triangle.
    const int r0 = std::max(0, static_cast<int>(std::floor(lo)));
    const int r1 = std::min(f.height - 1, static_cast<int>(std::floor(hi)));
    for (int r = r0; r <= r1; ++r) {
      double x_min, x_max;
      band_extent(t, r, r + 1.0, x_min, x_max);
      if (!(x_min <= x_max)) continue;
      const int a = std::clamp(static_cast<int>(std::floor(x_min)), 0, f.width - 1);
      const int b = std::clamp(static_cast<int>(std::floor(x_max)), 0, f.width - 1);
      f.spans[r].emplace_back(a, b);
      row_lo[r] = std::min(row_lo[r], a);
      row_hi[r] = std::max(row_hi[r], b);
    }
  }
  // Dilate the row hulls by the gutter (square structuring element).
  f.lo.assign(static_cast<std::size_t>(f.height + 2 * gutter), kNone);
  f.hi.assign(f.lo.size(), -kNone);
  for (int r = 0; r < f.height; ++r) {
    if (row_lo[r] == kNone) continue;
    for (int d = r; d <= r + 2 * gutter; ++d) {
      f.lo[d] = std::min(f.lo[d], row_lo[r] - gutter);
      f.hi[d] = std::max(f.hi[d], row_hi[r] + gutter);
    }
  }
  for (int d = 0; d < static_cast<int>(f.lo.size()); ++d)
    if (f.lo[d] != kNone && f.hi[d] - f.lo[d] > f.hi[f.widest_row] - f.lo[f.widest_row]) f.widest_row = d;
  return f;
}

// Lowest row, then leftmost column, where the footprint's dilated hull
// avoids every occupied texel; false when there is none.
bool first_fit(const Bitmap& atlas, const std::vector<int>& free_run, const Footprint& f, int gutter, int y_limit,
               int& best_x, int& best_y) {
  const int size = atlas.width();
  const int widest = f.hi[f.widest_row] - f.lo[f.widest_row] + 1;
  for (int y = 0; y + f.height <= size && y < y_limit; ++y) {
    // Quick reject: the widest row of the hull needs a free run that long
    // (clipped at the atlas border, where the gutter may hang over).
    const int widest_at = y + f.widest_row - gutter;
    if (widest_at >= 0 && widest_at < size && free_run[widest_at] < std::min(widest, f.width)) continue;
    int x = 0;
    int first_row = f.widest_row;  // the row that blocked last is tried first
    const int rows = static_cast<int>(f.lo.size());
    while (x + f.width <= size) {
      int next_x = -1;
      for (int i = 0; i < rows; ++i) {
        const int d = i == 0 ? first_row : (i <= first_row ? i - 1 : i);
        if (f.lo[d] == kNone) continue;
        const int row = y + d - gutter;
        if (row < 0 || row >= size) continue;
        const int a = std::max(0, x + f.lo[d]), b = std::min(size - 1, x + f.hi[d]);
        const int blocked = atlas.next(a, row, true);
        if (blocked > b) continue;
        // Move right until this row's hull starts after the next free texel
        // at or after the blocker.
        const int free_at = atlas.next(blocked, row, false);
        next_x = std::max(x + 1, free_at - f.lo[d]);
        first_row = d;
        break;
      }
      if (next_x < 0) {
        best_x = x, best_y = y;
        return true;
      }
      x = next_x;
    }
  }
  return false;
}

// One attempt at a given scale: false as soon as a chart does not fit.
bool try_pack(const std::vector<Chart>& charts, const std::vector<std::uint32_t>& order, const PackOptions& options,
              double scale, std::vector<Placement>& placements) {
  const int rotations = options.rotate ? 2 : 1;
  const int size = options.resolution;
  for (const Chart& c : charts) {
    const double lo = std::min(c.extent.x, c.extent.y) * scale, hi = std::max(c.extent.x, c.extent.y) * scale;
    if (lo + 1.0 > size || (!options.rotate && hi + 1.0 > size)) return false;
  }
  std::vector<std::array<Footprint, 2>> prepared(charts.size());
  tbb::parallel_for(std::size_t{0}, charts.size(), [&](std::size_t i) {
    for (int r = 0; r < rotations; ++r) prepared[i][r] = rasterize(charts[i], scale, r == 1, options.gutter);
  });
  Bitmap atlas(size, size);
  std::vector<int> free_run(static_cast<std::size_t>(size), size);  // longest free run per row
  placements.assign(charts.size(), Placement{});
  for (std::uint32_t index : order) {
    int best_x = -1, best_y = 0, best_r = 0, best_top = size + 1;
    for (int r = 0; r < rotations; ++r) {
      const Footprint& f = prepared[index][r];
      int x, y;
      // Only a placement whose top ends lower can win.
      if (first_fit(atlas, free_run, f, options.gutter, best_top - f.height, x, y) && y + f.height < best_top) {
        best_top = y + f.height;
        best_x = x, best_y = y, best_r = r;
      }
    }
    if (best_x < 0) return false;
    const Footprint& f = prepared[index][best_r];
    for (int r = 0; r < f.height; ++r)
    {
      for (const auto& [a, b] : f.spans[r]) atlas.set(best_x + a, best_x + b, best_y + r);
      free_run[best_y + r] = atlas.longest_free_run(best_y + r);
    }
    placements[index] = {best_x, best_y, best_r == 1};
  }
  return true;
}

}  // namespace

namespace {

// Largest scale found by stepping down from `start` and bisecting.
bool search_scale(const std::vector<Chart>& charts, const std::vector<std::uint32_t>& order,
                  const PackOptions& options, double upper, PackResult& result) {
  double fits = 0.0, fails = upper * 1.0001;
  std::vector<Placement> placements;
  for (double s = upper * 0.95; s > upper * 1e-4; s *= 0.85) {
    ++result.attempts;
    if (try_pack(charts, order, options, s, placements)) {
      fits = s;
      result.placements = placements;
      break;
    }
    fails = s;
  }
  if (fits == 0.0) return false;
  for (int step = 0; step < options.search_steps; ++step) {
    const double s = std::sqrt(fits * fails);
    ++result.attempts;
    if (try_pack(charts, order, options, s, placements)) {
      fits = s;
      result.placements = placements;
    } else {
      fails = s;
    }
  }
  result.scale = fits;
  return true;
}

}  // namespace

bool pack_charts(const std::vector<Chart>& charts, const PackOptions& options, PackResult& result) {
  result = PackResult{};
  if (charts.empty()) return true;
  double area = 0.0;
  for (const Chart& c : charts)
    for (std::size_t i = 0; i < c.faces.size(); ++i) {
      const glm::dvec2 a = c.uv[3 * i], b = c.uv[3 * i + 1], d = c.uv[3 * i + 2];
      area += 0.5 * std::abs((b.x - a.x) * (d.y - a.y) - (b.y - a.y) * (d.x - a.x));
    }
  // Largest first (by the longer side, then area), chart order on ties.
  std::vector<std::uint32_t> order(charts.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    const float la = std::max(charts[a].extent.x, charts[a].extent.y);
    const float lb = std::max(charts[b].extent.x, charts[b].extent.y);
    if (la != lb) return la > lb;
    return charts[a].extent.x * charts[a].extent.y > charts[b].extent.x * charts[b].extent.y;
  });
  // At this scale the charts' own area fills the atlas: nothing larger fits.
  const double upper = area > 0.0 ? options.resolution / std::sqrt(area) : 1.0;
  // The search runs on an atlas a quarter the size (gutter scaled too), where
  // an attempt costs ~1/16; the full-size atlas then only confirms and nudges
  // the scale up (a coarse raster is more conservative, so it rarely
  // overestimates).
  constexpr int kCoarse = 4;
  if (options.resolution < 256) return search_scale(charts, order, options, upper, result);
  PackOptions coarse = options;
  coarse.resolution = options.resolution / kCoarse;
  coarse.gutter = (options.gutter + kCoarse - 1) / kCoarse;
  PackResult coarse_result;
  if (!search_scale(charts, order, coarse, upper / kCoarse, coarse_result)) {
    return search_scale(charts, order, options, upper, result);
  }
  result.attempts = coarse_result.attempts;
  std::vector<Placement> placements;
  double s = coarse_result.scale * kCoarse;
  double fits = 0.0;
  for (int i = 0; i < 24 && fits == 0.0; ++i, s *= 0.97) {
    ++result.attempts;
    if (try_pack(charts, order, options, s, placements)) {
      fits = s;
      result.placements = placements;
    }
  }
  if (fits == 0.0) return search_scale(charts, order, options, upper, result);
  for (int i = 0; i < 3; ++i) {
    const double up = fits * 1.03;
    ++result.attempts;
    if (!try_pack(charts, order, options, up, placements)) break;
    fits = up;
    result.placements = placements;
  }
  result.scale = fits;
  return true;
}

}  // namespace nmbake::unwrap_detail
