#include "nmbake/raster.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/vec2.hpp>
#include <limits>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include "nmbake/surface.hpp"

namespace {

using nmbake::LowSurface;
using nmbake::RasterStats;
using nmbake::TexelSamples;

LowSurface surface_from_uvs(const std::vector<glm::vec2>& corner_uvs) {
  LowSurface s;
  s.uv = corner_uvs;
  return s;
}

std::size_t sample_index(const TexelSamples& ts, int x, int y, int s) {
  return (static_cast<std::size_t>(y) * ts.width + x) * ts.samples + s;
}

// The sample's position in pixel space (px = u * W, py = (1 - v) * H).
glm::dvec2 sample_pixel(int x, int y, glm::vec2 o) { return {x + double(o.x), y + double(o.y)}; }

glm::dvec2 to_pixel(glm::vec2 uv, int w, int h) { return {double(uv.x) * w, (1.0 - double(uv.y)) * h}; }

// Pixel-space point of triangle t at barycentrics b (weights of corners 1, 2).
glm::dvec2 bary_point(const LowSurface& s, int t, glm::vec2 b, int w, int h) {
  const glm::dvec2 p0 = to_pixel(s.uv[3 * t], w, h);
  const glm::dvec2 p1 = to_pixel(s.uv[3 * t + 1], w, h);
  const glm::dvec2 p2 = to_pixel(s.uv[3 * t + 2], w, h);
  return p0 + double(b.x) * (p1 - p0) + double(b.y) * (p2 - p0);
}

// Barycentric weights (w0, w1, w2) of p in triangle t, pixel space.
void weights(const LowSurface& s, int t, glm::dvec2 p, int w, int h, double out[3]) {
  const glm::dvec2 a = to_pixel(s.uv[3 * t], w, h);
  const glm::dvec2 b = to_pixel(s.uv[3 * t + 1], w, h);
  const glm::dvec2 c = to_pixel(s.uv[3 * t + 2], w, h);
  const auto cross = [](glm::dvec2 u, glm::dvec2 v) { return u.x * v.y - u.y * v.x; };
  const double area = cross(b - a, c - a);
  out[1] = cross(p - a, c - a) / area;
  out[2] = cross(b - a, p - a) / area;
  out[0] = 1.0 - out[1] - out[2];
}

bool inside(const LowSurface& s, int t, glm::dvec2 p, int w, int h, double tolerance) {
  double wt[3];
  weights(s, t, p, w, h, wt);
  return wt[0] >= -tolerance && wt[1] >= -tolerance && wt[2] >= -tolerance;
}

// Area of triangle t clipped to the texel square (Sutherland-Hodgman).
double overlap_area(const LowSurface& s, int t, int x, int y, int w, int h) {
  std::vector<glm::dvec2> poly = {to_pixel(s.uv[3 * t], w, h), to_pixel(s.uv[3 * t + 1], w, h),
                                  to_pixel(s.uv[3 * t + 2], w, h)};
  // Half-planes: coordinate `axis` compared with `bound`, keeping >= (lower) or <= (upper).
  const struct {
    int axis;
    double bound;
    bool lower;
  } planes[4] = {
      {0, double(x), true}, {0, double(x + 1), false}, {1, double(y), true}, {1, double(y + 1), false}};
  for (const auto& plane : planes) {
    const auto keep = [&](glm::dvec2 p) {
      return plane.lower ? p[plane.axis] >= plane.bound : p[plane.axis] <= plane.bound;
    };
    std::vector<glm::dvec2> next;
    for (std::size_t i = 0; i < poly.size(); ++i) {
      const glm::dvec2 p = poly[i], q = poly[(i + 1) % poly.size()];
      if (keep(p)) next.push_back(p);
      if (keep(p) != keep(q)) {
        const double f = (plane.bound - p[plane.axis]) / (q[plane.axis] - p[plane.axis]);
        next.push_back(p + f * (q - p));
      }
    }
    poly = std::move(next);
    if (poly.empty()) return 0.0;
  }
  double area = 0.0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const glm::dvec2 p = poly[i], q = poly[(i + 1) % poly.size()];
    area += p.x * q.y - p.y * q.x;
  }
  return std::abs(area) / 2.0;
}

