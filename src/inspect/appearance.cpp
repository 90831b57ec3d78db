// The appearance error of a map (appearance.hpp): Embree primary rays from
// fixed cameras onto the low and the high mesh (preview's camera and ray
// scenes), the map decoded as preview decodes it (MikkTSpace, Mikkelsen
// 2008), and the consensus of the high normals seen through every texel.
#include "nmbake/appearance.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <numeric>

#include "inspect/preview_draw.hpp"
#include "nmbake/preview.hpp"

namespace nmbake {

using namespace preview_detail;

namespace {

// atan2 of |a x b| and a.b in double: acos of a float dot product cannot
// resolve angles below ~0.02 degrees (a zero error must read as zero).
float angle_degrees(const glm::vec3& a, const glm::vec3& b) {
  const glm::dvec3 da(a), db(b);
  const double la = glm::length(da), lb = glm::length(db);
  if (!(la > 0.0) || !(lb > 0.0)) return 180.0f;
  return static_cast<float>(std::atan2(glm::length(glm::cross(da, db)), glm::dot(da, db)) *
                            57.29577951308232);
}

}  // namespace

// Sequential, in sample order: the same figures for any thread count.
AppearanceError summarize_appearance(std::vector<float> angles) {
  AppearanceError e;
  e.samples = angles.size();
  if (angles.empty()) return e;
  double sum = 0.0;
  for (float a : angles) sum += a;
  e.mean = sum / static_cast<double>(angles.size());
  const auto rank = [&](double q) {
    const std::size_t k = std::min(
        angles.size() - 1, static_cast<std::size_t>(std::ceil(q * static_cast<double>(angles.size()))) - 1);
    std::nth_element(angles.begin(), angles.begin() + static_cast<std::ptrdiff_t>(k), angles.end());
    return static_cast<double>(angles[k]);
  };
  e.p95 = rank(0.95);
  e.p99 = rank(0.99);
  e.max = *std::max_element(angles.begin(), angles.end());
  return e;
}

namespace {

std::uint32_t texel_of(glm::vec2 uv, int width, int height) {
  // Texel x covers u in [x / W, (x + 1) / W); row y covers v in
  // (1 - (y + 1) / H, 1 - y / H]. Clamped: UVs on or past the border.
  const float fx = std::floor(std::clamp(uv.x, 0.0f, 1.0f) * static_cast<float>(width));
  const float fy = std::floor(std::clamp(1.0f - uv.y, 0.0f, 1.0f) * static_cast<float>(height));
  const int x = std::clamp(static_cast<int>(fx), 0, width - 1);
  const int y = std::clamp(static_cast<int>(fy), 0, height - 1);
  return static_cast<std::uint32_t>(y) * static_cast<std::uint32_t>(width) + static_cast<std::uint32_t>(x);
}

}  // namespace

const std::vector<glm::vec2>& appearance_views() {
  static const std::vector<glm::vec2> views = [] {
    const float diagonal = 35.26439f;  // atan(1 / sqrt(2)): a cube diagonal
    std::vector<glm::vec2> v = {{0.0f, 0.0f},   {90.0f, 0.0f}, {180.0f, 0.0f},
                                {270.0f, 0.0f}, {0.0f, 89.0f}, {0.0f, -89.0f}};
    for (float pitch : {diagonal, -diagonal}) {
      for (float yaw : {45.0f, 135.0f, 225.0f, 315.0f}) v.push_back({yaw, pitch});
    }
    return v;
  }();
  return views;
}

std::string AppearanceError::to_text() const {
  char line[200];
  std::snprintf(line, sizeof line, "%zu samples, mean %.4f deg, p95 %.3f, p99 %.3f, max %.2f", samples, mean,
                p95, p99, max);
  return line;
}

Status render_appearance(const LowSurface& surface, const Mesh& high, int map_width, int map_height,
                         const AppearanceOptions& options, AppearanceSamples& out) {
  if (options.size < 16 || options.size > 4096)
    return Status::bad_input("view size out of range (16 to 4096)");
  if (options.supersample < 1 || options.supersample > 8)
    return Status::bad_input("supersampling out of range (1 to 8)");
  if (!(options.depth_tolerance > 0.0f) || !std::isfinite(options.depth_tolerance)) {
    return Status::bad_input("the depth tolerance must be a positive share of the diagonal");
  }
  if (map_width < 1 || map_height < 1) return Status::bad_input("the map needs at least one texel");
  NMBAKE_CHECK(high.has_normals(), "high mesh normals prepared");
  NMBAKE_CHECK(surface.triangle_count() > 0, "low surface built");

  LowSoup low_soup;
  NMBAKE_TRY(low_soup.build(surface));
  RayScene high_scene;
  NMBAKE_TRY(high_scene.build(high.positions, high.indices));

  Bounds bounds;
  bounds.min = bounds.max = surface.position.front();
  for (const glm::vec3& p : surface.position) {
    bounds.min = glm::min(bounds.min, p);
    bounds.max = glm::max(bounds.max, p);
  }
  const float tolerance = options.depth_tolerance * bounds.diagonal();
  const Framing framing = frame_points({&surface.position, &high.positions});

  out = AppearanceSamples{};
  out.map_width = map_width;
  out.map_height = map_height;
  out.size = options.size;
  out.supersample = options.supersample;
  out.depth_tolerance = tolerance;
  std::vector<RayHit> low_hits, high_hits;
  for (std::size_t v = 0; v < appearance_views().size(); ++v) {
    const glm::vec2 view_angles = appearance_views()[v];
    ViewOptions view;
    view.size = options.size;
    view.supersample = options.supersample;
    view.pitch_degrees = view_angles.y;
    view.up = UpAxis::y;
    const Camera camera = make_camera(framing, view, view_angles.x);
    trace_primary(low_soup.scene, camera, options.supersample, low_hits);
    trace_primary(high_scene, camera, options.supersample, high_hits);
    for (std::size_t s = 0; s < low_hits.size(); ++s) {
      const RayHit& low = low_hits[s];
      if (low.triangle < 0) continue;
      ++out.low_hits;
      const RayHit& hit = high_hits[s];
      if (hit.triangle < 0) {
        ++out.high_missed;
        continue;
      }
      if (!(std::fabs(hit.t - low.t) <= tolerance)) {
        ++out.depth_rejected;
        continue;
      }
      bool fallback = false;
      const glm::vec3 n = high_normal(high, hit.triangle, hit.bary, glm::vec3(0.0f, 0.0f, 1.0f), fallback);
      out.high_normal_fallbacks += fallback ? 1 : 0;
      const glm::vec2 uv = interpolate(surface.uv, 3 * static_cast<std::size_t>(low.triangle), low.bary);
      out.low_triangle.push_back(low.triangle);
      out.low_bary.push_back(low.bary);
      out.texel.push_back(texel_of(uv, map_width, map_height));
      out.high_normal.push_back(n);
      out.view.push_back(static_cast<std::uint8_t>(v));
      out.pixel.push_back(static_cast<std::uint32_t>(s));
    }
  }

  // In sample order: the same sums for any thread count.
  out.consensus.assign(static_cast<std::size_t>(map_width) * map_height, glm::vec3(0.0f));
  for (std::size_t s = 0; s < out.texel.size(); ++s) out.consensus[out.texel[s]] += out.high_normal[s];
  for (glm::vec3& c : out.consensus) {
    const float l = glm::length(c);
    c = l > 1e-12f && std::isfinite(l) ? c / l : glm::vec3(0.0f);
  }
  return Status::ok();
}

std::vector<float> appearance_angles(const AppearanceSamples& samples, const LowSurface& surface,
                                     const Image& map, NormalSpace space, GreenChannel green,
                                     std::uint64_t* decode_fallbacks) {
  NMBAKE_CHECK(map.channels >= 3 && map.width >= 1 && map.height >= 1, "a normal map");
  const std::size_t n = samples.sample_count();
  std::vector<float> angles(n);
  std::vector<std::uint8_t> fallbacks(n, 0);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t s) {
    bool fallback = false;
    const glm::vec3 decoded = decode_map_normal(surface, map, samples.low_triangle[s], samples.low_bary[s],
                                                space, green, glm::vec3(0.0f, 0.0f, 1.0f), fallback);
    fallbacks[s] = fallback ? 1 : 0;
    angles[s] = angle_degrees(decoded, samples.high_normal[s]);
  });
  if (decode_fallbacks != nullptr) {
    *decode_fallbacks = static_cast<std::uint64_t>(std::count(fallbacks.begin(), fallbacks.end(), 1));
  }
  return angles;
}

