// The texture transfer maps (maps.hpp: base-color, roughness, metallic,
// emissive, opacity): at each hit, the high triangle's material, its UV one
// interpolation away, the material's factor times its texture sampled with
// the texel's footprint (textures.hpp). Figures: samples whose material has
// no texture for the map (the factor alone: a high part without the
// texture, or without a material definition) and samples whose UV fell in a
// UDIM tile the texture lacks (black).
#include <atomic>
#include <cmath>
#include <glm/geometric.hpp>

#include "maps/modules.hpp"
#include "nmbake/textures.hpp"

namespace nmbake {
namespace {

using maps_detail::texel_means;

// Per sample: the footprint (UV width on the high's texture) of one sample
// of a texel of a width x height map.
struct Footprint {
  float texel_scale;  // 1 / sqrt(width * height * samples)

  float of(const BandInputs& in, const SurfaceTransfer& transfer, std::size_t s, std::int32_t hit) const {
    const auto low = static_cast<std::size_t>(in.samples.triangle[s]);
    const glm::vec3* p = &in.surface.position[3 * low];
    const glm::vec2* uv = &in.surface.uv[3 * low];
    const float area = glm::length(glm::cross(p[1] - p[0], p[2] - p[0]));
    const glm::vec2 a = uv[1] - uv[0], b = uv[2] - uv[0];
    const float uv_area = std::abs(a.x * b.y - a.y * b.x);
    if (!(uv_area > 0.0f)) return 0.0f;
    const float side = std::sqrt(area / uv_area) * texel_scale;  // scene units per sample
    const float f = side * transfer.uv_density[static_cast<std::size_t>(hit)];
    return std::isfinite(f) ? f : 0.0f;
  }
};

glm::vec2 hit_uv(const SurfaceTransfer& transfer, std::int32_t hit, glm::vec2 b) {
  return maps_detail::interpolate(transfer.corner_uv, 3 * static_cast<std::size_t>(hit), b);
}

struct TransferModule : MapSet::Module {
  explicit TransferModule(MapKind map) : Module(map) {}

  void encode_band(const BandInputs& in, const MapSettings& settings, EncodeStats&) override {
    NMBAKE_CHECK(settings.transfer != nullptr && settings.map_height > 0, "surface data for a transfer map");
    const SurfaceTransfer& transfer = *settings.transfer;
    const Footprint footprint{
        1.0f / std::sqrt(static_cast<float>(in.samples.width) * static_cast<float>(settings.map_height) *
                         static_cast<float>(in.samples.samples))};
    std::atomic<std::uint64_t> factor_only{0}, tile_missing{0};
    const auto texture_of = [&](const MaterialTextures& t) {
      switch (kind) {
        case MapKind::base_color:
          return t.base_color;
        case MapKind::roughness:
          return t.roughness;
        case MapKind::metallic:
          return t.metallic;
        case MapKind::emissive:
          return t.emissive;
        default:
          return t.opacity;
      }
    };
    const auto ref_of = [&](const Material& m) -> const TextureRef& {
      switch (kind) {
        case MapKind::base_color:
          return m.base_color_texture;
        case MapKind::roughness:
          return m.roughness_texture;
        case MapKind::metallic:
          return m.metallic_texture;
        case MapKind::emissive:
          return m.emissive_texture;
        default:
          return m.opacity_texture;
      }
    };
    // The material, and its texture's value at the sample (RGBA, 1 without
    // one); false: no texture.
    const auto lookup = [&](std::size_t s, const Material*& m, glm::vec4& texel, bool& alpha) {
      const std::int32_t hit = in.hits.triangle[s];
      const std::uint32_t index = transfer.triangle_material[static_cast<std::size_t>(hit)];
      m = &transfer.materials[index];
      texel = glm::vec4(1.0f);
      alpha = false;
      const int t = texture_of(transfer.material_textures[index]);
      if (t < 0) {
        factor_only.fetch_add(1, std::memory_order_relaxed);
        return false;
      }
      const LoadedTexture& texture = transfer.textures.textures[static_cast<std::size_t>(t)];
      bool missing = false;
      texel = sample_texture(texture, ref_of(*m), hit_uv(transfer, hit, in.hits.bary[s]),
                             footprint.of(in, transfer, s, hit), missing);
      if (missing) tile_missing.fetch_add(1, std::memory_order_relaxed);
      const int c = texture.tiles.begin()->second.channels;
      alpha = c == 2 || c == 4;
      return true;
    };
    if (map_traits(kind).channels == 3) {
      texel_means<3>(in, image, {0.0f, 0.0f, 0.0f}, [&](std::size_t s, std::array<float, 3>& v) {
        v = {0.0f, 0.0f, 0.0f};
        if (in.hits.triangle[s] < 0) return;
        const Material* m = nullptr;
        glm::vec4 texel;
        bool alpha = false;
        lookup(s, m, texel, alpha);
        const glm::vec3 factor = kind == MapKind::base_color ? glm::vec3(m->base_color) : m->emissive;
        const glm::vec3 c = factor * glm::vec3(texel);
        v = {c.r, c.g, c.b};
      });
    } else {
      texel_means<1>(in, image, {0.0f}, [&](std::size_t s, std::array<float, 1>& v) {
        v = {0.0f};
        if (in.hits.triangle[s] < 0) return;
        const Material* m = nullptr;
        glm::vec4 texel;
        bool alpha = false;
        const bool textured = lookup(s, m, texel, alpha);
        float factor = m->base_color.a;
        int channel = 3;
        if (kind == MapKind::roughness) {
          factor = m->roughness;
          channel = m->roughness_texture.channel;
        } else if (kind == MapKind::metallic) {
          factor = m->metallic;
          channel = m->metallic_texture.channel;
        } else {
          channel = m->opacity_texture.channel;
        }
        v[0] = factor * (textured ? texture_channel(texel, channel, alpha) : 1.0f);
      });
    }
    add("samples with the factor alone (no texture)", static_cast<double>(factor_only.load()));
    add("samples in a UDIM tile the texture lacks", static_cast<double>(tile_missing.load()));
  }
};

}  // namespace

std::unique_ptr<MapSet::Module> make_transfer_module(MapKind map) {
  if (!map_traits(map).surface) return nullptr;
  return std::make_unique<TransferModule>(map);
}

}  // namespace nmbake
