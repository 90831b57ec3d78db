// Tangent-frame views: "visualize the vectors you generate" (Sanglard, "Bump
// Mapping with GLSL", 2009). The MikkTSpace frames (Mikkelsen 2008) of the
// low mesh drawn as short T/B/N lines over the shaded mesh, and the UV layout
// coloured by tangent with mirrored triangles hatched, so a wrong or mirrored
// frame shows at a glance.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <numeric>
#include <tuple>

#include "inspect/preview_draw.hpp"
#include "nmbake/preview.hpp"

namespace nmbake {

using namespace preview_detail;

namespace {

glm::vec3 unit_or(const glm::vec3& v, const glm::vec3& fallback) {
  const float l = glm::length(v);
  return l > 1e-12f && std::isfinite(l) ? v / l : fallback;
}

void put(Image& image, int x, int y, const glm::vec3& colour) {
  if (x < 0 || y < 0 || x >= image.width || y >= image.height) return;
  float* p = image.at(x, y);
  for (int c = 0; c < 3; ++c) p[c] = colour[c];
}

// A line between two image points, one sample per pixel step; `visible`
// decides per step (used for the depth test).
template <class Visible>
void draw_line(Image& image, glm::vec2 a, glm::vec2 b, int thickness, const glm::vec3& colour,
               Visible visible) {
  // Far off-image points (near the camera plane, absurd UVs) are skipped:
  // they would overflow the integer pixel coordinates.
  constexpr float kFar = 1e6f;
  if (!(std::fabs(a.x) < kFar && std::fabs(a.y) < kFar && std::fabs(b.x) < kFar && std::fabs(b.y) < kFar))
    return;
  const glm::vec2 d = b - a;
  const float length = std::max(std::fabs(d.x), std::fabs(d.y));
  if (length > 1e5f) return;
  const int steps = std::max(1, static_cast<int>(std::ceil(length)));
  for (int i = 0; i <= steps; ++i) {
    const float f = static_cast<float>(i) / static_cast<float>(steps);
    const glm::vec2 p = a + f * d;
    const int x = static_cast<int>(std::floor(p.x)), y = static_cast<int>(std::floor(p.y));
    if (!visible(f, x, y)) continue;
    for (int oy = 0; oy < thickness; ++oy) {
      for (int ox = 0; ox < thickness; ++ox) put(image, x + ox, y + oy, colour);
    }
  }
}

}  // namespace

Status render_tangent_frames(const LowSurface& surface, const TangentViewOptions& options, Image& out,
                             TangentViewStats& stats) {
  NMBAKE_TRY(validate_view_options(options.view));
  if (!(options.length >= 0.0f) || !std::isfinite(options.length)) {
    return Status::bad_input("--length must be a non-negative number (scene units)");
  }
  NMBAKE_CHECK(surface.triangle_count() > 0, "low surface built");
  stats = TangentViewStats{};

  std::vector<glm::vec3> positions;
  positions.reserve(surface.position.size() + 1);
  positions.assign(surface.position.begin(), surface.position.end());
  std::vector<std::uint32_t> indices(positions.size());
  std::iota(indices.begin(), indices.end(), 0u);
  RayScene scene;
  NMBAKE_TRY(scene.build(positions, indices));

  Bounds bounds;
  bounds.min = bounds.max = positions[0];
  for (const glm::vec3& p : positions) {
    bounds.min = glm::min(bounds.min, p);
    bounds.max = glm::max(bounds.max, p);
  }
  const ViewOptions& view = options.view;
  const Camera camera = make_camera(frame_points({&surface.position}), view, view.yaw_degrees);
  const Lights lights = make_lights(camera, view);
  std::vector<RayHit> hits;
  trace_primary(scene, camera, view.supersample, hits);

  const int size = view.size;
  const int k = view.supersample;
  const int grid = size * k;
  out = Image{size, size, 3, {}};
  out.pixels.assign(static_cast<std::size_t>(size) * size * 3, 0.0f);
  // Camera-space depth of the nearest surface seen in each pixel.
  std::vector<float> depth(static_cast<std::size_t>(size) * size, std::numeric_limits<float>::infinity());
  tbb::parallel_for(0, size, [&](int y) {
    for (int x = 0; x < size; ++x) {
      glm::vec3 sum(0.0f);
      float nearest = std::numeric_limits<float>::infinity();
      for (int j = 0; j < k; ++j) {
        for (int i = 0; i < k; ++i) {
          const std::size_t s =
              static_cast<std::size_t>(y * k + j) * grid + static_cast<std::size_t>(x * k + i);
          const RayHit& h = hits[s];
          if (h.triangle < 0) {
            sum += kBackground;
            continue;
          }
          const glm::vec2 p = sample_position(s, size, k);
          const glm::vec3 dir = camera.direction(p.x, p.y);
          const glm::vec3 n =
              unit_or(interpolate(surface.normal, 3 * static_cast<std::size_t>(h.triangle), h.bary), -dir);
          sum += shade(n, -dir, lights);
          nearest = std::min(nearest, h.t * glm::dot(dir, camera.forward));
        }
      }
      depth[static_cast<std::size_t>(y) * size + x] = nearest;
      for (int c = 0; c < 3; ++c) out.at(x, y)[c] = sum[c] / static_cast<float>(k * k);
    }
  });

  // Distinct corner frames: corners that share position, normal and tangent
  // draw once; where they differ (seams, mirrored charts) each is drawn.
  const std::size_t corner_count = surface.position.size();
  auto key = [&](std::size_t c) {
    const glm::vec3& p = surface.position[c];
    const glm::vec3& n = surface.normal[c];
    const glm::vec4& t = surface.tangent[c];
    return std::make_tuple(p.x, p.y, p.z, n.x, n.y, n.z, t.x, t.y, t.z, t.w);
  };
  std::vector<std::size_t> order(corner_count);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
  order.erase(
      std::unique(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return key(a) == key(b); }),
      order.end());
  stats.frames = order.size();
  for (std::size_t t = 0; t < surface.triangle_count(); ++t) {
    const float w = surface.tangent[3 * t].w + surface.tangent[3 * t + 1].w + surface.tangent[3 * t + 2].w;
    stats.mirrored_triangles += w < 0.0f ? 1 : 0;
  }