std::vector<float> appearance_angles_without_map(const AppearanceSamples& samples,
                                                 const LowSurface& surface) {
  const std::size_t n = samples.sample_count();
  std::vector<float> angles(n);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t s) {
    const glm::vec3 N = interpolate(surface.normal, 3 * static_cast<std::size_t>(samples.low_triangle[s]),
                                    samples.low_bary[s]);
    angles[s] = angle_degrees(N, samples.high_normal[s]);
  });
  return angles;
}

std::vector<float> appearance_floor_angles(const AppearanceSamples& samples) {
  const std::size_t n = samples.sample_count();
  std::vector<float> angles(n);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t s) {
    angles[s] = angle_degrees(samples.consensus[samples.texel[s]], samples.high_normal[s]);
  });
  return angles;
}

AppearanceError appearance_error(const AppearanceSamples& samples, const LowSurface& surface,
                                 const Image& map, NormalSpace space, GreenChannel green) {
  std::uint64_t fallbacks = 0;
  AppearanceError e =
      summarize_appearance(appearance_angles(samples, surface, map, space, green, &fallbacks));
  e.decode_fallbacks = fallbacks;
  return e;
}

AppearanceError appearance_without_map(const AppearanceSamples& samples, const LowSurface& surface) {
  return summarize_appearance(appearance_angles_without_map(samples, surface));
}

