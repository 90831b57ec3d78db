// Adaptive sampling: the first pass's values and the rule that picks the
// texels to refine (include/nmbake/adaptive.hpp). The refinement itself is
// the bake's own raster (rasterize_selected), trace and encode.
//
// The rule is a second-difference test, as in the refinement criteria of
// adaptive anti-aliasing (Mitchell, "Generating Antialiased Images at Low
// Sampling Densities", SIGGRAPH 1987, tests contrast between neighbouring
// samples; here the contrast that matters for a box filter is curvature, not
// slope).
#include "nmbake/adaptive.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace nmbake {

std::vector<float> texel_sizes(const LowSurface& surface, int width, int height) {
  const std::size_t triangles = surface.triangle_count();
  std::vector<float> size(triangles, 0.0f);
  for (std::size_t t = 0; t < triangles; ++t) {
    const glm::vec3* p = &surface.position[3 * t];
    const glm::vec2* uv = &surface.uv[3 * t];
    const double world = 0.5 * static_cast<double>(glm::length(glm::cross(p[1] - p[0], p[2] - p[0])));
    const glm::dvec2 a(static_cast<double>(uv[1].x - uv[0].x) * width, static_cast<double>(uv[1].y - uv[0].y) * height);
    const glm::dvec2 b(static_cast<double>(uv[2].x - uv[0].x) * width, static_cast<double>(uv[2].y - uv[0].y) * height);
    const double texels = 0.5 * std::fabs(a.x * b.y - a.y * b.x);
    if (texels > 1e-12 && world > 0.0 && std::isfinite(world / texels)) {
      size[t] = static_cast<float>(std::sqrt(world / texels));
    }
  }
  return size;
}

void first_pass_values(const TexelSamples& samples, const Hits& hits, const Mesh& high, bool smooth_high,
                       const std::vector<float>& texel_size, FirstPass& out) {
  NMBAKE_CHECK(samples.samples == 1, "the first pass has one sample per texel");
  const std::size_t texels = static_cast<std::size_t>(samples.width) * static_cast<std::size_t>(samples.height);
  out.width = samples.width;
  out.rows = samples.height;
  out.state.assign(texels, FirstPass::none);
  out.normal.assign(texels, glm::vec3(0.0f));
  out.depth.assign(texels, 0.0f);
  out.turn.assign(texels, 0.0f);
  const bool smooth = smooth_high && high.has_normals();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, texels, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t t = r.begin(); t != r.end(); ++t) {
      const std::int32_t low = samples.triangle[t];
      if (low < 0) continue;
      const std::int32_t tri = hits.triangle[t];
      if (tri < 0) {
        out.state[t] = FirstPass::miss;
        continue;
      }
      const std::uint32_t* v = &high.indices[3 * static_cast<std::size_t>(tri)];
      const glm::vec2 b = hits.bary[t];
      glm::vec3 n;
      if (smooth) {
        n = high.normals[v[0]] * (1.0f - b.x - b.y) + high.normals[v[1]] * b.x + high.normals[v[2]] * b.y;
      } else {
        const glm::vec3 a = high.positions[v[0]];
        n = glm::cross(high.positions[v[1]] - a, high.positions[v[2]] - a);
      }
      const float l = glm::length(n);
      // A normal that cannot be normalised counts as a miss: it is refined.
      if (!(l > 0.0f) || !std::isfinite(l)) {
        out.state[t] = FirstPass::miss;
        continue;
      }
      out.state[t] = FirstPass::hit;
      out.normal[t] = n / l;
      const float size = texel_size[static_cast<std::size_t>(low)];
      out.depth[t] = size > 0.0f ? hits.distance[t] / size : 0.0f;
      if (smooth) {
        float turn = 0.0f;
        for (int e = 0; e < 3; ++e) {
          const std::uint32_t i = v[e], j = v[(e + 1) % 3];
          const float length = glm::length(high.positions[i] - high.positions[j]);
          if (length > 0.0f) turn = std::max(turn, glm::length(high.normals[i] - high.normals[j]) / length);
        }
        out.turn[t] = turn * size;
      }
    }
  });
}

