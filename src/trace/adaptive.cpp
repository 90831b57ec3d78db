// Adaptive sampling: the first pass's values and the rules that pick the
// texels to refine (include/nmbake/adaptive.hpp). The refinement itself is
// the bake's own raster (rasterize_selected), trace and encode.
//
// The level-1 rule is a contrast test between neighbouring samples, as in
// adaptive anti-aliasing (Mitchell, "Generating Antialiased Images at Low
// Sampling Densities", SIGGRAPH 1987), on the second difference: for a box
// filter the contrast that matters is curvature, not slope. Level 2 is the
// classic recursive refinement of Whitted ("An Improved Illumination Model
// for Shaded Display", CACM 1980): more samples where the samples taken
// disagree.
#include "nmbake/adaptive.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

namespace nmbake {

std::vector<int> adaptive_levels(const AdaptiveOptions& options) {
  if (options.max_samples <= 4) return {4};
  return {4, options.max_samples};
}

std::vector<float> texel_sizes(const LowSurface& surface, int width, int height) {
  const std::size_t triangles = surface.triangle_count();
  std::vector<float> size(triangles, 0.0f);
  for (std::size_t t = 0; t < triangles; ++t) {
    const glm::vec3* p = &surface.position[3 * t];
    const glm::vec2* uv = &surface.uv[3 * t];
    const double world = 0.5 * static_cast<double>(glm::length(glm::cross(p[1] - p[0], p[2] - p[0])));
    const glm::dvec2 a(static_cast<double>(uv[1].x - uv[0].x) * width,
                       static_cast<double>(uv[1].y - uv[0].y) * height);
    const glm::dvec2 b(static_cast<double>(uv[2].x - uv[0].x) * width,
                       static_cast<double>(uv[2].y - uv[0].y) * height);
    const double texels = 0.5 * std::fabs(a.x * b.y - a.y * b.x);
    if (texels > 1e-12 && world > 0.0 && std::isfinite(world / texels)) {
      size[t] = static_cast<float>(std::sqrt(world / texels));
    }
  }
  return size;
}

void first_pass_values(const TexelSamples& samples, const Hits& hits, const std::vector<float>& texel_size,
                       FirstPass& out) {
  NMBAKE_CHECK(samples.samples == 1, "the first pass has one sample per texel");
  const std::size_t texels =
      static_cast<std::size_t>(samples.width) * static_cast<std::size_t>(samples.height);
  NMBAKE_CHECK(out.rgb.size() >= 3 * texels, "the first pass is encoded");
  out.width = samples.width;
  out.rows = samples.height;
  out.state.resize(texels);
  out.depth.resize(texels);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, texels, 4096),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t t = r.begin(); t != r.end(); ++t) {
                        const std::int32_t low = samples.triangle[t];
                        out.depth[t] = 0.0f;
                        if (low < 0) {
                          out.state[t] = FirstPass::none;
                        } else if (hits.triangle[t] < 0) {
                          out.state[t] = FirstPass::miss;
                        } else {
                          out.state[t] = FirstPass::hit;
                          const float size = texel_size[static_cast<std::size_t>(low)];
                          out.depth[t] = size > 0.0f ? hits.distance[t] / size : 0.0f;
                        }
                      }
                    });
}

FirstPass first_pass_row(const FirstPass& from, int row) {
  FirstPass out;
  out.width = from.width;
  out.rows = 1;
  const auto begin = static_cast<std::ptrdiff_t>(row) * from.width;
  const auto end = begin + from.width;
  out.state.assign(from.state.begin() + begin, from.state.begin() + end);
  out.rgb.assign(from.rgb.begin() + 3 * begin, from.rgb.begin() + 3 * end);
  out.depth.assign(from.depth.begin() + begin, from.depth.begin() + end);
  return out;
}