AppearanceError appearance_floor(const AppearanceSamples& samples) {
  return summarize_appearance(appearance_floor_angles(samples));
}

Image appearance_heat(const AppearanceSamples& samples, const std::vector<const std::vector<float>*>& columns,
                      float heat_max) {
  const int size = samples.size, k = samples.supersample;
  const int views = static_cast<int>(appearance_views().size());
  const int gap = 2;
  const int panels = static_cast<int>(columns.size());
  Image out{panels * size + (panels - 1) * gap, views * size + (views - 1) * gap, 3, {}};
  out.pixels.assign(static_cast<std::size_t>(out.width) * out.height * 3, 0.0f);
  fill_rect(out, 0, 0, out.width, out.height, glm::vec3(0.04f));
  const std::size_t grid = static_cast<std::size_t>(size) * k;
  for (int c = 0; c < panels; ++c) {
    NMBAKE_CHECK(columns[c]->size() == samples.sample_count(), "an angle per compared sample");
    // Sums per pixel of each view, in sample order.
    std::vector<float> sum(static_cast<std::size_t>(views) * size * size, 0.0f);
    std::vector<std::uint16_t> count(sum.size(), 0);
    for (std::size_t s = 0; s < samples.sample_count(); ++s) {
      const std::size_t row = samples.pixel[s] / grid, col = samples.pixel[s] % grid;
      const std::size_t p = (static_cast<std::size_t>(samples.view[s]) * size + row / k) * size + col / k;
      sum[p] += (*columns[c])[s];
      ++count[p];
    }
    for (int v = 0; v < views; ++v) {
      for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
          const std::size_t p = (static_cast<std::size_t>(v) * size + y) * size + x;
          const glm::vec3 colour =
              count[p] > 0 ? heat_colour(sum[p] / static_cast<float>(count[p]) / heat_max) : kBackground;
          float* o = out.at(c * (size + gap) + x, v * (size + gap) + y);
          for (int ch = 0; ch < 3; ++ch) o[ch] = colour[ch];
        }
      }
    }
  }
  return out;
}

}  // namespace nmbake