FirstPass first_pass_row(const FirstPass& from, int row) {
  FirstPass out;
  out.width = from.width;
  out.rows = 1;
  const auto begin = static_cast<std::size_t>(row) * static_cast<std::size_t>(from.width);
  const auto end = begin + static_cast<std::size_t>(from.width);
  out.state.assign(from.state.begin() + static_cast<std::ptrdiff_t>(begin), from.state.begin() + static_cast<std::ptrdiff_t>(end));
  out.normal.assign(from.normal.begin() + static_cast<std::ptrdiff_t>(begin), from.normal.begin() + static_cast<std::ptrdiff_t>(end));
  out.depth.assign(from.depth.begin() + static_cast<std::ptrdiff_t>(begin), from.depth.begin() + static_cast<std::ptrdiff_t>(end));
  out.turn.assign(from.turn.begin() + static_cast<std::ptrdiff_t>(begin), from.turn.begin() + static_cast<std::ptrdiff_t>(end));
  return out;
}

namespace {

// A texel's first-pass values, or none outside the band and its two rows.
struct Sample {
  std::uint8_t state = FirstPass::none;
  glm::vec3 normal{0.0f};
  float depth = 0.0f;
  float turn = 0.0f;
};

bool refine(const Sample& centre, const Sample (&around)[8], const AdaptiveOptions& o) {
  if (centre.state == FirstPass::none) return false;
  if (centre.state == FirstPass::miss) return true;
  if (centre.turn > o.turn_threshold) return true;
  for (const Sample& s : around) {
    if (s.state == FirstPass::miss) return true;
  }
  // Opposite pairs: left/right, up/down and the two diagonals.
  static constexpr int kPairs[4][2] = {{3, 4}, {1, 6}, {0, 7}, {2, 5}};
  for (const auto& pair : kPairs) {
    const Sample& a = around[pair[0]];
    const Sample& b = around[pair[1]];
    const bool has_a = a.state == FirstPass::hit, has_b = b.state == FirstPass::hit;
    if (has_a && has_b) {
      if (glm::length(a.normal + b.normal - 2.0f * centre.normal) > o.normal_threshold) return true;
      if (std::fabs(a.depth + b.depth - 2.0f * centre.depth) > o.depth_threshold) return true;
    } else if (has_a || has_b) {
      const Sample& one = has_a ? a : b;
      if (glm::length(one.normal - centre.normal) > o.border_threshold) return true;
      if (std::fabs(one.depth - centre.depth) > o.depth_threshold) return true;
    }
  }
  return false;
}

}  // namespace

void refine_texels(const FirstPass& above, const FirstPass& band, const FirstPass& below,
                   const AdaptiveOptions& options, std::vector<std::uint32_t>& refined) {
  const int width = band.width;
  const int rows = band.rows;
  // Row y of the band, -1 = above, rows = below.
  const auto at = [&](int x, int y) {
    Sample s;
    if (x < 0 || x >= width) return s;
    const FirstPass* from = &band;
    int row = y;
    if (y < 0) {
      from = &above;
      row = 0;
    } else if (y >= rows) {
      from = &below;
      row = 0;
    }
    if (from->rows == 0) return s;
    const std::size_t i = static_cast<std::size_t>(row) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
    s.state = from->state[i];
    s.normal = from->normal[i];
    s.depth = from->depth[i];
    s.turn = from->turn[i];
    return s;
  };
  // Per row, then joined in row order: the list is the same for any thread count.
  std::vector<std::vector<std::uint32_t>> per_row(static_cast<std::size_t>(rows));
  tbb::parallel_for(0, rows, [&](int y) {
    std::vector<std::uint32_t>& list = per_row[static_cast<std::size_t>(y)];
    for (int x = 0; x < width; ++x) {
      const Sample centre = at(x, y);
      if (centre.state == FirstPass::none) continue;
      // Neighbours in reading order: row above (left, centre, right), then
      // left and right, then the row below.
      const Sample around[8] = {at(x - 1, y - 1), at(x, y - 1), at(x + 1, y - 1), at(x - 1, y),
                                at(x + 1, y),     at(x - 1, y + 1), at(x, y + 1), at(x + 1, y + 1)};
      if (refine(centre, around, options)) {
        list.push_back(static_cast<std::uint32_t>(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                                                  static_cast<std::size_t>(x)));
      }
    }
  });
  refined.clear();
  for (const std::vector<std::uint32_t>& list : per_row) refined.insert(refined.end(), list.begin(), list.end());
}

}  // namespace nmbake