double distance(glm::dvec2 a, glm::dvec2 b) { return std::hypot(a.x - b.x, a.y - b.y); }

// Brute-force distance from p to triangle t: a dense set of points on it.
double brute_force_distance(const LowSurface& s, int t, glm::dvec2 p, int w, int h) {
  if (inside(s, t, p, w, h, 0.0)) return 0.0;
  const glm::dvec2 c[3] = {to_pixel(s.uv[3 * t], w, h), to_pixel(s.uv[3 * t + 1], w, h),
                           to_pixel(s.uv[3 * t + 2], w, h)};
  double best = std::numeric_limits<double>::infinity();
  constexpr int steps = 5000;
  for (int e = 0; e < 3; ++e) {
    for (int i = 0; i <= steps; ++i) {
      const double a = double(i) / steps;
      best = std::min(best, distance(p, c[e] + a * (c[(e + 1) % 3] - c[e])));
    }
  }
  return best;
}

// Random-ish but fixed mesh: a jittered grid of quads over part of the UV
// square plus scattered, overlapping small triangles.
std::vector<glm::vec2> random_mesh_uvs() {
  std::uint32_t state = 12345u;
  const auto next = [&state] {
    state = state * 1664525u + 1013904223u;
    return double(state >> 8) / double(1u << 24);
  };
  constexpr int n = 10;
  std::vector<glm::vec2> grid((n + 1) * (n + 1));
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const double jitter_x = (i > 0 && i < n) ? (next() - 0.5) * 0.5 : 0.0;
      const double jitter_y = (j > 0 && j < n) ? (next() - 0.5) * 0.5 : 0.0;
      grid[j * (n + 1) + i] =
          glm::vec2(float(0.05 + 0.6 * (i + jitter_x) / n), float(0.05 + 0.6 * (j + jitter_y) / n));
    }
  }
  std::vector<glm::vec2> uvs;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const glm::vec2 a = grid[j * (n + 1) + i], b = grid[j * (n + 1) + i + 1];
      const glm::vec2 c = grid[(j + 1) * (n + 1) + i + 1], d = grid[(j + 1) * (n + 1) + i];
      uvs.insert(uvs.end(), {a, b, c, a, c, d});
    }
  }
  for (int k = 0; k < 120; ++k) {
    const glm::vec2 centre(float(0.05 + 0.9 * next()), float(0.05 + 0.9 * next()));
    for (int c = 0; c < 3; ++c) {
      uvs.push_back(centre + glm::vec2(float((next() - 0.5) * 0.12), float((next() - 0.5) * 0.12)));
    }
  }
  return uvs;
}

TEST(RasterSamplePattern, CountsRangeDistinctStratified) {
  EXPECT_FALSE(nmbake::is_supported_sample_count(0));
  EXPECT_FALSE(nmbake::is_supported_sample_count(2));
  EXPECT_FALSE(nmbake::is_supported_sample_count(8));
  for (const int n : {1, 4, 16, 64}) {
    ASSERT_TRUE(nmbake::is_supported_sample_count(n));
    const std::vector<glm::vec2> o = nmbake::sample_offsets(n);
    ASSERT_EQ(int(o.size()), n);
    const int k = int(std::lround(std::sqrt(double(n))));
    std::set<std::pair<float, float>> distinct;
    std::set<int> cells, fine_columns, fine_rows;
    for (const glm::vec2 p : o) {
      EXPECT_GE(p.x, 0.0f);
      EXPECT_LT(p.x, 1.0f);
      EXPECT_GE(p.y, 0.0f);
      EXPECT_LT(p.y, 1.0f);
      distinct.insert({p.x, p.y});
      cells.insert(int(p.y * k) * k + int(p.x * k));
      fine_columns.insert(int(p.x * n));
      fine_rows.insert(int(p.y * n));
    }
    EXPECT_EQ(int(distinct.size()), n);
    EXPECT_EQ(int(cells.size()), n) << "one sample per k x k cell";
    EXPECT_EQ(int(fine_columns.size()), n) << "n-rooks: no two samples share a column";
    EXPECT_EQ(int(fine_rows.size()), n) << "n-rooks: no two samples share a row";
    // Fixed: the same pattern on every call.
    EXPECT_EQ(o, nmbake::sample_offsets(n));
  }
  EXPECT_EQ(nmbake::sample_offsets(1), std::vector<glm::vec2>{glm::vec2(0.5f, 0.5f)});
  const std::vector<glm::vec2> rgss = {
      {0.375f, 0.125f}, {0.875f, 0.375f}, {0.125f, 0.625f}, {0.625f, 0.875f}};
  EXPECT_EQ(nmbake::sample_offsets(4), rgss);
}

