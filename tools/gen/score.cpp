#include "score.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include "nmbake/encode.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/trace.hpp"

namespace nmbake::scenes {

namespace {

// atan2(|a x b|, a . b) in double: acos of a float dot product cannot
// resolve angles below ~0.02 degrees, which is where a good bake lives.
float angle_degrees(const glm::vec3& a, const glm::vec3& b) {
  const glm::dvec3 da(a), db(b);
  const double la = glm::length(da), lb = glm::length(db);
  if (!(la > 0.0) || !(lb > 0.0)) return 180.0f;
  const double radians = std::atan2(glm::length(glm::cross(da, db)), glm::dot(da, db));
  return static_cast<float>(radians * 180.0 / 3.14159265358979323846);
}

glm::vec3 decode(const Image& map, int x, int y) {
  const float* p = map.at(x, y);
  return glm::vec3(2.0f * p[0] - 1.0f, 2.0f * p[1] - 1.0f, 2.0f * p[2] - 1.0f);
}

std::size_t count_non_finite(const Image& map) {
  return static_cast<std::size_t>(
      std::count_if(map.pixels.begin(), map.pixels.end(), [](float v) { return !std::isfinite(v); }));
}

template <class V>
V lerp(const std::vector<V>& c, std::size_t base, glm::vec2 b) {
  return c[base] * (1.0f - b.x - b.y) + c[base + 1] * b.x + c[base + 2] * b.y;
}

}  // namespace

std::string AngularError::to_text() const {
  char line[256];
  std::snprintf(line, sizeof line,
                "texels %zu  mean %.4f  median %.4f  p95 %.4f  p99 %.4f  max %.3f deg  >1deg %.3f%%  >5deg "
                "%.3f%%  nan %zu",
                texels, mean, median, p95, p99, max, 100.0 * over_1deg, 100.0 * over_5deg, non_finite);
  return line;
}

AngularError summarize_errors(std::vector<float> e, std::size_t non_finite) {
  AngularError s;
  s.texels = e.size();
  s.non_finite = non_finite;
  if (e.empty()) return s;
  double sum = 0.0;
  std::size_t over1 = 0, over5 = 0;
  for (float v : e) {
    sum += v;
    over1 += v > 1.0f ? 1 : 0;
    over5 += v > 5.0f ? 1 : 0;
  }
  const double n = static_cast<double>(e.size());
  s.mean = sum / n;
  s.over_1deg = static_cast<double>(over1) / n;
  s.over_5deg = static_cast<double>(over5) / n;
  std::sort(e.begin(), e.end());
  auto q = [&](double f) { return e[std::min(e.size() - 1, static_cast<std::size_t>(f * n))]; };
  s.median = q(0.5);
  s.p95 = q(0.95);
  s.p99 = q(0.99);
  s.max = e.back();
  return s;
}

AngularError score_heightfield(const HeightfieldParams& params, const Image& map, int samples) {
  const std::vector<glm::vec2> offsets = sample_offsets(samples);
  std::vector<float> errors;
  errors.reserve(static_cast<std::size_t>(map.width) * map.height);
  for (int y = 0; y < map.height; ++y) {
    for (int x = 0; x < map.width; ++x) {
      glm::vec3 expected(0.0f);
      for (const glm::vec2& o : offsets) {
        const float u = (static_cast<float>(x) + o.x) / static_cast<float>(map.width);
        const float v = 1.0f - (static_cast<float>(y) + o.y) / static_cast<float>(map.height);
        expected += heightfield_normal(params, u * params.size, v * params.size);
      }
      errors.push_back(angle_degrees(decode(map, x, y), expected));
    }
  }
  return summarize_errors(std::move(errors), count_non_finite(map));
}

AngularError score_sphere(const SphereParams& params, const Mesh& low, const Image& map, int samples,
                          float front, float back) {
  SurfaceStats surface_stats;
  const LowSurface surface = build_low_surface(low, nullptr, surface_stats);
  TexelSamples raster;
  RasterStats raster_stats;
  rasterize(surface, map.width, map.height, samples, raster, raster_stats);
  RayOptions rays;
  rays.front = front;
  rays.back = back;

  std::vector<float> errors;
  for (int y = 0; y < map.height; ++y) {
    for (int x = 0; x < map.width; ++x) {
      const std::size_t texel = static_cast<std::size_t>(y) * map.width + x;
      if (!raster.coverage[texel]) continue;
      glm::vec3 expected(0.0f);
      glm::vec3 T0(0.0f), N0(0.0f);
      float sign0 = 1.0f;
      bool first = true;
      for (int k = 0; k < samples; ++k) {
        const std::size_t s = texel * samples + k;
        const std::int32_t tri = raster.triangle[s];
        if (tri < 0) continue;
        const glm::vec2 b = raster.bary[s];
        bool fallback = false;
        const Ray ray = make_ray(surface, tri, b, rays, fallback);
        // Bisection on g(t) = |p| - r(p / |p|), positive outside.
        auto g = [&](double t) {
          const glm::vec3 p = ray.origin + static_cast<float>(t) * ray.direction;
          return static_cast<double>(glm::length(p)) -
                 static_cast<double>(sphere_radius(params, glm::normalize(p)));
        };
        double lo = 0.0, hi = ray.tfar;
        if (!(g(lo) > 0.0 && g(hi) < 0.0)) continue;  // the analytic surface is out of reach: not scored
        for (int i = 0; i < 50; ++i) {
          const double mid = 0.5 * (lo + hi);
          (g(mid) > 0.0 ? lo : hi) = mid;
        }
        const glm::vec3 hit = ray.origin + static_cast<float>(0.5 * (lo + hi)) * ray.direction;
        const glm::vec3 truth = sphere_normal(params, glm::normalize(hit));
        const std::size_t base = 3 * static_cast<std::size_t>(tri);
        const glm::vec4 tw = lerp(surface.tangent, base, b);
        const glm::vec3 N = lerp(surface.normal, base, b);
        const float sign = tw.w < 0.0f ? -1.0f : 1.0f;
        glm::vec3 t;
        world_to_tangent(truth, glm::vec3(tw), N, sign, TangentEncode::inverse, t);
        expected += t;
        if (first) {
          T0 = glm::vec3(tw);
          N0 = N;
          sign0 = sign;
          first = false;
        }
      }
      if (first) continue;
      const glm::vec3 baked_world = tangent_to_world(decode(map, x, y), T0, N0, sign0);
      const glm::vec3 expected_world = tangent_to_world(glm::normalize(expected), T0, N0, sign0);
      errors.push_back(angle_degrees(baked_world, expected_world));
    }
  }
  return summarize_errors(std::move(errors), count_non_finite(map));
}

}  // namespace nmbake::scenes
