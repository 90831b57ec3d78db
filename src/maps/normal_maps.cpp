// Maps of directions: the normal map (the encode stage, unchanged), the
// object-space normal beside it, and the bent normal (the mean unoccluded AO
// direction), encoded as the normal map is: exact inverse of the MikkTSpace
// decode in tangent space, per sample normalised, averaged per texel and
// renormalised, rgb = 0.5 n + 0.5.
#include <cmath>
#include <glm/geometric.hpp>

#include "maps/modules.hpp"

namespace nmbake {

namespace {

using maps_detail::interpolate;

// Row block by row block (by_rows()): the encode stage's encode_rows().
struct NormalModule final : MapSet::Module {
  bool object;
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
    nmbake::encode_rows(in.surface, in.samples, in.high, in.hits, options, image, stats, row_begin, row_end);
  }
  void rows_encoded(const EncodeStats& band, EncodeStats& normal_stats) override {
    if (!object) {
      normal_stats.add(band);
      return;
    }
    add("zero_high_normals", static_cast<double>(band.zero_high_normals));
    add("zero_results", static_cast<double>(band.zero_results));
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