TEST(RasterTiny, LowerLeftHalfOf4x4) {
  // Lower-left in UV is the bottom-left of the file: the texels with x <= y.
  const LowSurface s = surface_from_uvs({{0, 0}, {1, 0}, {0, 1}});
  for (const int samples : {1, 4}) {
    TexelSamples ts;
    RasterStats stats;
    nmbake::rasterize(s, 4, 4, samples, ts, stats);
    ASSERT_EQ(ts.width, 4);
    ASSERT_EQ(ts.height, 4);
    ASSERT_EQ(ts.samples, samples);
    ASSERT_EQ(ts.sample_count(), std::size_t(16 * samples));
    ASSERT_EQ(ts.bary.size(), ts.sample_count());
    ASSERT_EQ(ts.coverage.size(), 16u);
    for (int y = 0; y < 4; ++y) {
      for (int x = 0; x < 4; ++x) {
        // Texels with x == y + 1 touch the triangle at one corner only.
        EXPECT_EQ(ts.coverage[y * 4 + x], x <= y ? 1 : 0) << x << "," << y;
        for (int k = 0; k < samples; ++k) {
          EXPECT_EQ(ts.triangle[sample_index(ts, x, y, k)], x <= y ? 0 : -1);
        }
      }
    }
    EXPECT_EQ(stats.covered_texels, 10u);
    EXPECT_EQ(stats.overlapping_samples, 0u);
    EXPECT_EQ(stats.degenerate_uv_triangles, 0u);
    // 1 sample: the diagonal texels' centres lie on the edge, inclusive. 4
    // samples: RGSS samples 0 and 1 lie below the diagonal (o.x > o.y) in each
    // of the 4 diagonal texels.
    EXPECT_EQ(stats.border_samples, samples == 1 ? 0u : 8u);
  }
  // The border sample 0 of texel (0, 0), at (0.375, 0.125), snaps to (0.25,
  // 0.25) on the diagonal: weights w1 = 0.0625 (corner (4, 4)), w2 = 0.9375.
  TexelSamples ts;
  RasterStats stats;
  nmbake::rasterize(s, 4, 4, 4, ts, stats);
  EXPECT_EQ(ts.bary[sample_index(ts, 0, 0, 0)], glm::vec2(0.0625f, 0.9375f));
  // An inside sample: texel (0, 3) sample 2 at (0.125, 3.625) -> u = 0.03125, v = 0.09375.
  EXPECT_EQ(ts.bary[sample_index(ts, 0, 3, 2)], glm::vec2(0.03125f, 0.09375f));
}