namespace {

// One row of first-pass values (null outside the band and its two rows).
struct Row {
  const std::uint8_t* state = nullptr;
  const float* rgb = nullptr;
  const float* depth = nullptr;
};

Row row_of(const FirstPass& f, int row) {
  if (f.rows == 0) return {};
  const std::size_t at = static_cast<std::size_t>(row) * static_cast<std::size_t>(f.width);
  return {f.state.data() + at, f.rgb.data() + 3 * at, f.depth.data() + at};
}

// The stored vector of an encoded texel (the encoding is affine: second
// differences of rgb are half those of the vector).
inline glm::vec3 stored(const float* rgb, int x) {
  return glm::vec3(rgb[3 * x], rgb[3 * x + 1], rgb[3 * x + 2]) * 2.0f - 1.0f;
}

// Level 1 for texel x of row `mid` between rows `up` and `down`.
bool refine(const Row& up, const Row& mid, const Row& down, int x, int width, const AdaptiveOptions& o) {
  if (mid.state[x] == FirstPass::miss || o.normal_threshold <= 0.0f) return true;
  const auto state = [&](const Row& r, int i) {
    return r.state != nullptr && i >= 0 && i < width ? r.state[i] : std::uint8_t{FirstPass::none};
  };
  for (const Row* r : {&up, &mid, &down}) {
    for (int i = x - 1; i <= x + 1; ++i) {
      if (state(*r, i) == FirstPass::miss) return true;
    }
  }
  const glm::vec3 centre = stored(mid.rgb, x);
  const float depth = mid.depth[x];
  // Opposite pairs: left/right, up/down and the two diagonals.
  const struct {
    const Row* a;
    int ax;
    const Row* b;
    int bx;
  } pairs[4] = {
      {&mid, x - 1, &mid, x + 1}, {&up, x, &down, x}, {&up, x - 1, &down, x + 1}, {&up, x + 1, &down, x - 1}};
  for (const auto& p : pairs) {
    const bool has_a = state(*p.a, p.ax) == FirstPass::hit, has_b = state(*p.b, p.bx) == FirstPass::hit;
    if (has_a && has_b) {
      if (glm::length(stored(p.a->rgb, p.ax) + stored(p.b->rgb, p.bx) - 2.0f * centre) > o.normal_threshold)
        return true;
      if (std::fabs(p.a->depth[p.ax] + p.b->depth[p.bx] - 2.0f * depth) > o.depth_threshold) return true;
    } else if (has_a || has_b) {
      const Row& one = has_a ? *p.a : *p.b;
      const int i = has_a ? p.ax : p.bx;
      if (glm::length(stored(one.rgb, i) - centre) > o.border_threshold) return true;
      if (std::fabs(one.depth[i] - depth) > o.depth_threshold) return true;
    }
  }
  return false;
}

}  // namespace

void refine_texels(const FirstPass& above, const FirstPass& band, const FirstPass& below,
                   const AdaptiveOptions& options, std::vector<std::uint32_t>& refined) {
  const int width = band.width;
  const int rows = band.rows;
  // Per row, then joined in row order: the list is the same for any thread count.
  std::vector<std::vector<std::uint32_t>> per_row(static_cast<std::size_t>(rows));
  tbb::parallel_for(0, rows, [&](int y) {
    const Row up = y > 0 ? row_of(band, y - 1) : row_of(above, 0);
    const Row mid = row_of(band, y);
    const Row down = y + 1 < rows ? row_of(band, y + 1) : row_of(below, 0);
    std::vector<std::uint32_t>& list = per_row[static_cast<std::size_t>(y)];
    const std::size_t first = static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
    for (int x = 0; x < width; ++x) {
      if (mid.state[x] != FirstPass::none && refine(up, mid, down, x, width, options)) {
        list.push_back(static_cast<std::uint32_t>(first + static_cast<std::size_t>(x)));
      }
    }
  });
  refined.clear();
  for (const std::vector<std::uint32_t>& list : per_row)
    refined.insert(refined.end(), list.begin(), list.end());
}

void spread_texels(const TexelSamples& samples, const Hits& hits, const Mesh& high, bool smooth_high,
                   const std::uint32_t* texels, const AdaptiveOptions& options,
                   std::vector<std::uint32_t>& out) {
  const std::size_t count = static_cast<std::size_t>(samples.width);
  const std::size_t spp = static_cast<std::size_t>(samples.samples);
  const bool smooth = smooth_high && high.has_normals();
  std::vector<std::uint8_t> spread(count, 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1024),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      glm::vec3 normal[64];
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        int found = 0, missed = 0;
                        glm::vec3 sum(0.0f);
                        for (std::size_t k = 0; k < spp && k < 64; ++k) {
                          const std::size_t s = i * spp + k;
                          if (samples.triangle[s] < 0) continue;
                          const std::int32_t tri = hits.triangle[s];
                          if (tri < 0) {
                            ++missed;
                            continue;
                          }
                          const std::uint32_t* v = &high.indices[3 * static_cast<std::size_t>(tri)];
                          const glm::vec2 b = hits.bary[s];
                          glm::vec3 n = smooth ? high.normals[v[0]] * (1.0f - b.x - b.y) +
                                                     high.normals[v[1]] * b.x + high.normals[v[2]] * b.y
                                               : glm::cross(high.positions[v[1]] - high.positions[v[0]],
                                                            high.positions[v[2]] - high.positions[v[0]]);
                          const float l = glm::length(n);
                          if (!(l > 0.0f) || !std::isfinite(l)) {
                            ++missed;  // no normal: treated like a miss
                            continue;
                          }
                          normal[found++] = n / l;
                          sum += n / l;
                        }
                        if ((found > 0 && missed > 0) || options.spread_threshold <= 0.0f) {
                          spread[i] = 1;
                          continue;
                        }
                        const float l = glm::length(sum);
                        if (found < 2 || !(l > 0.0f)) continue;
                        const glm::vec3 mean = sum / l;
                        // |a - b| of unit vectors is 2 sin(angle / 2): about the angle.
                        for (int k = 0; k < found; ++k) {
                          if (glm::length(normal[k] - mean) > options.spread_threshold) {
                            spread[i] = 1;
                            break;
                          }
                        }
                      }
                    });
  for (std::size_t i = 0; i < count; ++i) {
    if (spread[i]) out.push_back(texels[i]);
  }
}

}  // namespace nmbake
