// Maps of values read from the hits (height, position, curvature, miss) and
// from the rays cast from them (ao, thickness). Each texel is the mean of its
// samples' values (maps_detail::texel_means); a sample whose ray missed takes
// the map's miss value (maps.hpp's table).
#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "modules.hpp"

namespace nmbake {

namespace {

using maps_detail::interpolate;
using maps_detail::texel_means;

// The largest |v| and the min and max over covered texels of a one-channel image.
struct Extent {
  float min = 0.0f, max = 0.0f, largest = 0.0f;
  std::uint64_t texels = 0;
};
Extent covered_extent(const Image& image, const std::vector<std::uint8_t>& coverage) {
  Extent e;
  bool first = true;
  for (std::size_t t = 0; t < coverage.size(); ++t) {
    if (!coverage[t]) continue;
    const float v = image.pixels[t];
    e.min = first ? v : std::min(e.min, v);
    e.max = first ? v : std::max(e.max, v);
    first = false;
    ++e.texels;
  }
  e.largest = std::max(std::fabs(e.min), std::fabs(e.max));
  return e;
}

// A signed quantity stored as 0.5 + v / (2 R) in integer files: R given, or
// from the map (auto). R = 0 (a flat map) stores 0.5 everywhere, counted.
struct SignedRange {
  float range = 0.0f;
  void integer_mapping(float& scale, float& offset) const {
    scale = range > 0.0f ? 0.5f / range : 0.0f;
    offset = 0.5f;
  }
};

struct HeightModule final : MapSet::Module, SignedRange {
  HeightModule() : Module(MapKind::height) {}
  void encode_band(const BandInputs& in, const MapSettings&, EncodeStats&) override {
    texel_means<1>(in, image, {0.0f}, [&](std::size_t s, std::array<float, 1>& v) {
      v[0] = in.hits.triangle[s] >= 0 ? in.hits.distance[s] : 0.0f;
    });
  }
  void finish(const std::vector<std::uint8_t>& coverage) override {
    const Extent e = covered_extent(image, coverage);
    range = given > 0.0f ? given : e.largest;
    set("min", e.min);
    set("max", e.max);
    set("range", range);
    set("range_given", given > 0.0f ? 1.0 : 0.0);
    std::uint64_t clamped = 0;
    for (std::size_t t = 0; t < coverage.size(); ++t) clamped += coverage[t] && std::fabs(image.pixels[t]) > range;
    set("clamped_texels", static_cast<double>(clamped));
    set("flat_range_fallback", range > 0.0f ? 0.0 : 1.0);
  }
  void integer_mapping(float& scale, float& offset) const override { SignedRange::integer_mapping(scale, offset); }
  float given = 0.0f;
};

struct CurvatureModule final : MapSet::Module, SignedRange {
  CurvatureModule() : Module(MapKind::curvature) {}
  void encode_band(const BandInputs& in, const MapSettings& settings, EncodeStats&) override {
    const std::vector<float>& k = *settings.vertex_curvature;
    texel_means<1>(in, image, {0.0f}, [&](std::size_t s, std::array<float, 1>& v) {
      const std::int32_t hit = in.hits.triangle[s];
      if (hit < 0) {
        v[0] = 0.0f;
        return;
      }
      const std::uint32_t* t = &in.high.indices[3 * static_cast<std::size_t>(hit)];
      const glm::vec2 b = in.hits.bary[s];
      v[0] = k[t[0]] * (1.0f - b.x - b.y) + k[t[1]] * b.x + k[t[2]] * b.y;
    });
  }
  void finish(const std::vector<std::uint8_t>& coverage) override {
    const Extent e = covered_extent(image, coverage);
    // Auto: the 99th percentile of |H|, so a few sharp creases do not flatten
    // the rest of the map to grey.
    std::vector<float> magnitudes;
    magnitudes.reserve(e.texels);
    for (std::size_t t = 0; t < coverage.size(); ++t) {
      if (coverage[t]) magnitudes.push_back(std::fabs(image.pixels[t]));
    }
    float p99 = 0.0f;
    if (!magnitudes.empty()) {
      const std::size_t at = std::min(magnitudes.size() - 1, magnitudes.size() * 99 / 100);
      std::nth_element(magnitudes.begin(), magnitudes.begin() + static_cast<std::ptrdiff_t>(at), magnitudes.end());
      p99 = magnitudes[at];
    }
    range = given > 0.0f ? given : p99;
    set("min", e.min);
    set("max", e.max);
    set("range", range);
    set("range_given", given > 0.0f ? 1.0 : 0.0);
    std::uint64_t clamped = 0;
    for (std::size_t t = 0; t < coverage.size(); ++t) clamped += coverage[t] && std::fabs(image.pixels[t]) > range;
    set("clamped_texels", static_cast<double>(clamped));
    set("flat_range_fallback", range > 0.0f ? 0.0 : 1.0);
  }
  void integer_mapping(float& scale, float& offset) const override { SignedRange::integer_mapping(scale, offset); }
  float given = 0.0f;
};

struct PositionModule final : MapSet::Module {
  PositionModule() : Module(MapKind::position) {}
  void encode_band(const BandInputs& in, const MapSettings& settings, EncodeStats&) override {
    const Bounds& box = settings.position_bounds;
    const glm::vec3 extent = box.max - box.min;
    glm::vec3 inv(0.0f), flat(0.0f);
    for (int a = 0; a < 3; ++a) {
      // A flat box axis (a plane) stores 0.5 on it.
      if (extent[a] > 0.0f) {
        inv[a] = 1.0f / extent[a];
      } else {
        flat[a] = 0.5f;
      }
    }
    texel_means<3>(in, image, {0.0f, 0.0f, 0.0f}, [&](std::size_t s, std::array<float, 3>& v) {
      const std::int32_t hit = in.hits.triangle[s];
      glm::vec3 p;
      if (hit >= 0) {
        const std::uint32_t* t = &in.high.indices[3 * static_cast<std::size_t>(hit)];
        const glm::vec2 b = in.hits.bary[s];
        p = in.high.positions[t[0]] * (1.0f - b.x - b.y) + in.high.positions[t[1]] * b.x +
            in.high.positions[t[2]] * b.y;
      } else {
        // A miss: the low surface point.
        p = interpolate(in.surface.position, 3 * static_cast<std::size_t>(in.samples.triangle[s]), in.samples.bary[s]);
      }
      for (int a = 0; a < 3; ++a) v[a] = std::clamp((p[a] - box.min[a]) * inv[a] + flat[a], 0.0f, 1.0f);
    });
  }
  void finish(const std::vector<std::uint8_t>&) override {}
};

struct MissModule final : MapSet::Module {
  MissModule() : Module(MapKind::miss) {}
  void encode_band(const BandInputs& in, const MapSettings&, EncodeStats&) override {
    texel_means<1>(in, image, {0.0f}, [&](std::size_t s, std::array<float, 1>& v) {
      v[0] = in.hits.triangle[s] >= 0 ? 0.0f : 1.0f;
    });
  }
};

struct OcclusionModule final : MapSet::Module {
  OcclusionModule() : Module(MapKind::ao) {}
  void encode_band(const BandInputs& in, const MapSettings&, EncodeStats&) override {
    texel_means<1>(in, image, {1.0f}, [&](std::size_t s, std::array<float, 1>& v) { v[0] = (*in.visibility)[s]; });
  }
};

struct ThicknessModule final : MapSet::Module {
  explicit ThicknessModule(float distance) : Module(MapKind::thickness), distance_(distance) {}
  void encode_band(const BandInputs& in, const MapSettings&, EncodeStats&) override {
    texel_means<1>(in, image, {0.0f}, [&](std::size_t s, std::array<float, 1>& v) { v[0] = (*in.thickness)[s]; });
  }
  void integer_mapping(float& scale, float& offset) const override {
    scale = distance_ > 0.0f ? 1.0f / distance_ : 0.0f;
    offset = 0.0f;
  }
  float distance_;
};

}  // namespace

std::unique_ptr<MapSet::Module> make_value_module(MapKind map, const MapSettings& settings) {
  switch (map) {
    case MapKind::height: {
      auto m = std::make_unique<HeightModule>();
      m->given = settings.height_range;
      return m;
    }
    case MapKind::curvature: {
      NMBAKE_CHECK(settings.vertex_curvature != nullptr, "vertex curvature computed for a curvature map");
      auto m = std::make_unique<CurvatureModule>();
      m->given = settings.curvature_range;
      return m;
    }
    case MapKind::position: return std::make_unique<PositionModule>();
    case MapKind::miss: return std::make_unique<MissModule>();
    case MapKind::ao: return std::make_unique<OcclusionModule>();
    case MapKind::thickness: return std::make_unique<ThicknessModule>(settings.thickness.distance);
    default: return nullptr;
  }
}

std::unique_ptr<MapSet::Module> make_direction_module(MapKind map);

std::unique_ptr<MapSet::Module> make_map_module(MapKind map, const MapSettings& settings) {
  if (auto m = make_direction_module(map)) return m;
  if (auto m = make_value_module(map, settings)) return m;
  NMBAKE_CHECK(false, "a module for every implemented map");
  return nullptr;
}

}  // namespace nmbake