TEST(RasterTiny, FullQuadCoversEverythingWithoutBorderOrOverlap) {
  const LowSurface s = surface_from_uvs({{0, 0}, {1, 0}, {1, 1}, {0, 0}, {1, 1}, {0, 1}});
  for (const auto& [w, h, samples] :
       std::vector<std::tuple<int, int, int>>{{8, 8, 1}, {5, 7, 1}, {8, 8, 4}, {16, 16, 16}, {9, 4, 64}}) {
    TexelSamples ts;
    RasterStats stats;
    nmbake::rasterize(s, w, h, samples, ts, stats);
    EXPECT_EQ(stats.covered_texels, std::uint64_t(w * h));
    EXPECT_EQ(stats.border_samples, 0u) << w << "x" << h << "x" << samples;
    EXPECT_EQ(stats.overlapping_samples, 0u) << "the shared diagonal is not an overlap";
    EXPECT_EQ(std::count(ts.coverage.begin(), ts.coverage.end(), 1), w * h);
    EXPECT_EQ(std::count(ts.triangle.begin(), ts.triangle.end(), -1), 0);
  }
  // On an 8x8 map the texel centres (i + 0.5, i + 0.5) lie on the diagonal:
  // they go to the first triangle in order, (0,0),(1,0),(1,1): the lower
  // right, x >= y in the file.
  TexelSamples ts;
  RasterStats stats;
  nmbake::rasterize(s, 8, 8, 1, ts, stats);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) {
      EXPECT_EQ(ts.triangle[sample_index(ts, x, y, 0)], x + y >= 7 ? 0 : 1) << x << "," << y;
    }
  }
}

TEST(RasterTiny, VFlipTriangleNearVOneCoversTopRows) {
  const LowSurface s = surface_from_uvs({{0.0f, 0.9f}, {1.0f, 0.9f}, {0.5f, 1.0f}});
  TexelSamples ts;
  RasterStats stats;
  nmbake::rasterize(s, 8, 8, 1, ts, stats);
  // py spans [0, 0.8]: only the top row of the file.
  for (int y = 0; y < 8; ++y) {
    int row_count = 0;
    for (int x = 0; x < 8; ++x) row_count += ts.coverage[y * 8 + x];
    EXPECT_EQ(row_count, y == 0 ? 8 : 0) << "row " << y;
  }
  EXPECT_EQ(stats.covered_texels, 8u);
}

TEST(RasterBary, InsideSamplesReconstructTheirUv) {
  const LowSurface s = surface_from_uvs(random_mesh_uvs());
  const int w = 96, h = 80, samples = 4;
  TexelSamples ts;
  RasterStats stats;
  nmbake::rasterize(s, w, h, samples, ts, stats);
  const std::vector<glm::vec2> o = nmbake::sample_offsets(samples);
  const int triangle_count = int(s.uv.size() / 3);
  std::uint64_t inside_count = 0, border_count = 0, overlap_count = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int k = 0; k < samples; ++k) {
        const std::size_t i = sample_index(ts, x, y, k);
        const int t = ts.triangle[i];
        const glm::vec2 b = ts.bary[i];
        if (t < 0) {
          EXPECT_EQ(ts.coverage[y * w + x], 0);
          continue;
        }
        ASSERT_LT(t, triangle_count);
        ASSERT_EQ(ts.coverage[y * w + x], 1);
        EXPECT_GE(b.x, 0.0f);
        EXPECT_GE(b.y, 0.0f);
        EXPECT_LE(b.x + b.y, 1.0f);
        const glm::dvec2 p = sample_pixel(x, y, o[k]);
        int first_containing = -1, strictly_containing = 0;
        for (int c = 0; c < triangle_count; ++c) {
          double wt[3];
          weights(s, c, p, w, h, wt);
          if (first_containing < 0 && inside(s, c, p, w, h, 1e-9)) first_containing = c;
          if (wt[0] > 1e-6 && wt[1] > 1e-6 && wt[2] > 1e-6) ++strictly_containing;
        }
        overlap_count += strictly_containing >= 2;
        if (first_containing >= 0) {
          ++inside_count;
          EXPECT_EQ(t, first_containing);
          const glm::dvec2 q = bary_point(s, t, b, w, h);
          // Compare in UV units, as the contract states.
          EXPECT_NEAR(q.x / w, p.x / w, 1e-5);
          EXPECT_NEAR(1.0 - q.y / h, 1.0 - p.y / h, 1e-5);
        } else {
          ++border_count;
        }
      }
    }
  }
  EXPECT_GT(inside_count, 1000u);
  EXPECT_GT(border_count, 50u);
  EXPECT_EQ(border_count, stats.border_samples);
  EXPECT_GT(overlap_count, 0u);
  EXPECT_EQ(overlap_count, stats.overlapping_samples);
}

