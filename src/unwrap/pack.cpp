// Chart packing with a horizon (skyline), the "Tetris" packing of Lévy,
// Petitjean, Ray and Maillot, "Least Squares Conformal Maps for Automatic
// Texture Atlas Generation" (SIGGRAPH 2002, section 5): each chart's
// footprint is its conservative raster at the atlas resolution, reduced to a
// bottom and a top row per texel column (so charts nest into each other's
// profiles, unlike bounding boxes), dilated by the gutter. Charts are placed
// largest first where their top ends lowest on the current horizon, in 0 or
// 90 degree rotation. The scale is the largest for which everything fits:
// first found by stepping down from the 100%-utilization bound, then refined
// by bisection.
#include <algorithm>
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

constexpr int kEmpty = std::numeric_limits<int>::max();

// Per texel column of the chart: rows [bottom, top) touched by the chart.
struct Footprint {
  std::vector<int> bottom, top;
  int max_top = 0;
  int width() const { return static_cast<int>(bottom.size()); }
};

// y range of the triangle within the column band [x0, x1]: the clipped
// polygon's extreme y lies at a vertex inside the band or where an edge
// crosses x0 or x1.
void band_extent(const glm::dvec2 (&t)[3], double x0, double x1, double& y_min, double& y_max) {
  y_min = std::numeric_limits<double>::infinity();
  y_max = -y_min;
  for (int k = 0; k < 3; ++k) {
    const glm::dvec2 a = t[k], b = t[(k + 1) % 3];
    if (a.x >= x0 && a.x <= x1) y_min = std::min(y_min, a.y), y_max = std::max(y_max, a.y);
    for (double x : {x0, x1}) {
      if ((a.x < x && b.x > x) || (a.x > x && b.x < x)) {
        const double y = a.y + (b.y - a.y) * (x - a.x) / (b.x - a.x);
        y_min = std::min(y_min, y), y_max = std::max(y_max, y);
      }
    }
  }
}

Footprint rasterize(const Chart& chart, double scale, bool rotated) {
  const Placement origin{0, 0, rotated};
  const double w = (rotated ? chart.extent.y : chart.extent.x) * scale;
  Footprint f;
  const int width = static_cast<int>(std::floor(w)) + 1;
  f.bottom.assign(width, kEmpty);
  f.top.assign(width, -kEmpty);
  for (std::size_t i = 0; i < chart.faces.size(); ++i) {
    glm::dvec2 t[3];
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int k = 0; k < 3; ++k) {
      t[k] = chart_to_texel(chart.uv[3 * i + k], chart, origin, scale);
      lo = std::min(lo, t[k].x), hi = std::max(hi, t[k].x);
    }
    // Conservative: every column whose closed band touches the triangle.
    const int c0 = std::max(0, static_cast<int>(std::floor(lo)));
    const int c1 = std::min(width - 1, static_cast<int>(std::floor(hi)));
    for (int c = c0; c <= c1; ++c) {
      double y_min, y_max;
      band_extent(t, c, c + 1.0, y_min, y_max);
      if (!(y_min <= y_max)) continue;
      f.bottom[c] = std::min(f.bottom[c], std::max(0, static_cast<int>(std::floor(y_min))));
      f.top[c] = std::max(f.top[c], static_cast<int>(std::floor(y_max)) + 1);
    }
  }
  for (int c = 0; c < width; ++c)
    if (f.bottom[c] != kEmpty) f.max_top = std::max(f.max_top, f.top[c]);
  return f;
}

// The footprint's bottom profile dilated by the gutter (square structuring
// element), over columns [-gutter, width + gutter).
std::vector<int> dilated_bottom(const Footprint& f, int gutter) {
  const int w = f.width();
  std::vector<int> d(static_cast<std::size_t>(w + 2 * gutter), kEmpty);
  for (int c = 0; c < w; ++c) {
    if (f.bottom[c] == kEmpty) continue;
    for (int k = c; k <= c + 2 * gutter; ++k) d[k] = std::min(d[k], f.bottom[c] - gutter);
  }
  return d;
}

struct Prepared {
  Footprint foot[2];
  std::vector<int> low[2];
};

// One attempt at a given scale: false as soon as a chart does not fit.
bool try_pack(const std::vector<Chart>& charts, const std::vector<std::uint32_t>& order, const PackOptions& options,
              double scale, std::vector<Placement>& placements) {
  const int rotations = options.rotate ? 2 : 1;
  const int resolution = options.resolution;
  // Quick reject: a chart wider and taller than the atlas.
  for (const Chart& c : charts) {
    const double lo = std::min(c.extent.x, c.extent.y) * scale, hi = std::max(c.extent.x, c.extent.y) * scale;
    if (lo + 1.0 > resolution || (!options.rotate && hi + 1.0 > resolution)) return false;
  }
  std::vector<Prepared> prepared(charts.size());
  tbb::parallel_for(std::size_t{0}, charts.size(), [&](std::size_t i) {
    for (int r = 0; r < rotations; ++r) {
      prepared[i].foot[r] = rasterize(charts[i], scale, r == 1);
      prepared[i].low[r] = dilated_bottom(prepared[i].foot[r], options.gutter);
    }
  });
  std::vector<int> horizon(static_cast<std::size_t>(resolution), 0);
  placements.assign(charts.size(), Placement{});
  const int g = options.gutter;
  for (std::uint32_t index : order) {
    const Prepared& p = prepared[index];
    int best_top = resolution + 1, best_x = -1, best_y = 0, best_r = 0;
    for (int r = 0; r < rotations; ++r) {
      const Footprint& f = p.foot[r];
      const std::vector<int>& low = p.low[r];
      const int w = f.width();
      for (int x = 0; x + w <= resolution; ++x) {
        // Lowest y with the dilated bottom above the horizon everywhere.
        const int limit = best_top - f.max_top;  // y must stay below this to win
        int y = 0;
        const int c_begin = std::max(-g, -x), c_end = std::min(w + g, resolution - x);
        for (int c = c_begin; c < c_end && y < limit; ++c) {
          const int b = low[c + g];
          if (b != kEmpty) y = std::max(y, horizon[x + c] - b);
        }
        if (y >= limit) continue;
        best_top = y + f.max_top;
        best_x = x, best_y = y, best_r = r;
      }
    }
    if (best_x < 0 || best_top > resolution) return false;
    const Footprint& f = p.foot[best_r];
    for (int c = 0; c < f.width(); ++c)
      if (f.bottom[c] != kEmpty) horizon[best_x + c] = std::max(horizon[best_x + c], best_y + f.top[c]);
    placements[index] = {best_x, best_y, best_r == 1};
  }
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

}  // namespace nmbake::unwrap_detail
