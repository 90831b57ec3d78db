// The 3D preview sheet: the high mesh and the low mesh with its normal map,
// lit the same way (Blinn-Phong, Blinn 1977), and the angular error of the
// map as a heat map. The map is decoded as a MikkTSpace renderer does
// (Mikkelsen 2008, per-pixel bitangent): n = normalize(t.x T + t.y B + t.z N)
// with T, N interpolated and not normalised and B = sign cross(N, T). The
// reference normal of the heat map is found with the baker's own rays
// (trace.hpp), so the panel measures the bake, not the silhouettes.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numeric>

#include "inspect/preview_draw.hpp"
#include "nmbake/load.hpp"
#include "nmbake/parts.hpp"
#include "nmbake/preview.hpp"

namespace nmbake {

using namespace preview_detail;

Status validate_view_options(const ViewOptions& v) {
  if (v.size < 16 || v.size > 4096) {
    return Status::bad_input("--size " + std::to_string(v.size) + " is out of range (16 to 4096)");
  }
  if (!std::isfinite(v.yaw_degrees)) return Status::bad_input("--yaw must be a finite number of degrees");
  if (!(v.pitch_degrees >= -89.0f && v.pitch_degrees <= 89.0f)) {
    return Status::bad_input("--pitch must be within -89 to 89 degrees");
  }
  const float l = glm::length(v.light);
  if (!(l > 1e-6f) || !std::isfinite(l))
    return Status::bad_input("--light must be a non-zero finite direction");
  if (v.supersample < 1 || v.supersample > 8)
    return Status::bad_input("supersampling must be 1 to 8 per axis");
  return Status::ok();
}

Status load_preview_meshes(const std::string& low_path, const std::string& high_path, Mesh& low,
                           LowSurface& surface, Mesh& high) {
  LoadStats load_stats;
  NMBAKE_TRY(load_mesh(low_path, LoadOptions{true, true}, low, load_stats));
  if (!low.has_uvs()) {
    return Status::bad_input(low_path +
                             ": the low mesh has no UV coordinates; a normal map needs a UV layout");
  }
  MeshStats mesh_stats;
  prepare_low_normals(low, mesh_stats);
  SurfaceStats surface_stats;
  surface = build_low_surface(low, nullptr, surface_stats);
  if (!high_path.empty()) {
    NMBAKE_TRY(load_mesh(high_path, LoadOptions{false, true}, high, load_stats));
    if (high.has_normals()) {
      normalize_normals(high, mesh_stats);
    } else {
      compute_vertex_normals(high, mesh_stats);
    }
    pad_for_embree(high);
  }
  return Status::ok();
}

namespace {

Bounds bounds_of(const std::vector<glm::vec3>& points) {
  Bounds b;
  if (points.empty()) return b;
  b.min = b.max = points[0];
  for (const glm::vec3& p : points) {
    b.min = glm::min(b.min, p);
    b.max = glm::max(b.max, p);
  }
  return b;
}

// Bilinear, texel centres at u = (x + 0.5) / W, v = 1 - (y + 0.5) / H,
// clamped at the borders (the baker's padding lies inside the map).
glm::vec3 sample_map(const Image& map, glm::vec2 uv) {
  // Clamped first, so absurd (huge but finite) UVs cannot give inf - inf.
  const float px =
      std::clamp(uv.x * static_cast<float>(map.width) - 0.5f, -1.0f, static_cast<float>(map.width));
  const float py = std::clamp((1.0f - uv.y) * static_cast<float>(map.height) - 0.5f, -1.0f,
                              static_cast<float>(map.height));
  const float fx0 = std::floor(px), fy0 = std::floor(py);
  const float wx = px - fx0, wy = py - fy0;
  auto clamp_x = [&](float x) {
    return static_cast<int>(std::clamp(x, 0.0f, static_cast<float>(map.width - 1)));
  };
  auto clamp_y = [&](float y) {
    return static_cast<int>(std::clamp(y, 0.0f, static_cast<float>(map.height - 1)));
  };
  const int x0 = clamp_x(fx0), x1 = clamp_x(fx0 + 1.0f), y0 = clamp_y(fy0), y1 = clamp_y(fy0 + 1.0f);
  auto texel = [&](int x, int y) {
    const float* p = map.at(x, y);
    return glm::vec3(p[0], p[1], p[2]);
  };
  return (texel(x0, y0) * (1.0f - wx) + texel(x1, y0) * wx) * (1.0f - wy) +
         (texel(x0, y1) * (1.0f - wx) + texel(x1, y1) * wx) * wy;
}

glm::vec3 unit_or(const glm::vec3& v, const glm::vec3& fallback, bool& used_fallback) {
  const float l = glm::length(v);
  if (l > 1e-12f && std::isfinite(l)) return v / l;
  used_fallback = true;
  return fallback;
}

constexpr float kRadToDeg = 57.29577951308232f;
const glm::vec3 kMissColour{0.9f, 0.1f, 0.85f};
const glm::vec3 kGapColour{0.04f, 0.04f, 0.045f};
const glm::vec3 kTextColour{0.95f, 0.95f, 0.92f};

struct AngleSummary {
  double mean = 0.0, p99 = 0.0, max = 0.0;
};

// Sequential, in sample order: the same numbers for any thread count.
AngleSummary summarize(std::vector<float> angles) {
  AngleSummary s;
  if (angles.empty()) return s;
  double sum = 0.0;
  for (float a : angles) sum += a;
  s.mean = sum / static_cast<double>(angles.size());
  const std::size_t k =
      std::min(angles.size() - 1, static_cast<std::size_t>(0.99 * static_cast<double>(angles.size())));
  std::nth_element(angles.begin(), angles.begin() + static_cast<std::ptrdiff_t>(k), angles.end());
  s.p99 = angles[k];
  s.max = *std::max_element(angles.begin(), angles.end());
  return s;
}

void blit(Image& sheet, const Image& panel, int ox, int oy) {
  for (int y = 0; y < panel.height; ++y) {
    for (int x = 0; x < panel.width; ++x) {
      const float* src = panel.at(x, y);
      float* dst = sheet.at(ox + x, oy + y);
      for (int c = 0; c < 3; ++c) dst[c] = src[c];
    }
  }
}

Image make_panel(int size, const glm::vec3& colour) {
  Image p{size, size, 3, {}};
  p.pixels.resize(static_cast<std::size_t>(size) * size * 3);
  for (std::size_t i = 0; i < p.pixels.size(); ++i) p.pixels[i] = colour[i % 3];
  return p;
}

// The scale bar along the bottom of the heat panel: "0 [ramp] MAX deg".
void draw_scale_bar(Image& panel, float heat_max, int scale) {
  const int margin = 3 * scale;
  const std::string left = "0";
  const std::string right = format_number(heat_max, heat_max == std::floor(heat_max) ? 0 : 1) + " deg";
  const int y = panel.height - margin - 8 * scale;
  draw_text(panel, margin, y, left, scale, kTextColour);
  const int right_x = panel.width - margin - text_width(right, scale);
  draw_text(panel, right_x, y, right, scale, kTextColour);
  const int x0 = margin + text_width(left, scale) + 2 * scale;
  const int x1 = right_x - 2 * scale;
  if (x1 <= x0) return;
  const int y0 = y + scale, y1 = y + 6 * scale;
  fill_rect(panel, x0 - 1, y0 - 1, x1 + 1, y1 + 1, glm::vec3(0.02f));
  for (int x = x0; x < x1; ++x) {
    const float f = (static_cast<float>(x - x0) + 0.5f) / static_cast<float>(x1 - x0);
    fill_rect(panel, x, y0, x + 1, y1, heat_colour(f));
  }
}

}  // namespace

glm::vec3 decode_map_normal(const LowSurface& surface, const Image& map, std::int32_t tri, glm::vec2 b,
                            NormalSpace space, GreenChannel green, const glm::vec3& otherwise, bool& fallback,
                            const NormalDecode& decode) {
  const std::size_t base = 3 * static_cast<std::size_t>(tri);
  const glm::vec3 N = interpolate(surface.normal, base, b);
  const glm::vec4 tw = interpolate(surface.tangent, base, b);
  const glm::vec2 uv = interpolate(surface.uv, base, b);
  glm::vec3 t = 2.0f * sample_map(map, uv) - 1.0f;
  const glm::vec3 low_normal = unit_or(N, otherwise, fallback);
  if (space != NormalSpace::tangent) return unit_or(t, low_normal, fallback);
  if (green == GreenChannel::down) t.y = -t.y;
  if (decode.is_default()) {
    const glm::vec3 T(tw);
    const float sign = tw.w < 0.0f ? -1.0f : 1.0f;
    const glm::vec3 raw = t.x * T + t.y * (sign * glm::cross(N, T)) + t.z * N;
    const float l = glm::length(raw);
    if (l > 1e-12f && std::isfinite(l)) return tangent_to_world(t, T, N, sign);
    fallback = true;
    return low_normal;
  }
  // Another engine's decode (preset.hpp): z from the filtered x, y, B per
  // vertex, the frame normalised, as `decode` says.
  if (decode.rebuild_blue) t.z = std::sqrt(std::max(0.0f, 1.0f - t.x * t.x - t.y * t.y));
  glm::vec3 T(tw), B = decode_bitangent(surface, static_cast<std::size_t>(tri), b, decode.bitangent), M = N;
  bool usable = true;
  if (decode.unit_frame) {
    for (glm::vec3* column : {&T, &B, &M}) {
      const float lc = glm::length(*column);
      usable = usable && lc > 1e-12f && std::isfinite(lc);
      if (usable) *column /= lc;
    }
  }
  const glm::vec3 raw = t.x * T + t.y * B + t.z * M;
  const float l = glm::length(raw);
  if (usable && l > 1e-12f && std::isfinite(l)) return raw / l;
  fallback = true;
  return low_normal;
}

Status render_preview(const LowSurface& surface, const Mesh& high, const Image& map,
                      const PreviewOptions& options, Image& sheet, PreviewStats& stats) {
  NMBAKE_TRY(validate_view_options(options.view));
  if (options.turntable < 1 || options.turntable > 64)
    return Status::bad_input("--turntable must be 1 to 64");
  if (!(options.heat_max_degrees > 0.0f) || !std::isfinite(options.heat_max_degrees)) {
    return Status::bad_input("--heat-max must be a positive number of degrees");
  }
  if (map.channels < 3 || map.width < 1 || map.height < 1) {
    return Status::bad_input("the normal map needs 3 channels and at least one texel");
  }
  NMBAKE_CHECK(high.has_normals(), "high mesh normals prepared");
  NMBAKE_CHECK(surface.triangle_count() > 0, "low surface built");
  stats = PreviewStats{};

  // Primary-ray scenes: the low corners as a triangle soup (triangle id =
  // low triangle), the high mesh on its own buffers.
  LowSoup low_soup;
  NMBAKE_TRY(low_soup.build(surface));
  RayScene high_scene;
  NMBAKE_TRY(high_scene.build(high.positions, high.indices));
  // The baker's own scene and rays for the reference normals.
  HighScene bake_scene;
  NMBAKE_TRY(HighScene::build(high, BuildQuality::medium, options.rays.ignore_backfaces, bake_scene));

  const Bounds low_bounds = bounds_of(surface.position);
  const float diagonal = low_bounds.diagonal();
  // The rays on a copy of the surface: the banded cage prepares its edge
  // band on it (the panels read `surface` itself).
  LowSurface ray_surface = surface;
  RayOptions rays;
  resolve_rays(options.rays, bake_scene, ray_surface, diagonal, 0, rays);
  stats.front = rays.front;
  stats.back = rays.back;

  const Framing framing = frame_points({&surface.position, &high.positions});

  const int size = options.view.size;
  const int k = options.view.supersample;
  const int grid = size * k;
  const std::size_t sample_count = static_cast<std::size_t>(grid) * grid;
  const int views = options.turntable;
  const int gap = std::max(2, size / 48);
  const int text_scale = std::max(1, size / 192);
  sheet = Image{3 * size + 2 * gap, views * size + (views - 1) * gap, 3, {}};
  sheet.pixels.assign(static_cast<std::size_t>(sheet.width) * sheet.height * 3, 0.0f);
  fill_rect(sheet, 0, 0, sheet.width, sheet.height, kGapColour);

  std::vector<float> all_angles;
  std::vector<RayHit> low_hits, high_hits;
  std::vector<glm::vec3> high_colour(sample_count), low_colour(sample_count);
  std::vector<float> angle(sample_count);  // degrees; -1: no low surface; -2: bake ray missed
  std::vector<std::uint64_t> row_decode_fallbacks(grid), row_high_fallbacks(grid);

  for (int v = 0; v < views; ++v) {
    const float yaw = options.view.yaw_degrees + 360.0f * static_cast<float>(v) / static_cast<float>(views);
    const Camera camera = make_camera(framing, options.view, yaw);
    const Lights lights = make_lights(camera, options.view);
    trace_primary(low_soup.scene, camera, k, low_hits);
    trace_primary(high_scene, camera, k, high_hits);

    // The bake rays from every low point seen, traced exactly as the baker does.
    TexelSamples bake_samples;
    bake_samples.width = grid;
    bake_samples.height = grid;
    bake_samples.samples = 1;
    bake_samples.triangle.resize(sample_count);
    bake_samples.bary.resize(sample_count);
    bake_samples.coverage.resize(sample_count);
    for (std::size_t s = 0; s < sample_count; ++s) {
      bake_samples.triangle[s] = low_hits[s].triangle;
      bake_samples.bary[s] = low_hits[s].bary;
      bake_samples.coverage[s] = low_hits[s].triangle >= 0 ? 1 : 0;
    }
    Hits bake_hits;
    TraceStats trace_stats;
    trace(bake_scene, ray_surface, bake_samples, rays, bake_hits, trace_stats);

    std::fill(row_decode_fallbacks.begin(), row_decode_fallbacks.end(), 0);
    std::fill(row_high_fallbacks.begin(), row_high_fallbacks.end(), 0);
    tbb::parallel_for(0, grid, [&](int row) {
      for (int col = 0; col < grid; ++col) {
        const std::size_t s = static_cast<std::size_t>(row) * grid + col;
        const glm::vec2 p = sample_position(s, size, k);
        const glm::vec3 to_eye = -camera.direction(p.x, p.y);
        high_colour[s] = kBackground;
        low_colour[s] = kBackground;
        angle[s] = -1.0f;
        if (high_hits[s].triangle >= 0) {
          bool fallback = false;
          const glm::vec3 n = high_normal(high, high_hits[s].triangle, high_hits[s].bary, to_eye, fallback);
          row_high_fallbacks[row] += fallback ? 1 : 0;
          high_colour[s] = shade(n, to_eye, lights);
        }
        const std::int32_t tri = low_hits[s].triangle;
        if (tri < 0) continue;
        const std::size_t base = 3 * static_cast<std::size_t>(tri);
        const glm::vec2 b = low_hits[s].bary;
        bool fallback = false;
        const glm::vec3 low_normal = unit_or(interpolate(surface.normal, base, b), to_eye, fallback);
        const glm::vec3 n = decode_map_normal(surface, map, tri, b, options.space, options.green, to_eye,
                                              fallback, options.decode);
        row_decode_fallbacks[row] += fallback ? 1 : 0;
        low_colour[s] = shade(n, to_eye, lights);
        const std::int32_t hit = bake_hits.triangle[s];
        if (hit < 0) {
          angle[s] = -2.0f;
          continue;
        }
        bool high_fallback = false;
        const glm::vec3 reference = high_normal(high, hit, bake_hits.bary[s], low_normal, high_fallback);
        row_high_fallbacks[row] += high_fallback ? 1 : 0;
        angle[s] = std::acos(std::clamp(glm::dot(n, reference), -1.0f, 1.0f)) * kRadToDeg;
      }
    });
    for (int row = 0; row < grid; ++row) {
      stats.decode_fallbacks += row_decode_fallbacks[row];
      stats.high_normal_fallbacks += row_high_fallbacks[row];
    }

    // Pixels: the mean of their k x k samples.
    Image high_panel = make_panel(size, kBackground), low_panel = high_panel, heat_panel = high_panel;
    const float inv = 1.0f / static_cast<float>(k * k);
    tbb::parallel_for(0, size, [&](int y) {
      for (int x = 0; x < size; ++x) {
        glm::vec3 h(0.0f), l(0.0f), e(0.0f);
        for (int j = 0; j < k; ++j) {
          for (int i = 0; i < k; ++i) {
            const std::size_t s =
                static_cast<std::size_t>(y * k + j) * grid + static_cast<std::size_t>(x * k + i);
            h += high_colour[s];
            l += low_colour[s];
            e += angle[s] == -1.0f   ? kBackground
                 : angle[s] == -2.0f ? kMissColour
                                     : heat_colour(angle[s] / options.heat_max_degrees);
          }
        }
        for (int c = 0; c < 3; ++c) {
          high_panel.at(x, y)[c] = h[c] * inv;
          low_panel.at(x, y)[c] = l[c] * inv;
          heat_panel.at(x, y)[c] = e[c] * inv;
        }
      }
    });

    PreviewViewStats vs;
    vs.yaw_degrees = yaw;
    std::vector<float> angles;
    for (std::size_t s = 0; s < sample_count; ++s) {
      if (angle[s] == -1.0f) continue;
      ++vs.low_samples;
      if (angle[s] == -2.0f) {
        ++vs.bake_misses;
        continue;
      }
      angles.push_back(angle[s]);
    }
    all_angles.insert(all_angles.end(), angles.begin(), angles.end());
    const AngleSummary summary = summarize(std::move(angles));
    vs.mean_degrees = summary.mean;
    vs.p99_degrees = summary.p99;
    vs.max_degrees = summary.max;
    stats.views.push_back(vs);
    stats.all.low_samples += vs.low_samples;
    stats.all.bake_misses += vs.bake_misses;

    // Labels and the numbers.
    const int margin = 3 * text_scale;
    const int line = 10 * text_scale;
    draw_text(high_panel, margin, margin, "high", text_scale, kTextColour);
    draw_text(low_panel, margin, margin, "low+map", text_scale, kTextColour);
    if (views > 1) {
      const float shown = std::fmod(std::fmod(yaw, 360.0f) + 360.0f, 360.0f);
      draw_text(high_panel, margin, margin + line, "yaw " + format_number(shown, 0), text_scale, kTextColour);
    }
    draw_text(heat_panel, margin, margin, "mean " + format_number(vs.mean_degrees, 2) + " deg", text_scale,
              kTextColour);
    draw_text(heat_panel, margin, margin + line, "p99 " + format_number(vs.p99_degrees, 2) + " deg",
              text_scale, kTextColour);
    if (vs.bake_misses > 0) {
      const double share = 100.0 * static_cast<double>(vs.bake_misses) / static_cast<double>(vs.low_samples);
      draw_text(heat_panel, margin, margin + 2 * line, "miss " + format_number(share, 1) + "%", text_scale,
                kMissColour);
    }
    draw_scale_bar(heat_panel, options.heat_max_degrees, text_scale);

    const int oy = v * (size + gap);
    blit(sheet, high_panel, 0, oy);
    blit(sheet, low_panel, size + gap, oy);
    blit(sheet, heat_panel, 2 * (size + gap), oy);
  }
  const AngleSummary summary = summarize(std::move(all_angles));
  stats.all.mean_degrees = summary.mean;
  stats.all.p99_degrees = summary.p99;
  stats.all.max_degrees = summary.max;
  return Status::ok();
}

}  // namespace nmbake