TEST(RasterBary, BorderSampleTakesNearestPointOfNearestTriangle) {
  // Two triangles with a sub-texel gap and odd slopes, on a small map.
  const LowSurface s = surface_from_uvs(
      {{0.11f, 0.13f}, {0.47f, 0.21f}, {0.29f, 0.83f}, {0.52f, 0.25f}, {0.91f, 0.37f}, {0.33f, 0.87f}});
  const int w = 23, h = 19;
  for (const int samples : {1, 16}) {
    TexelSamples ts;
    RasterStats stats;
    nmbake::rasterize(s, w, h, samples, ts, stats);
    const std::vector<glm::vec2> o = nmbake::sample_offsets(samples);
    std::uint64_t checked = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        for (int k = 0; k < samples; ++k) {
          const std::size_t i = sample_index(ts, x, y, k);
          const int t = ts.triangle[i];
          if (t < 0) continue;
          const glm::dvec2 p = sample_pixel(x, y, o[k]);
          if (inside(s, 0, p, w, h, 1e-9) || inside(s, 1, p, w, h, 1e-9)) continue;
          ++checked;
          const glm::dvec2 q = bary_point(s, t, ts.bary[i], w, h);
          const double ours = distance(p, q);
          // Nearest of the triangles that may overlap the texel: the
          // brute-force nearest over both is no nearer than ours.
          double best = std::numeric_limits<double>::infinity();
          for (int c = 0; c < 2; ++c) {
            // Only triangles overlapping the texel are candidates.
            if (overlap_area(s, c, x, y, w, h) > 1e-12)
              best = std::min(best, brute_force_distance(s, c, p, w, h));
          }
          // The brute force samples the edges every ~2e-3 texel; ours only
          // carries float barycentrics.
          EXPECT_NEAR(ours, best, 2e-3) << x << "," << y << " sample " << k;
          EXPECT_LE(ours, best + 1e-5);
        }
      }
    }
    EXPECT_GT(checked, 20u);
    EXPECT_EQ(checked, stats.border_samples);
  }
}

TEST(RasterBary, EquidistantBorderSampleTakesLowerTriangleIndex) {
  // On a 4x4 map, texel (1, 1) (centre (1.5, 1.5) in pixels) lies between a
  // triangle whose right edge is px = 1.25 and its mirror image with the
  // left edge at px = 1.75: both overlap the texel, both 0.25 away.
  const std::vector<glm::vec2> left = {{0.0f, 1.0f}, {0.3125f, 1.0f}, {0.3125f, 0.0f}};
  const std::vector<glm::vec2> right = {{0.75f, 1.0f}, {0.4375f, 1.0f}, {0.4375f, 0.0f}};
  for (const bool left_first : {true, false}) {
    std::vector<glm::vec2> uvs = left_first ? left : right;
    const std::vector<glm::vec2>& second = left_first ? right : left;
    uvs.insert(uvs.end(), second.begin(), second.end());
    const LowSurface s = surface_from_uvs(uvs);
    TexelSamples ts;
    RasterStats stats;
    nmbake::rasterize(s, 4, 4, 1, ts, stats);
    ASSERT_EQ(ts.coverage[1 * 4 + 1], 1);
    const std::size_t i = sample_index(ts, 1, 1, 0);
    EXPECT_EQ(ts.triangle[i], 0);
    const glm::dvec2 q = bary_point(s, 0, ts.bary[i], 4, 4);
    EXPECT_NEAR(q.x, left_first ? 1.25 : 1.75, 1e-6);
    EXPECT_NEAR(q.y, 1.5, 1e-6);
  }
}