  float length = options.length;
  if (length == 0.0f) {
    double sum = 0.0;
    for (std::size_t t = 0; t < surface.triangle_count(); ++t) {
      for (int e = 0; e < 3; ++e) {
        sum += glm::length(surface.position[3 * t + (e + 1) % 3] - surface.position[3 * t + e]);
      }
    }
    length = static_cast<float>(0.4 * sum / (3.0 * static_cast<double>(surface.triangle_count())));
  }
  const float tolerance = 0.3f * length + 1e-4f * bounds.diagonal();
  const int thickness = std::max(1, size / 400);
  auto segment = [&](const glm::vec3& a, const glm::vec3& b, const glm::vec3& colour) {
    glm::vec2 pa, pb;
    float za = 0.0f, zb = 0.0f;
    if (!camera.project(a, pa, za) || !camera.project(b, pb, zb)) return;
    draw_line(out, pa, pb, thickness, colour, [&](float f, int x, int y) {
      if (x < 0 || y < 0 || x >= size || y >= size) return false;
      const float z = 1.0f / ((1.0f - f) / za + f / zb);  // perspective-correct depth
      return z <= depth[static_cast<std::size_t>(y) * size + x] + tolerance;
    });
  };
  for (std::size_t c : order) {
    const glm::vec3 P = surface.position[c];
    const glm::vec3 N = unit_or(surface.normal[c], glm::vec3(0.0f, 0.0f, 1.0f));
    const glm::vec3 T = unit_or(glm::vec3(surface.tangent[c]), glm::vec3(1.0f, 0.0f, 0.0f));
    const float sign = surface.tangent[c].w < 0.0f ? -1.0f : 1.0f;
    const glm::vec3 B = unit_or(sign * glm::cross(N, T), glm::vec3(0.0f, 1.0f, 0.0f));
    segment(P, P + length * T, glm::vec3(0.95f, 0.15f, 0.1f));
    segment(P, P + length * B, glm::vec3(0.2f, 0.9f, 0.2f));
    segment(P, P + length * N, glm::vec3(0.25f, 0.45f, 1.0f));
  }
  return Status::ok();
}

