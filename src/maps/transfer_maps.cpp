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
#include <vector>

#include "maps/modules.hpp"
#include "nmbake/textures.hpp"

namespace nmbake {
namespace {

using maps_detail::texel_means;

// What a map reads of one material: its factor (a scalar map's in .r), the
// texture (an index into the texture set, -1: none) and how it is read.
struct Attribute {
  glm::vec3 factor;
  const TextureRef* ref;
  int texture;
  bool alpha;  // the texture has an alpha channel
};

Attribute attribute_of(MapKind kind, const Material& m, const MaterialTextures& t, const TextureSet& set) {
  Attribute a{glm::vec3(m.base_color.a), &m.opacity_texture, t.opacity, false};
  switch (kind) {
    case MapKind::base_color:
      a = {glm::vec3(m.base_color), &m.base_color_texture, t.base_color, false};
      break;
    case MapKind::emissive:
      a = {m.emissive, &m.emissive_texture, t.emissive, false};
      break;
    case MapKind::roughness:
      a = {glm::vec3(m.roughness), &m.roughness_texture, t.roughness, false};
      break;
    case MapKind::metallic:
      a = {glm::vec3(m.metallic), &m.metallic_texture, t.metallic, false};
      break;
    default:
      break;
  }
  if (a.texture >= 0) {
    const int c = set.textures[static_cast<std::size_t>(a.texture)].tiles.begin()->second.channels;
    a.alpha = c == 2 || c == 4;
  }
  return a;
}

struct TransferModule : MapSet::Module {
  explicit TransferModule(MapKind map) : Module(map) {}

  // Per low triangle: the side of one sample of a texel in scene units,
  // sqrt(area / UV area) / sqrt(width * height * samples) (0 for a triangle
  // without UV area), for the footprint (textures.hpp). Every band of a map
  // set reads the same surface: computed at its first band.
  std::vector<float> sample_side_;

  void encode_band(const BandInputs& in, const MapSettings& settings, EncodeStats&) override {
    NMBAKE_CHECK(settings.transfer != nullptr && settings.map_height > 0, "surface data for a transfer map");
    const SurfaceTransfer& transfer = *settings.transfer;
    if (sample_side_.empty()) {
      NMBAKE_CHECK(in.surface.triangle_count() > 0, "a low surface");
      sample_side_ = maps_detail::low_sample_sides(in.surface, in.samples.width, settings.map_height,
                                                   in.samples.samples);
    }
    NMBAKE_CHECK(sample_side_.size() == in.surface.triangle_count(), "one surface for the map set's bands");
    std::vector<Attribute> attributes;
    for (std::size_t m = 0; m < transfer.materials.size(); ++m) {
      attributes.push_back(
          attribute_of(kind, transfer.materials[m], transfer.material_textures[m], transfer.textures));
    }
    std::atomic<std::uint64_t> factor_only{0}, tile_missing{0};
    // The hit material's attribute, and its texture's value at the sample
    // (RGBA; 1 without a texture); false: no texture.
    const auto lookup = [&](std::size_t s, const Attribute*& a, glm::vec4& texel) {
      const std::int32_t hit = in.hits.triangle[s];
      a = &attributes[transfer.triangle_material[static_cast<std::size_t>(hit)]];
      texel = glm::vec4(1.0f);
      if (a->texture < 0) {
        factor_only.fetch_add(1, std::memory_order_relaxed);
        return false;
      }
      // The footprint: the sample's side on the low times the hit triangle's UV density.
      const float f = sample_side_[static_cast<std::size_t>(in.samples.triangle[s])] *
                      transfer.uv_density[static_cast<std::size_t>(hit)];
      bool missing = false;
      texel = sample_texture(
          transfer.textures.textures[static_cast<std::size_t>(a->texture)], *a->ref,
          maps_detail::interpolate(transfer.corner_uv, 3 * static_cast<std::size_t>(hit), in.hits.bary[s]),
          std::isfinite(f) ? f : 0.0f, missing);
      if (missing) tile_missing.fetch_add(1, std::memory_order_relaxed);
      return true;
    };
    if (map_traits(kind).channels == 3) {
      texel_means<3>(in, image, {0.0f, 0.0f, 0.0f}, [&](std::size_t s, std::array<float, 3>& v) {
        v = {0.0f, 0.0f, 0.0f};
        if (in.hits.triangle[s] < 0) return;
        const Attribute* a = nullptr;
        glm::vec4 texel;
        lookup(s, a, texel);
        const glm::vec3 c = a->factor * glm::vec3(texel);
        v = {c.r, c.g, c.b};
      });
    } else {
      texel_means<1>(in, image, {0.0f}, [&](std::size_t s, std::array<float, 1>& v) {
        v = {0.0f};
        if (in.hits.triangle[s] < 0) return;
        const Attribute* a = nullptr;
        glm::vec4 texel;
        const bool textured = lookup(s, a, texel);
        v[0] = a->factor.r * (textured ? texture_channel(texel, a->ref->channel, a->alpha) : 1.0f);
      });
    }
    add("factor_only_samples", static_cast<double>(factor_only.load()));
    add("missing_tile_samples", static_cast<double>(tile_missing.load()));
  }
};

}  // namespace

std::vector<float> maps_detail::low_sample_sides(const LowSurface& surface, int width, int height,
                                                 int samples) {
  const float texel_scale =
      1.0f / std::sqrt(static_cast<float>(width) * static_cast<float>(height) * static_cast<float>(samples));
  std::vector<float> side(surface.triangle_count());
  for (std::size_t t = 0; t < side.size(); ++t) {
    const glm::vec3* p = &surface.position[3 * t];
    const glm::vec2* uv = &surface.uv[3 * t];
    const float area = glm::length(glm::cross(p[1] - p[0], p[2] - p[0]));
    const glm::vec2 a = uv[1] - uv[0], b = uv[2] - uv[0];
    const float uv_area = std::abs(a.x * b.y - a.y * b.x);
    side[t] = uv_area > 0.0f ? std::sqrt(area / uv_area) * texel_scale : 0.0f;
  }
  return side;
}

std::unique_ptr<MapSet::Module> make_transfer_module(MapKind map) {
  if (!map_traits(map).surface) return nullptr;
  return std::make_unique<TransferModule>(map);
}

}  // namespace nmbake
