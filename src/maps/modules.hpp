// The map modules behind MapSet (maps.hpp): one per map, each saying what it
// reads from a band, how it turns samples into texels, what an integer file
// stores and what it reports. Private to src/maps/.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <memory>
#include <vector>

#include "nmbake/maps.hpp"

namespace nmbake {

// What a band gives its maps.
struct BandInputs {
  const LowSurface& surface;
  const TexelSamples& samples;
  const Mesh& high;
  const Hits& hits;
  const std::vector<float>* visibility;  // trace_occlusion(), when a map needs it
  const std::vector<glm::vec3>* bent;
  const std::vector<float>* thickness;  // trace_thickness()
  int out_row;                          // row of the module's image that holds the band's first row
};

struct MapSet::Module {
  MapKind kind;
  Image image;  // raw texels: the rows [first_row, last_row) of the map
  std::vector<std::pair<std::string, double>> figures;

  explicit Module(MapKind map) : kind(map) {}
  virtual ~Module() = default;
  virtual void encode_band(const BandInputs& in, const MapSettings& settings, EncodeStats& normal_stats) = 0;
  // Read straight from the hits (height, position, curvature, miss): such
  // maps are encoded together by encode_hit_values(), one pass over each
  // block of rows for all of them (their encode_band() does nothing).
  virtual bool from_hit_values() const { return false; }
  // A map encoded a block of rows at a time (its encode_band() does
  // nothing): MapSet::encode_band() runs these and the hit values over each
  // block in turn, blocks in parallel, so every map reads a block's samples
  // and hits while they are in cache. encode_rows() encodes rows
  // [row_begin, row_end) of the band on the calling thread, adding to the
  // block's own `stats`; after the band, rows_encoded() gets their sum.
  virtual bool by_rows() const { return false; }
  virtual void encode_rows(const BandInputs& /*in*/, const MapSettings& /*settings*/, int /*row_begin*/,
                           int /*row_end*/, EncodeStats& /*stats*/) {}
  virtual void rows_encoded(const EncodeStats& /*band*/, EncodeStats& /*normal_stats*/) {}
  // After the last band, before dilation: ranges from the covered texels.
  virtual void finish(const std::vector<std::uint8_t>& /*coverage*/) {}
  // Integer files store v * scale + offset (clamped to [0, 1] by the writer).
  virtual void integer_mapping(float& scale, float& offset) const {
    scale = 1.0f;
    offset = 0.0f;
  }
  void add(const char* name, double value) {
    for (auto& f : figures) {
      if (f.first == name) {
        f.second += value;
        return;
      }
    }
    figures.emplace_back(name, value);
  }
  void set(const char* name, double value) {
    for (auto& f : figures) {
      if (f.first == name) {
        f.second = value;
        return;
      }
    }
    figures.emplace_back(name, value);
  }
};

std::unique_ptr<MapSet::Module> make_map_module(MapKind map, const MapSettings& settings);

// The images of the hit-value maps of a set (null: not baked).
struct HitValueImages {
  Image* height = nullptr;
  Image* position = nullptr;
  Image* curvature = nullptr;
  Image* miss = nullptr;
};
// One pass over rows [row_begin, row_end) of the band for every hit-value
// map, on the calling thread: a sample's hit triangle is read once for all
// of them. Each map's texel is the mean of its samples' values, as
// texel_means() computes it.
void encode_hit_values(const BandInputs& in, const MapSettings& settings, const HitValueImages& out,
                       int row_begin, int row_end);

namespace maps_detail {

// Texel by texel over the band, rows in parallel: a covered texel gets the
// mean of value(sample) over its samples inside a chart (value writes C
// floats), an uncovered one `background`. Sums in sample order, so the result
// does not depend on the thread count.
template <int C, class F>
void texel_means(const BandInputs& in, Image& image, const std::array<float, C>& background, F&& value) {
  const TexelSamples& samples = in.samples;
  const int width = samples.width;
  const int spp = samples.samples;
  tbb::parallel_for(tbb::blocked_range<int>(0, samples.height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y != rows.end(); ++y) {
      float* out = image.pixels.data() + static_cast<std::size_t>(in.out_row + y) * width * C;
      for (int x = 0; x < width; ++x) {
        const std::size_t texel = static_cast<std::size_t>(y) * width + x;
        float* p = out + static_cast<std::size_t>(x) * C;
        if (!samples.coverage[texel]) {
          for (int c = 0; c < C; ++c) p[c] = background[c];
          continue;
        }
        std::array<float, C> sum{};
        int used = 0;
        for (int k = 0; k < spp; ++k) {
          const std::size_t s = texel * spp + static_cast<std::size_t>(k);
          if (samples.triangle[s] < 0) continue;
          std::array<float, C> v;
          value(s, v);
          for (int c = 0; c < C; ++c) sum[c] += v[c];
          ++used;
        }
        // A covered texel has at least one sample in a chart (raster.hpp).
        const float inv = used > 0 ? 1.0f / static_cast<float>(used) : 0.0f;
        for (int c = 0; c < C; ++c) p[c] = used > 0 ? sum[c] * inv : background[c];
      }
    }
  });
}

// Per low triangle: the side of one sample of a texel in scene units,
// sqrt(area / UV area) / sqrt(width * height * samples) (0 for a triangle
// without UV area), for a texture footprint (textures.hpp).
std::vector<float> low_sample_sides(const LowSurface& surface, int width, int height, int samples);

template <class V>
inline V interpolate(const std::vector<V>& corner, std::size_t base, glm::vec2 b) {
  return corner[base] * (1.0f - b.x - b.y) + corner[base + 1] * b.x + corner[base + 2] * b.y;
}

}  // namespace maps_detail

}  // namespace nmbake
