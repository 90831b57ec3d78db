// Maps of directions: the normal map (the encode stage, unchanged), the
// object-space normal beside it, and the bent normal (the mean unoccluded AO
// direction), encoded as the normal map is: exact inverse of the MikkTSpace
// decode in tangent space, per sample normalised, averaged per texel and
// renormalised, rgb = 0.5 n + 0.5.
//
// The high's normal textures (HighNormalMaps, encode.hpp) change the hit
// normal of the normal and object-space normal maps: at a hit on a triangle
// whose material has a normal texture, the texture is sampled as the
// transfer maps sample theirs (trilinear, the texel's footprint:
// textures.hpp), read as data, t = 2 rgb - 1, +Y up (OpenGL, as glTF), x and
// y times the material's scale (glTF normalTexture.scale), renormalised; and
// decoded as MikkTSpace's per-pixel decode does in the high's own frame:
// n = normalize(t.x T + t.y B + t.z N), T the high's tangent and N its
// normal interpolated (not normalised), B = sign cross(N, T). The result is
// then encoded in the low's frame as any hit normal. Every sample that
// cannot be perturbed keeps the high normal of a bake without, counted.
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <mutex>

#include "maps/modules.hpp"

namespace nmbake {

namespace {

using maps_detail::interpolate;

// The world normal of sample s perturbed by its hit material's normal
// texture (see the top of this file), or (0, 0, 0): no texture, or a
// fallback (counted in `stats`).
glm::vec3 perturbed_normal(const BandInputs& in, const MapSettings& settings, const std::vector<float>& sides,
                           std::size_t s, EncodeStats& stats) {
  const std::int32_t low = in.samples.triangle[s], hit = in.hits.triangle[s];
  if (low < 0 || hit < 0) return glm::vec3(0.0f);
  const SurfaceTransfer& transfer = *settings.transfer;
  const auto tri = static_cast<std::size_t>(hit);
  const std::uint32_t material = transfer.triangle_material[tri];
  const int texture = transfer.material_textures[material].normal;
  if (texture < 0) return glm::vec3(0.0f);
  ++stats.high_normal_map_samples;
  const float density = transfer.uv_density[tri];
  if (!(density > 0.0f)) {
    ++stats.high_normal_map_no_uv;  // no UV area: no texture to read, no tangent
    return glm::vec3(0.0f);
  }
  const glm::vec2 hb = in.hits.bary[s];
  const std::uint32_t* h = &in.high.indices[3 * tri];
  glm::vec3 N(0.0f);
  bool smooth = false;
  if (settings.encode.high_normals == HighNormals::smooth && in.high.has_normals()) {
    N = in.high.normals[h[0]] * (1.0f - hb.x - hb.y) + in.high.normals[h[1]] * hb.x +
        in.high.normals[h[2]] * hb.y;
    const float l2 = glm::dot(N, N);
    smooth = l2 > 1e-24f && std::isfinite(l2);
  }
  if (!smooth) {  // the face normal, as the encode takes it
    N = glm::cross(in.high.positions[h[1]] - in.high.positions[h[0]],
                   in.high.positions[h[2]] - in.high.positions[h[0]]);
  }
  const glm::vec4 tw = interpolate(transfer.corner_tangent, 3 * tri, hb);
  const glm::vec3 T(tw);
  const glm::vec3 C = glm::cross(N, T);
  const float c2 = glm::dot(C, C), scale2 = glm::dot(N, N) * glm::dot(T, T);
  if (!(c2 > 1e-12f * scale2) || !(scale2 > 0.0f) || !std::isfinite(c2) || !std::isfinite(scale2)) {
    ++stats.high_normal_map_degenerate_tangent;
    return glm::vec3(0.0f);
  }
  const glm::vec3 B = (tw.w < 0.0f ? -1.0f : 1.0f) * C;
  const Material& m = transfer.materials[material];
  const float footprint = sides[static_cast<std::size_t>(low)] * density;
  bool missing = false;
  const glm::vec4 texel = sample_texture(transfer.textures.textures[static_cast<std::size_t>(texture)],
                                         m.normal_texture, interpolate(transfer.corner_uv, 3 * tri, hb),
                                         std::isfinite(footprint) ? footprint : 0.0f, missing);
  if (missing) {
    ++stats.high_normal_map_tile_missing;
    return glm::vec3(0.0f);
  }
  glm::vec3 t = 2.0f * glm::vec3(texel) - 1.0f;
  t.x *= m.normal_scale;
  t.y *= m.normal_scale;
  const float lt = glm::length(t);
  const glm::vec3 n = lt > 1e-6f && std::isfinite(lt) ? (t.x * T + t.y * B + t.z * N) / lt : glm::vec3(0.0f);
  const float ln = glm::length(n);
  if (!(ln > 1e-12f) || !std::isfinite(ln)) {
    ++stats.high_normal_map_zero_normal;
    return glm::vec3(0.0f);
  }
  return n / ln;
}

// Row block by row block (by_rows()): the encode stage's encode_rows(),
// with the high's normal textures applied first when the bake reads them.
struct NormalModule final : MapSet::Module {
  bool object;
  std::once_flag sides_once;
  std::vector<float> sides;  // low_sample_sides(), for the normal textures' footprint
  // Per thread, the hit normals of a block of rows (allocated once: a
  // block's 200 KB freed and mapped again each time was page faults).
  tbb::enumerable_thread_specific<std::vector<glm::vec3>> hit_normal_buffers;
  NormalModule(MapKind map, bool object_space) : Module(map), object(object_space) {}
  void encode_band(const BandInputs&, const MapSettings&, EncodeStats&) override {}
  bool by_rows() const override { return true; }
  void encode_rows(const BandInputs& in, const MapSettings& settings, int row_begin, int row_end,
                   EncodeStats& stats) override {
    EncodeOptions options = settings.encode;
    if (object) {
      options.space = NormalSpace::object;
      options.green = GreenChannel::up;
    }
    const glm::vec3* given = nullptr;
    if (settings.transfer != nullptr && settings.transfer->normal_maps()) {
      std::call_once(sides_once, [&] {
        sides = maps_detail::low_sample_sides(in.surface, in.samples.width, settings.map_height,
                                              in.samples.samples);
      });
      const std::size_t row_samples = static_cast<std::size_t>(in.samples.width) * in.samples.samples;
      const std::size_t first = static_cast<std::size_t>(row_begin) * row_samples;
      std::vector<glm::vec3>& hit_normals = hit_normal_buffers.local();
      hit_normals.resize(
          std::max(hit_normals.size(), static_cast<std::size_t>(row_end - row_begin) * row_samples));
      for (std::size_t i = 0; i < static_cast<std::size_t>(row_end - row_begin) * row_samples; ++i)
        hit_normals[i] = perturbed_normal(in, settings, sides, first + i, stats);
      given = hit_normals.data();
    }
    nmbake::encode_rows(in.surface, in.samples, in.high, in.hits, options, image, stats, row_begin, row_end,
                        given);
  }
  void rows_encoded(const EncodeStats& band, EncodeStats& normal_stats) override {
    if (!object) {
      normal_stats.add(band);
      return;
    }
    add("zero_high_normals", static_cast<double>(band.zero_high_normals));
    add("zero_results", static_cast<double>(band.zero_results));
    if (band.high_normal_map_samples > 0) {
      add("high_normal_map_samples", static_cast<double>(band.high_normal_map_samples));
      add("high_normal_map_no_uv", static_cast<double>(band.high_normal_map_no_uv));
      add("high_normal_map_degenerate_tangent", static_cast<double>(band.high_normal_map_degenerate_tangent));
      add("high_normal_map_zero_normal", static_cast<double>(band.high_normal_map_zero_normal));
      add("high_normal_map_tile_missing", static_cast<double>(band.high_normal_map_tile_missing));
    }
  }
};

struct BentNormalModule final : MapSet::Module {
  BentNormalModule() : Module(MapKind::bent_normal) {}
  void encode_band(const BandInputs& in, const MapSettings& settings, EncodeStats&) override {
    const TexelSamples& samples = in.samples;
    const bool tangent = settings.encode.space == NormalSpace::tangent;
    const bool flip_green = tangent && settings.encode.green == GreenChannel::down;
    const int width = samples.width, spp = samples.samples;
    const glm::vec3 background = tangent ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(0.0f);
    std::vector<std::uint64_t> singular(static_cast<std::size_t>(samples.height), 0);
    std::vector<std::uint64_t> zero(static_cast<std::size_t>(samples.height), 0);
    tbb::parallel_for(tbb::blocked_range<int>(0, samples.height), [&](const tbb::blocked_range<int>& rows) {
      for (int y = rows.begin(); y != rows.end(); ++y) {
        float* out = image.pixels.data() + static_cast<std::size_t>(in.out_row + y) * width * 3;
        for (int x = 0; x < width; ++x) {
          const std::size_t texel = static_cast<std::size_t>(y) * width + x;
          glm::vec3 value = background;
          if (samples.coverage[texel]) {
            glm::vec3 sum(0.0f), low_sum(0.0f);
            for (int k = 0; k < spp; ++k) {
              const std::size_t s = texel * spp + static_cast<std::size_t>(k);
              const std::int32_t tri = samples.triangle[s];
              if (tri < 0) continue;
              const std::size_t base = 3 * static_cast<std::size_t>(tri);
              const glm::vec2 b = samples.bary[s];
              const glm::vec3 N = interpolate(in.surface.normal, base, b);
              low_sum += N;
              if (in.hits.triangle[s] < 0) {
                // A miss keeps the low surface's own normal, as the normal map.
                const float l = glm::length(N);
                sum += tangent ? glm::vec3(0.0f, 0.0f, 1.0f) : (l > 0.0f && std::isfinite(l) ? N / l : N);
                continue;
              }
              const glm::vec3 d = (*in.bent)[s];
              if (!tangent) {
                sum += d;
                continue;
              }
              const glm::vec4 tw = interpolate(in.surface.tangent, base, b);
              glm::vec3 t;
              if (!world_to_tangent(d, glm::vec3(tw), N, tw.w < 0.0f ? -1.0f : 1.0f,
                                    settings.encode.tangent_encode, t)) {
                ++singular[static_cast<std::size_t>(y)];
              }
              sum += t;
            }
            const float l = glm::length(sum);
            if (l > 1e-12f && std::isfinite(l)) {
              value = sum / l;
            } else {
              ++zero[static_cast<std::size_t>(y)];
              const float ll = glm::length(low_sum);
              value =
                  tangent || !(ll > 0.0f && std::isfinite(ll)) ? glm::vec3(0.0f, 0.0f, 1.0f) : low_sum / ll;
            }
            if (flip_green) value.y = -value.y;
          }
          float* p = out + static_cast<std::size_t>(x) * 3;
          p[0] = 0.5f * value.x + 0.5f;
          p[1] = 0.5f * value.y + 0.5f;
          p[2] = 0.5f * value.z + 0.5f;
        }
      }
    });
    std::uint64_t singular_count = 0, zero_count = 0;
    for (std::size_t y = 0; y < singular.size(); ++y) {
      singular_count += singular[y];
      zero_count += zero[y];
    }
    add("singular_frames", static_cast<double>(singular_count));
    add("zero_results", static_cast<double>(zero_count));
  }
};

}  // namespace

std::unique_ptr<MapSet::Module> make_direction_module(MapKind map) {
  switch (map) {
    case MapKind::normal:
      return std::make_unique<NormalModule>(map, false);
    case MapKind::object_normal:
      return std::make_unique<NormalModule>(map, true);
    case MapKind::bent_normal:
      return std::make_unique<BentNormalModule>();
    default:
      return nullptr;
  }
}

}  // namespace nmbake