Status render_uv_layout(const LowSurface& surface, int size, Image& out, TangentViewStats& stats) {
  if (size < 16 || size > 8192)
    return Status::bad_input("--uv-size " + std::to_string(size) + " is out of range (16 to 8192)");
  stats.mirrored_triangles = 0;
  out = Image{size, size, 3, {}};
  out.pixels.assign(static_cast<std::size_t>(size) * size * 3, 0.0f);
  fill_rect(out, 0, 0, size, size, kBackground);
  const float s = static_cast<float>(size);
  const int stripe = std::max(2, size / 128);
  auto to_pixel = [&](glm::vec2 uv) { return glm::vec2(uv.x * s, (1.0f - uv.y) * s); };

  // Triangles in order, each over its pixel bounding box (later ones win on
  // overlaps): sequential, so the image never depends on threads.
  for (std::size_t t = 0; t < surface.triangle_count(); ++t) {
    const std::size_t base = 3 * t;
    const glm::vec2 a = to_pixel(surface.uv[base]), b = to_pixel(surface.uv[base + 1]),
                    c = to_pixel(surface.uv[base + 2]);
    const float sign_sum =
        surface.tangent[base].w + surface.tangent[base + 1].w + surface.tangent[base + 2].w;
    const bool mirrored = sign_sum < 0.0f;
    stats.mirrored_triangles += mirrored ? 1 : 0;
    const float area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (!(std::fabs(area) > 1e-12f) || !std::isfinite(area)) continue;
    const float lo_x = std::min({a.x, b.x, c.x}), hi_x = std::max({a.x, b.x, c.x});
    const float lo_y = std::min({a.y, b.y, c.y}), hi_y = std::max({a.y, b.y, c.y});
    // Clamped as floats first: absurd UVs must not overflow the cast.
    const float top = static_cast<float>(size - 1);
    const int x0 = static_cast<int>(std::clamp(std::floor(lo_x), 0.0f, top));
    const int x1 = static_cast<int>(std::clamp(std::ceil(hi_x), -1.0f, top));
    const int y0 = static_cast<int>(std::clamp(std::floor(lo_y), 0.0f, top));
    const int y1 = static_cast<int>(std::clamp(std::ceil(hi_y), -1.0f, top));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const glm::vec2 p(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f);
        const float w1 = ((p.x - a.x) * (c.y - a.y) - (p.y - a.y) * (c.x - a.x)) / area;
        const float w2 = ((b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)) / area;
        const float w0 = 1.0f - w1 - w2;
        if (w0 < 0.0f || w1 < 0.0f || w2 < 0.0f) continue;
        const glm::vec3 T =
            unit_or(glm::vec3(interpolate(surface.tangent, base, glm::vec2(w1, w2))), glm::vec3(0.0f));
        glm::vec3 colour = 0.5f * T + 0.5f;
        if (mirrored && ((x + y) / stripe) % 3 == 0) colour *= 0.25f;
        put(out, x, y, colour);
      }
    }
  }
  for (std::size_t t = 0; t < surface.triangle_count(); ++t) {
    for (int e = 0; e < 3; ++e) {
      const glm::vec2 a = to_pixel(surface.uv[3 * t + e]), b = to_pixel(surface.uv[3 * t + (e + 1) % 3]);
      draw_line(out, a, b, 1, glm::vec3(0.05f), [](float, int, int) { return true; });
    }
  }
  return Status::ok();
}

}  // namespace nmbake