TEST(RasterOverlap, StackedAndShiftedTrianglesAreCounted) {
  // Triangle 1 is triangle 0 shifted right by half a texel at 8x8: the
  // overlapping samples are the ones strictly inside both.
  const float shift = 0.5f / 8.0f;
  const LowSurface s = surface_from_uvs({{0.1f, 0.1f},
                                         {0.9f, 0.1f},
                                         {0.1f, 0.9f},
                                         {0.1f + shift, 0.1f},
                                         {0.9f + shift, 0.1f},
                                         {0.1f + shift, 0.9f}});
  const int w = 8, h = 8, samples = 16;
  TexelSamples ts;
  RasterStats stats;
  nmbake::rasterize(s, w, h, samples, ts, stats);
  const std::vector<glm::vec2> o = nmbake::sample_offsets(samples);
  std::uint64_t expected = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int k = 0; k < samples; ++k) {
        const glm::dvec2 p = sample_pixel(x, y, o[k]);
        double a[3], b[3];
        weights(s, 0, p, w, h, a);
        weights(s, 1, p, w, h, b);
        const bool in_both = std::min({a[0], a[1], a[2]}) > 1e-6 && std::min({b[0], b[1], b[2]}) > 1e-6;
        expected += in_both;
        // Where both contain the sample, the first in order wins.
        if (in_both) {
          EXPECT_EQ(ts.triangle[sample_index(ts, x, y, k)], 0);
        }
      }
    }
  }
  EXPECT_GT(expected, 100u);
  EXPECT_EQ(stats.overlapping_samples, expected);

  // Exactly stacked copies (mirrored winding): every strictly interior sample.
  const LowSurface stacked = surface_from_uvs({{0, 0}, {1, 0}, {0, 1}, {0, 0}, {0, 1}, {1, 0}});
  nmbake::rasterize(stacked, 4, 4, 1, ts, stats);
  // Centres strictly inside: x < y (6 texels); the diagonal ones are on the edge.
  EXPECT_EQ(stats.overlapping_samples, 6u);
  EXPECT_EQ(stats.covered_texels, 10u);
}

TEST(RasterDegenerate, ZeroAreaAndNonFiniteTrianglesAreSkippedAndCounted) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const LowSurface s = surface_from_uvs({
      {0.1f, 0.1f},
      {0.5f, 0.5f},
      {0.9f, 0.9f},  // collinear
      {0.3f, 0.3f},
      {0.3f, 0.3f},
      {0.3f, 0.3f},  // a point
      {0.2f, 0.2f},
      {nan, 0.4f},
      {0.6f, 0.1f},  // NaN
      {0.0f, 0.0f},
      {1.0f, 0.0f},
      {0.0f, 1.0f},  // an ordinary triangle
      {0.2f, 0.7f},
      {0.2f, 0.7f},
      {0.8f, 0.1f},  // repeated corner
  });
  TexelSamples ts;
  RasterStats stats;
  nmbake::rasterize(s, 16, 16, 4, ts, stats);
  EXPECT_EQ(stats.degenerate_uv_triangles, 4u);
  for (std::size_t i = 0; i < ts.sample_count(); ++i) {
    EXPECT_TRUE(ts.triangle[i] == -1 || ts.triangle[i] == 3) << i;
    EXPECT_FALSE(std::isnan(ts.bary[i].x) || std::isnan(ts.bary[i].y));
  }
  // The ordinary triangle rasterizes as if alone: the lower-left half, 16 * 17 / 2 texels.
  EXPECT_EQ(stats.covered_texels, 136u);
  EXPECT_EQ(stats.overlapping_samples, 0u);
}

