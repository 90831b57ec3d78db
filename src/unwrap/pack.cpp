// Chart packing into a texel bitmap, as in xatlas's bitmap packer (after the
// chart-packing step of Lévy, Petitjean, Ray and Maillot, "Least Squares
// Conformal Maps for Automatic Texture Atlas Generation", SIGGRAPH 2002,
// which packs the charts' rasters rather than their boxes): each chart is
// rasterized conservatively at the atlas resolution and dilated by the
// gutter (square structuring element); it may go wherever that dilated
// shape covers no occupied texel, so charts interlock. Charts are placed
// one by one in a heuristic's order, each in whichever of its four 90-degree
// turns lands lowest (by the heuristic's rule) at its lowest-then-leftmost
// free position; several heuristics run per attempt and the first that fits
// wins. The scale is the largest for which everything fits: searched on a
// quarter-size atlas, then bracketed and bisected at full size, then probed
// a little above the edge (greedy packing is not monotone in the scale).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>

#include "unwrap/unwrap_internal.hpp"

namespace nmbake::unwrap_detail {

glm::dvec2 chart_to_texel(const glm::vec2& uv, const Chart& chart, const Placement& p, double scale) {
  const glm::dvec2 q = glm::dvec2(uv) * scale;
  const glm::dvec2 e = glm::dvec2(chart.extent) * scale;
  // Turns 2 and 3 reflect turns 0 and 1 through the centre of the
  // footprint's box, whose sides are whole texels (see rasterize()).
  const glm::dvec2 box(std::floor(e.x) + 1.0, std::floor(e.y) + 1.0);
  glm::dvec2 t;
  switch (p.turns & 3) {
    case 1:
      t = {e.y - q.y, q.x};
      break;
    case 2:
      t = {box.x - q.x, box.y - q.y};
      break;
    case 3:
      t = {box.y - e.y + q.y, box.x - q.x};
      break;
    default:
      t = q;
      break;
  }
  return t + glm::dvec2(p.x, p.y);
}

namespace {

constexpr std::size_t kHeuristicCount = 6;

// A bit per texel, rows of 64-bit words; bit x of a row is texel column x.
class Bitmap {
 public:
  Bitmap(int width, int height)
      : width_(width), words_((width + 63) / 64 + 1), bits_(static_cast<std::size_t>(words_) * height, 0) {}
  int width() const { return width_; }
  void clear_row(int y) { std::fill_n(&bits_[static_cast<std::size_t>(y) * words_], words_, 0); }
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
  // Row y |= row `from_y` of `other` (same width).
  void or_row(const Bitmap& other, int from_y, int y) {
    const std::uint64_t* src = &other.bits_[static_cast<std::size_t>(from_y) * words_];
    std::uint64_t* dst = &bits_[static_cast<std::size_t>(y) * words_];
    for (int w = 0; w < words_; ++w) dst[w] |= src[w];
  }
  // The runs of set bits in row y, shifted by `offset`.
  void append_runs(int y, int offset, std::vector<std::pair<int, int>>& out) const {
    for (int x = next(0, y, true); x < width_;) {
      const int end = next(x, y, false);
      out.emplace_back(x + offset, end - 1 + offset);
      x = next(end, y, true);
    }
  }
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

using Runs = std::vector<std::pair<int, int>>;  // closed column ranges, sorted, disjoint, not touching

// A chart's conservative raster at one scale and turn: the texels it
// occupies (`spans`, per row) and the same set dilated by the gutter with a
// square structuring element (`keep_out`, rows [-gutter, height + gutter)),
// which must be free of every other chart's texels. Using the exact dilated
// shape, not row hulls, lets charts interlock.
struct Footprint {
  int width = 0, height = 0;
  std::vector<Runs> spans;
  std::vector<Runs> keep_out;
  int longest_row = 0, longest_length = 0;  // the keep-out's longest run
  // Per keep-out row, the free run it needs in the atlas row: its longest
  // run less the gutter on both sides (which may hang over the atlas border).
  std::vector<int> needed;
  // Keep-out rows in the order first_fit() tests them: every 16th row, then
  // the rows halfway between, and so on, so a blocker a few rows tall is
  // found after a few tests rather than after scanning from the bottom.
  std::vector<int> row_order;
};

std::vector<int> spread_order(int rows) {
  std::vector<int> order;
  order.reserve(rows);
  std::vector<char> taken(rows, 0);
  for (int stride = 16; stride >= 1; stride /= 2)
    for (int d = 0; d < rows; d += stride)
      if (!taken[d]) taken[d] = 1, order.push_back(d);
  return order;
}

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

Footprint rasterize(const Chart& chart, double scale, int turns, int gutter) {
  const Placement origin{0, 0, turns};
  const bool odd = (turns & 1) != 0;
  Footprint f;
  f.width = static_cast<int>(std::floor((odd ? chart.extent.y : chart.extent.x) * scale)) + 1;
  f.height = static_cast<int>(std::floor((odd ? chart.extent.x : chart.extent.y) * scale)) + 1;
  // Texels in a local bitmap with a gutter-wide margin, so the dilation fits.
  Bitmap raw(f.width + 2 * gutter, f.height);
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
      raw.set(a + gutter, b + gutter, r);
    }
  }
  // Square dilation: widen every run by the gutter, then OR the 2 * gutter + 1
  // rows around each row.
  Bitmap wide(raw.width(), f.height);
  f.spans.resize(f.height);
  for (int r = 0; r < f.height; ++r) {
    raw.append_runs(r, -gutter, f.spans[r]);
    for (const auto& [a, b] : f.spans[r]) wide.set(a, b + 2 * gutter, r);
  }
  Bitmap dilated(raw.width(), 1);
  f.keep_out.resize(static_cast<std::size_t>(f.height + 2 * gutter));
  for (int d = 0; d < static_cast<int>(f.keep_out.size()); ++d) {
    dilated.clear_row(0);
    for (int r = std::max(0, d - 2 * gutter); r <= std::min(f.height - 1, d); ++r) dilated.or_row(wide, r, 0);
    dilated.append_runs(0, -gutter, f.keep_out[d]);
    for (const auto& [a, b] : f.keep_out[d])
      if (b - a + 1 > f.longest_length) f.longest_length = b - a + 1, f.longest_row = d;
  }
  f.needed.resize(f.keep_out.size());
  for (std::size_t d = 0; d < f.keep_out.size(); ++d) {
    int longest = 0;
    for (const auto& [a, b] : f.keep_out[d]) longest = std::max(longest, b - a + 1);
    f.needed[d] = std::max(0, longest - 2 * gutter);
  }
  f.row_order = spread_order(static_cast<int>(f.keep_out.size()));
  return f;
}

// The footprint turned by a further 180 degrees, about the centre of its box.
Footprint reflected(const Footprint& f) {
  Footprint g;
  g.width = f.width, g.height = f.height;
  auto flip = [&](const std::vector<Runs>& rows, std::vector<Runs>& out) {
    const int n = static_cast<int>(rows.size());
    out.resize(rows.size());
    for (int r = 0; r < n; ++r)
      for (auto it = rows[r].rbegin(); it != rows[r].rend(); ++it)
        out[n - 1 - r].emplace_back(f.width - 1 - it->second, f.width - 1 - it->first);
  };
  flip(f.spans, g.spans);
  flip(f.keep_out, g.keep_out);
  g.longest_length = f.longest_length;
  g.needed.assign(f.needed.rbegin(), f.needed.rend());
  g.longest_row = static_cast<int>(f.keep_out.size()) - 1 - f.longest_row;
  g.row_order = f.row_order;
  return g;
}

// Lowest row, then leftmost column, where the footprint's keep-out region
// covers no occupied texel; false when there is none below y_limit.
bool first_fit(const Bitmap& atlas, const std::vector<int>& free_run, const Footprint& f, int gutter,
               int y_limit, int& best_x, int& best_y) {
  const int size = atlas.width();
  const int rows = static_cast<int>(f.keep_out.size());
  // Quick reject of a row: some keep-out row needs a longer free run than
  // the atlas row has (the row that rejected last is tried first).
  int reject_row = f.longest_row;
  auto too_narrow = [&](int y) {
    const int first = std::max(0, gutter - y), last = std::min(rows, size - y + gutter);
    if (reject_row >= first && reject_row < last && free_run[y + reject_row - gutter] < f.needed[reject_row])
      return true;
    for (int d = first; d < last; ++d) {
      if (free_run[y + d - gutter] < f.needed[d]) {
        reject_row = d;
        return true;
      }
    }
    return false;
  };
  for (int y = 0; y + f.height <= size && y < y_limit; ++y) {
    if (too_narrow(y)) continue;
    int x = 0;
    int first_row = f.longest_row;  // the row that blocked last is tried first
    while (x + f.width <= size) {
      int next_x = -1;
      for (int i = -1; i < rows && next_x < 0; ++i) {
        const int d = i < 0 ? first_row : f.row_order[i];
        if (i >= 0 && d == first_row) continue;
        const int row = y + d - gutter;
        if (row < 0 || row >= size) continue;
        for (const auto& [lo, hi] : f.keep_out[d]) {
          const int a = std::max(0, x + lo), b = std::min(size - 1, x + hi);
          if (a > b) continue;
          const int blocked = atlas.next(a, row, true);
          if (blocked > b) continue;
          // Every shift that leaves this run's start before the end of the
          // blocker's occupied stretch still covers an occupied texel.
          next_x = std::max(x + 1, atlas.next(blocked, row, false) - lo);
          first_row = d;
          break;
        }
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

// Among the four turns' lowest-then-leftmost positions, the one whose
// centre is lowest (then the leftmost) wins: 2 * y + height_weight * height
// is minimised (height_weight 0: lowest bottom, 2: lowest top). Places
// every chart (footprints prepared at one scale) in `order`; false as soon
// as one does not fit, or once `stop` returns true (checked per chart).
template <class Stop>
bool place_all(const std::vector<std::array<Footprint, 4>>& prepared, const std::vector<std::uint32_t>& order,
               long height_weight, int turn_count, int size, int gutter, std::vector<Placement>& placements,
               Stop&& stop) {
  Bitmap atlas(size, size);
  std::vector<int> free_run(static_cast<std::size_t>(size), size);  // longest free run per row
  placements.assign(prepared.size(), Placement{});
  constexpr long kNone = std::numeric_limits<long>::max();
  for (std::uint32_t index : order) {
    if (stop()) return false;
    int best_x = -1, best_y = 0, best_turns = 0;
    long best_key = kNone;
    for (int turns = 0; turns < turn_count; ++turns) {
      const Footprint& f = prepared[index][turns];
      if (f.width > size || f.height > size) continue;
      // Only rows where the key can still be beaten (or tied) are searched.
      const long limit = best_key == kNone ? size : (best_key - height_weight * f.height) / 2 + 1;
      if (limit <= 0) continue;
      int x, y;
      if (!first_fit(atlas, free_run, f, gutter, static_cast<int>(std::min<long>(limit, size)), x, y))
        continue;
      const long key = 2L * y + height_weight * f.height;
      if (key < best_key || (key == best_key && x < best_x)) {
        best_key = key;
        best_x = x, best_y = y, best_turns = turns;
      }
    }
    if (best_x < 0) return false;
    const Footprint& f = prepared[index][best_turns];
    for (int r = 0; r < f.height; ++r) {
      if (f.spans[r].empty()) continue;
      for (const auto& [a, b] : f.spans[r]) atlas.set(best_x + a, best_x + b, best_y + r);
      free_run[best_y + r] = atlas.longest_free_run(best_y + r);
    }
    placements[index] = {best_x, best_y, best_turns};
  }
  return true;
}

// Greedy packing swings by several points of utilization with the chart
// order and the placement rule, differently on every mesh, so each attempt
// tries several and keeps the first (in this list) that fits.
struct Heuristic {
  enum class Order { box_area, longer_side, shorter_side, half_perimeter, chart_area } order;
  int height_weight;  // see place_all()
};
constexpr std::array<Heuristic, kHeuristicCount> kHeuristics = {{
    {Heuristic::Order::box_area, 1},
    {Heuristic::Order::shorter_side, 1},
    {Heuristic::Order::chart_area, 2},
    {Heuristic::Order::longer_side, 1},
    {Heuristic::Order::half_perimeter, 1},
    {Heuristic::Order::box_area, 0},
}};

using Orders = std::array<std::vector<std::uint32_t>, kHeuristicCount>;

// Each chart's UV area (the sum of its triangles').
std::vector<double> chart_areas(const std::vector<Chart>& charts) {
  std::vector<double> area(charts.size(), 0.0);
  for (std::size_t k = 0; k < charts.size(); ++k) {
    const Chart& c = charts[k];
    for (std::size_t i = 0; i < c.faces.size(); ++i) {
      const glm::dvec2 a = c.uv[3 * i], b = c.uv[3 * i + 1], d = c.uv[3 * i + 2];
      area[k] += 0.5 * std::abs((b.x - a.x) * (d.y - a.y) - (b.y - a.y) * (d.x - a.x));
    }
  }
  return area;
}

// The chart orders of kHeuristics: by decreasing key, chart order on ties.
Orders chart_orders(const std::vector<Chart>& charts, const std::vector<double>& area) {
  Orders orders;
  for (std::size_t h = 0; h < kHeuristicCount; ++h) {
    auto key = [&](std::uint32_t i) -> double {
      const double w = charts[i].extent.x, e = charts[i].extent.y;
      switch (kHeuristics[h].order) {
        case Heuristic::Order::longer_side:
          return std::max(w, e);
        case Heuristic::Order::shorter_side:
          return std::min(w, e);
        case Heuristic::Order::half_perimeter:
          return w + e;
        case Heuristic::Order::chart_area:
          return area[i];
        case Heuristic::Order::box_area:
          break;
      }
      return w * e;
    };
    std::vector<std::uint32_t>& order = orders[h];
    order.resize(charts.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return key(a) > key(b); });
  }
  return orders;
}

// One attempt at a given scale: false when no heuristic fits every chart.
// The heuristics run in parallel; the first in kHeuristics that fits wins,
// whatever the thread count.
bool try_pack(const std::vector<Chart>& charts, const Orders& orders, const PackOptions& options,
              double scale, std::vector<Placement>& placements) {
  const int turn_count = options.rotate ? 4 : 1;
  const int size = options.resolution;
  for (const Chart& c : charts) {
    const double lo = std::min(c.extent.x, c.extent.y) * scale, hi = std::max(c.extent.x, c.extent.y) * scale;
    // A footprint is floor(extent * scale) + 1 texels a side and must lie
    // inside the atlas in every turn, so its longer side must be below
    // `size` too: checked before rasterize() allocates a bitmap that wide
    // (a needle chart to one far vertex asked for gigabytes).
    if (lo + 1.0 > size || !(hi < size)) return false;
  }
  std::vector<std::array<Footprint, 4>> prepared(charts.size());
  // Turns 2 and 3 are the reflections of turns 0 and 1.
  const int rastered = std::min(turn_count, 2);
  tbb::parallel_for(std::size_t{0}, charts.size() * rastered, [&](std::size_t k) {
    const std::size_t i = k / rastered;
    const int turns = static_cast<int>(k % rastered);
    prepared[i][turns] = rasterize(charts[i], scale, turns, options.gutter);
    if (turn_count == 4) prepared[i][turns + 2] = reflected(prepared[i][turns]);
  });
  std::array<std::vector<Placement>, kHeuristicCount> tried;
  std::array<char, kHeuristicCount> fits{};
  // A heuristic stops as soon as an earlier one has fitted: it could not win.
  std::atomic<std::size_t> first_fitted{kHeuristicCount};
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, kHeuristicCount, 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t h = range.begin(); h != range.end(); ++h) {
          auto stop = [&] { return first_fitted.load(std::memory_order_relaxed) < h; };
          fits[h] = place_all(prepared, orders[h], kHeuristics[h].height_weight, turn_count, size,
                              options.gutter, tried[h], stop);
          if (!fits[h]) continue;
          std::size_t seen = first_fitted.load();
          while (h < seen && !first_fitted.compare_exchange_weak(seen, h)) {
          }
        }
      },
      tbb::simple_partitioner());
  for (std::size_t h = 0; h < kHeuristicCount; ++h) {
    if (fits[h]) {
      placements = std::move(tried[h]);
      return true;
    }
  }
  return false;
}

// Largest scale found by stepping down from `upper` and bisecting.
bool search_scale(const std::vector<Chart>& charts, const Orders& order, const PackOptions& options,
                  double upper, PackResult& result) {
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
  const std::vector<double> areas = chart_areas(charts);
  double area = 0.0;
  for (double a : areas) area += a;
  const Orders order = chart_orders(charts, areas);

  // At this scale the charts' own area fills the atlas: nothing larger fits.
  const double upper = area > 0.0 ? options.resolution / std::sqrt(area) : 1.0;
  // The search runs on an atlas a quarter the size (gutter scaled too), where
  // an attempt costs ~1/16; the full-size atlas then brackets the scale near
  // the coarse one and bisects.
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
  // Bracket in 2% steps, then bisect to `kPrecision` (greedy packing is not
  // monotone in the scale, so this finds a local edge of the feasible scales).
  constexpr double kStep = 1.02, kPrecision = 1.005;
  const double start = coarse_result.scale * kCoarse;
  double fits = 0.0, fails = 0.0;
  auto attempt = [&](double s) {
    ++result.attempts;
    if (!try_pack(charts, order, options, s, placements)) return false;
    result.placements = placements;  // always the placements of `fits`
    return true;
  };
  if (attempt(start)) {
    fits = start;
    for (int i = 0; i < 8 && fails == 0.0; ++i) {
      const double up = fits * kStep;
      if (attempt(up))
        fits = up;
      else
        fails = up;
    }
  } else {
    fails = start;
    for (int i = 0; i < 24 && fits == 0.0; ++i) {
      const double down = fails / kStep;
      if (attempt(down))
        fits = down;
      else
        fails = down;
    }
    if (fits == 0.0) return search_scale(charts, order, options, upper, result);
  }
  if (fails > 0.0) {
    while (fails / fits > kPrecision) {
      const double mid = std::sqrt(fits * fails);
      if (attempt(mid))
        fits = mid;
      else
        fails = mid;
    }
  }
  // Greedy packing is not monotone in the scale: a slightly larger scale
  // often fits where the bisection's failing one did not (spider: +0.8%
  // scale, +1.1 points of utilization). Probe a few scales above the edge,
  // in parallel; the largest that fits wins, and the probing repeats from it.
  constexpr int kProbes = 6, kProbeRounds = 3;
  constexpr double kProbeStep = 0.004;
  for (int round = 0; round < kProbeRounds; ++round) {
    std::array<std::vector<Placement>, kProbes> probed;
    std::array<char, kProbes> probe_fits{};
    tbb::parallel_for(0, kProbes, [&](int k) {
      probe_fits[k] = try_pack(charts, order, options, fits * (1.0 + kProbeStep * (k + 1)), probed[k]);
    });
    result.attempts += kProbes;
    int best = -1;
    for (int k = 0; k < kProbes; ++k)
      if (probe_fits[k]) best = k;
    if (best < 0) break;
    fits *= 1.0 + kProbeStep * (best + 1);
    result.placements = std::move(probed[best]);
  }
  result.scale = fits;
  return true;
}

}  // namespace nmbake::unwrap_detail