TEST(RasterDeterminism, ByteIdenticalForOneAndTwoThreads) {
  const LowSurface s = surface_from_uvs(random_mesh_uvs());
  ASSERT_GT(s.uv.size() / 3, 300u);
  TexelSamples one, two;
  RasterStats stats_one, stats_two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    nmbake::rasterize(s, 256, 256, 16, one, stats_one);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    nmbake::rasterize(s, 256, 256, 16, two, stats_two);
  }
  ASSERT_EQ(one.sample_count(), two.sample_count());
  EXPECT_EQ(
      0, std::memcmp(one.triangle.data(), two.triangle.data(), one.triangle.size() * sizeof(std::int32_t)));
  EXPECT_EQ(0, std::memcmp(one.bary.data(), two.bary.data(), one.bary.size() * sizeof(glm::vec2)));
  EXPECT_EQ(one.coverage, two.coverage);
  EXPECT_EQ(stats_one.covered_texels, stats_two.covered_texels);
  EXPECT_EQ(stats_one.border_samples, stats_two.border_samples);
  EXPECT_EQ(stats_one.overlapping_samples, stats_two.overlapping_samples);
  EXPECT_GT(stats_one.covered_texels, 10000u);
  EXPECT_GT(stats_one.overlapping_samples, 0u);

  // Reusing the output for another mesh leaves nothing stale behind.
  const LowSurface small = surface_from_uvs({{0, 0}, {0.25f, 0}, {0, 0.25f}});
  RasterStats stats_small;
  nmbake::rasterize(small, 256, 256, 16, two, stats_small);
  TexelSamples fresh;
  nmbake::rasterize(small, 256, 256, 16, fresh, stats_small);
  EXPECT_EQ(two.triangle, fresh.triangle);
  EXPECT_EQ(two.coverage, fresh.coverage);
  EXPECT_EQ(0, std::memcmp(two.bary.data(), fresh.bary.data(), two.bary.size() * sizeof(glm::vec2)));
}

TEST(RasterSliver, ThinnerThanATexelStillCoversTheTexelsItCrosses) {
  // A needle from (0.05, 0.1) to (0.95, 0.83) in UV, 0.01 texel thick.
  const int w = 64, h = 64;
  const glm::dvec2 a{0.05, 0.1}, b{0.95, 0.83};
  const glm::dvec2 d = b - a;
  const glm::dvec2 normal = glm::dvec2(-d.y, d.x) / std::hypot(d.x, d.y);
  const glm::dvec2 c = 0.5 * (a + b) + normal * (0.01 / w);
  const LowSurface s = surface_from_uvs({glm::vec2(a), glm::vec2(b), glm::vec2(c)});
  TexelSamples ts;
  RasterStats stats;
  nmbake::rasterize(s, w, h, 4, ts, stats);
  EXPECT_EQ(stats.degenerate_uv_triangles, 0u);
  // Every texel the segment a-b passes through is covered.
  std::set<int> crossed;
  for (int i = 1; i < 100000; ++i) {
    const glm::dvec2 p = to_pixel(glm::vec2(a + d * (i / 100000.0)), w, h);
    const double fx = p.x - std::floor(p.x), fy = p.y - std::floor(p.y);
    if (fx < 1e-3 || fx > 1 - 1e-3 || fy < 1e-3 || fy > 1 - 1e-3) continue;  // near a texel boundary
    crossed.insert(int(p.y) * w + int(p.x));
  }
  EXPECT_GT(crossed.size(), 90u);
  for (const int texel : crossed) {
    EXPECT_EQ(ts.coverage[texel], 1) << texel % w << "," << texel / w;
    for (int k = 0; k < 4; ++k) EXPECT_EQ(ts.triangle[texel * 4 + k], 0);
  }
  // And it covers little else: at most the texels touched within the thickness.
  EXPECT_LE(stats.covered_texels, crossed.size() + 10);
  EXPECT_GE(stats.border_samples, 4 * crossed.size() - 8);
  for (const glm::vec2 bary : ts.bary) {
    EXPECT_TRUE(bary.x >= 0 && bary.y >= 0 && bary.x + bary.y <= 1.0f);
  }
}

}  // namespace

namespace {

// rasterize() tests a texel's samples four at a time; the per-sample path is
// the reference. Every byte must agree: triangles, barycentrics, coverage and
// the counters, on meshes with shared edges, overlaps, slivers, borders and
// bands.
void expect_same_as_per_sample(const LowSurface& s, int w, int h, int spp, int row_begin = 0,
                               int row_end = -1) {
  TexelSamples lanes, reference;
  RasterStats lane_stats, reference_stats;
  nmbake::rasterize(s, w, h, spp, lanes, lane_stats, row_begin, row_end);
  nmbake::detail::rasterize_per_sample(s, w, h, spp, reference, reference_stats, row_begin, row_end);
  ASSERT_EQ(lanes.sample_count(), reference.sample_count());
  EXPECT_EQ(lanes.triangle, reference.triangle) << w << "x" << h << " spp " << spp;
  EXPECT_EQ(0, std::memcmp(lanes.bary.data(), reference.bary.data(), lanes.bary.size() * sizeof(glm::vec2)))
      << w << "x" << h << " spp " << spp;
  EXPECT_EQ(lanes.coverage, reference.coverage);
  EXPECT_EQ(lane_stats.covered_texels, reference_stats.covered_texels);
  EXPECT_EQ(lane_stats.border_samples, reference_stats.border_samples);
  EXPECT_EQ(lane_stats.overlapping_samples, reference_stats.overlapping_samples);
}

TEST(RasterLanes, FourLanesEqualPerSample) {
  const LowSurface mesh = surface_from_uvs(random_mesh_uvs());
  for (const int spp : {4, 16, 64}) {
    expect_same_as_per_sample(mesh, 192, 160, spp);
    expect_same_as_per_sample(mesh, 192, 160, spp, 64, 128);
  }
  // Odd sizes, a sliver, a degenerate and a triangle hanging off the map.
  const LowSurface odd = surface_from_uvs({{0.05f, 0.1f},
                                           {0.95f, 0.83f},
                                           {0.5f, 0.4651f},
                                           {0.1f, 0.1f},
                                           {0.1f, 0.1f},
                                           {0.3f, 0.3f},
                                           {-0.2f, 0.5f},
                                           {0.6f, 1.3f},
                                           {0.4f, -0.1f}});
  for (const int spp : {4, 16, 64}) expect_same_as_per_sample(odd, 77, 53, spp);
  // The lanes really ran: most samples of the mesh are strictly inside a triangle.
  TexelSamples ts;
  RasterStats stats;
  nmbake::rasterize(mesh, 192, 160, 16, ts, stats);
  EXPECT_GT(stats.covered_texels * 16, 4 * stats.border_samples);
}

}  // namespace

namespace {

// Coverage against a brute-force clip of every triangle to every texel:
// a texel is covered exactly when some triangle overlaps it with nonzero
// area (only texels within 1e-9 texel^2 of touching are left out). The
// rasterizer tests only the ends of each row's run of overlapping texels.
TEST(RasterCoverage, MatchesClippedOverlapArea) {
  const LowSurface s = surface_from_uvs(random_mesh_uvs());
  const int w = 96, h = 80;
  const int triangle_count = int(s.uv.size() / 3);
  TexelSamples ts;
  RasterStats stats;
  nmbake::rasterize(s, w, h, 1, ts, stats);
  std::uint64_t checked = 0, covered = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double largest = 0.0;
      for (int t = 0; t < triangle_count; ++t) largest = std::max(largest, overlap_area(s, t, x, y, w, h));
      if (largest > 0.0 && largest <= 1e-9) continue;
      ++checked;
      covered += largest > 0.0;
      EXPECT_EQ(ts.coverage[y * w + x], largest > 0.0 ? 1 : 0) << x << "," << y << " area " << largest;
    }
  }
  EXPECT_GT(checked, static_cast<std::uint64_t>(w * h - 20));
  EXPECT_GT(covered, 2000u);
  EXPECT_EQ(covered, stats.covered_texels);
}

}  // namespace
