// Maps of values read from the hits (height, position, curvature, miss) and
// from the rays cast from them (ao, thickness). Each texel is the mean of its
// samples' values (maps_detail::texel_means); a sample whose ray missed takes
// the map's miss value (maps.hpp's table).
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>

#include "base/simd4.hpp"
#include "maps/modules.hpp"

namespace nmbake {

namespace {

using maps_detail::interpolate;
using maps_detail::texel_means;

// The min, max and largest |v| over the covered texels of a one-channel
// image, and how many there are (in parallel: min and max do not depend on
// the order).
struct Extent {
  float min = 0.0f, max = 0.0f, largest = 0.0f;
  std::uint64_t texels = 0;
};
// An Extent being gathered, chunk by chunk.
struct ExtentSum {
  float min = INFINITY, max = -INFINITY;
  std::uint64_t texels = 0;
  void add(float v) {
    min = std::min(min, v);
    max = std::max(max, v);
    ++texels;
  }
  void add(const ExtentSum& other) {
    min = std::min(min, other.min);
    max = std::max(max, other.max);
    texels += other.texels;
  }
  Extent extent() const {
    Extent e;
    if (texels == 0) return e;
    e.min = min;
    e.max = max;
    e.largest = std::max(std::fabs(min), std::fabs(max));
    e.texels = texels;
    return e;
  }
};
// The extent of the covered texels in [begin, end), calling each(v) for
// every covered value: two sums over alternating texels, so min and max are
// two dependency chains each (neither depends on the order; a single chain
// made the moon's curvature range 12 ms instead of 6).
template <class Each>
ExtentSum covered_extent_of(const Image& image, const std::vector<std::uint8_t>& coverage, std::size_t begin,
                            std::size_t end, Each&& each) {
  ExtentSum first, second;
  std::size_t t = begin;
  for (; t + 2 <= end; t += 2) {
    if (coverage[t]) {
      first.add(image.pixels[t]);
      each(image.pixels[t]);
    }
    if (coverage[t + 1]) {
      second.add(image.pixels[t + 1]);
      each(image.pixels[t + 1]);
    }
  }
  if (t < end && coverage[t]) {
    first.add(image.pixels[t]);
    each(image.pixels[t]);
  }
  first.add(second);
  return first;
}

Extent covered_extent(const Image& image, const std::vector<std::uint8_t>& coverage) {
  return tbb::parallel_reduce(
             tbb::blocked_range<std::size_t>(0, coverage.size(), 1 << 16), ExtentSum{},
             [&](const tbb::blocked_range<std::size_t>& r, ExtentSum sum) {
               sum.add(covered_extent_of(image, coverage, r.begin(), r.end(), [](float) {}));
               return sum;
             },
             [](ExtentSum a, const ExtentSum& b) {
               a.add(b);
               return a;
             })
      .extent();
}

// Covered texels with |v| > limit.
std::uint64_t count_beyond(const Image& image, const std::vector<std::uint8_t>& coverage, float limit) {
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, coverage.size(), 1 << 16), std::uint64_t{0},
      [&](const tbb::blocked_range<std::size_t>& r, std::uint64_t n) {
        for (std::size_t t = r.begin(); t != r.end(); ++t)
          n += coverage[t] && std::fabs(image.pixels[t]) > limit;
        return n;
      },
      [](std::uint64_t a, std::uint64_t b) { return a + b; });
}

// The value at rank floor(0.99 n) of the sorted |v| of the covered texels
// (the 99th percentile), exactly, without sorting them all, and how many
// |v| lie above it; with the extent of the same pass. A histogram of |v|'s
// float bits (for finite v >= 0 the bits order as the values: the top 15
// bits hold the exponent and 7 bits of mantissa, so a bin spans under 1%
// of its values' magnitude, subnormals included), integer counts per fixed
// chunk, finds the bin; only that bin's values are ordered.
struct Percentile {
  Extent extent;
  float value = 0.0f;
  std::uint64_t above = 0;
};
Percentile covered_percentile_99(const Image& image, const std::vector<std::uint8_t>& coverage) {
  constexpr int kShift = 16;
  constexpr std::size_t kBins = std::size_t{1} << (31 - kShift);
  const auto bin_of = [](float v) {
    std::uint32_t bits;
    const float a = std::fabs(v);
    std::memcpy(&bits, &a, 4);
    return static_cast<std::size_t>(bits >> kShift);
  };
  constexpr std::size_t kChunk = std::size_t{1} << 18;
  const std::size_t chunks = (coverage.size() + kChunk - 1) / kChunk;
  struct Part {
    ExtentSum extent;
    std::vector<std::uint32_t> histogram;
  };
  std::vector<Part> parts(chunks);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    Part& part = parts[c];
    part.histogram.assign(kBins, 0);
    const std::size_t end = std::min(coverage.size(), (c + 1) * kChunk);
    part.extent =
        covered_extent_of(image, coverage, c * kChunk, end, [&](float v) { ++part.histogram[bin_of(v)]; });
  });
  Percentile out;
  ExtentSum all;
  for (const Part& part : parts) all.add(part.extent);
  if (all.texels == 0) return out;
  out.extent = all.extent();
  const std::uint64_t texels = all.texels;
  const std::uint64_t rank = std::min(texels - 1, texels * 99 / 100);
  std::uint64_t below = 0, in_bin = 0;
  std::size_t bin = 0;
  for (; bin < kBins; ++bin) {
    std::uint64_t count = 0;
    for (const Part& part : parts) count += part.histogram[bin];
    if (below + count > rank) {
      in_bin = count;
      break;
    }
    below += count;
  }
  // The bin's values, chunk by chunk in parallel, joined in chunk order.
  std::vector<std::vector<float>> values(chunks);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    if (parts[c].extent.texels == 0) return;
    const std::size_t end = std::min(coverage.size(), (c + 1) * kChunk);
    for (std::size_t t = c * kChunk; t < end; ++t) {
      if (coverage[t] && bin_of(image.pixels[t]) == bin) values[c].push_back(std::fabs(image.pixels[t]));
    }
  });
  std::vector<float> bin_values;
  for (const auto& part : values) bin_values.insert(bin_values.end(), part.begin(), part.end());
  const auto at = bin_values.begin() + static_cast<std::ptrdiff_t>(rank - below);
  std::nth_element(bin_values.begin(), at, bin_values.end());
  out.value = *at;
  out.above =
      texels - below - in_bin +
      static_cast<std::uint64_t>(std::count_if(at, bin_values.end(), [&](float v) { return v > out.value; }));
  return out;
}

// A signed quantity stored as 0.5 + v / (2 R) in integer files: R given, or
// from the map (auto). R = 0 (a flat map) stores 0.5 everywhere, counted;
// so does an R below 0.5 / FLT_MAX (1.5e-39), whose scale 1 / 2R is no
// float (0 times it would be NaN).
struct SignedRange {
  float range = 0.0f;
  bool flat() const { return !(range > 0.0f && std::isfinite(0.5f / range)); }
  void integer_mapping(float& scale, float& offset) const {
    scale = flat() ? 0.0f : 0.5f / range;
    offset = 0.5f;
  }
};

struct HeightModule final : MapSet::Module, SignedRange {
  HeightModule() : Module(MapKind::height) {}
  void encode_band(const BandInputs&, const MapSettings&, EncodeStats&) override {}
  bool from_hit_values() const override { return true; }
  void finish(const std::vector<std::uint8_t>& coverage) override {
    const Extent e = covered_extent(image, coverage);
    range = given > 0.0f ? given : e.largest;
    set("min", e.min);
    set("max", e.max);
    set("range", range);
    set("range_given", given > 0.0f ? 1.0 : 0.0);
    set("clamped_texels", static_cast<double>(given > 0.0f ? count_beyond(image, coverage, range) : 0));
    set("flat_range_fallback", flat() ? 1.0 : 0.0);
  }
  void integer_mapping(float& scale, float& offset) const override {
    SignedRange::integer_mapping(scale, offset);
  }
  float given = 0.0f;
};

struct CurvatureModule final : MapSet::Module, SignedRange {
  CurvatureModule() : Module(MapKind::curvature) {}
  void encode_band(const BandInputs&, const MapSettings&, EncodeStats&) override {}
  bool from_hit_values() const override { return true; }
  void finish(const std::vector<std::uint8_t>& coverage) override {
    // Auto: the 99th percentile of |H|, so a few sharp creases do not flatten
    // the rest of the map to grey.
    Extent e;
    std::uint64_t clamped = 0;
    if (given > 0.0f) {
      e = covered_extent(image, coverage);
      range = given;
      clamped = count_beyond(image, coverage, range);
    } else {
      const Percentile p = covered_percentile_99(image, coverage);
      e = p.extent;
      range = p.value;
      clamped = p.above;
    }
    set("min", e.min);
    set("max", e.max);
    set("range", range);
    set("range_given", given > 0.0f ? 1.0 : 0.0);
    set("clamped_texels", static_cast<double>(clamped));
    set("flat_range_fallback", flat() ? 1.0 : 0.0);
  }
  void integer_mapping(float& scale, float& offset) const override {
    SignedRange::integer_mapping(scale, offset);
  }
  float given = 0.0f;
};

struct PositionModule final : MapSet::Module {
  PositionModule() : Module(MapKind::position) {}  // its box is reported from the settings (reports())
  void encode_band(const BandInputs&, const MapSettings&, EncodeStats&) override {}
  bool from_hit_values() const override { return true; }
};

struct MissModule final : MapSet::Module {
  MissModule() : Module(MapKind::miss) {}
  void encode_band(const BandInputs&, const MapSettings&, EncodeStats&) override {}
  bool from_hit_values() const override { return true; }
};

// encode_hit_values() for the maps that need the hit triangle's corners
// (position: their positions; curvature: their vertex curvature).
template <bool kPosition, bool kCurvature>
void hit_values(const BandInputs& in, const MapSettings& settings, const HitValueImages& out, int row_begin,
                int row_end) {
  const TexelSamples& samples = in.samples;
  const int width = samples.width, spp = samples.samples;
  const std::vector<float>* curvature = settings.vertex_curvature;
  NMBAKE_CHECK(!kCurvature || curvature != nullptr, "vertex curvature computed for a curvature map");
  const Bounds& box = settings.position_bounds;
  const glm::vec3 extent = box.max - box.min;
  glm::vec3 inv_extent(0.0f), flat(0.0f);
  for (int a = 0; a < 3; ++a) {
    // A flat box axis (a plane) stores 0.5 on it.
    if (extent[a] > 0.0f) {
      inv_extent[a] = 1.0f / extent[a];
    } else {
      flat[a] = 0.5f;
    }
  }
  const auto row_of = [&](Image* image, int y) {
    return image ? image->pixels.data() + static_cast<std::size_t>(in.out_row + y) * width * image->channels
                 : nullptr;
  };
  // Raw pointers, so the loop reloads none of them after its stores.
  const std::uint8_t* const coverage = samples.coverage.data();
  const std::int32_t* const sample_triangle = samples.triangle.data();
  const std::int32_t* const hit_triangle = in.hits.triangle.data();
  const float* const hit_distance = in.hits.distance.data();
  const glm::vec2* const hit_bary = in.hits.bary.data();
  const std::uint32_t* const indices = in.high.indices.data();
  const glm::vec3* const positions = in.high.positions.data();
  const float* const vertex_curvature = kCurvature ? curvature->data() : nullptr;
  for (int y = row_begin; y != row_end; ++y) {
    float* height = row_of(out.height, y);
    float* position = row_of(out.position, y);
    float* curv = row_of(out.curvature, y);
    float* miss = row_of(out.miss, y);
    for (int x = 0; x < width; ++x) {
      const std::size_t texel = static_cast<std::size_t>(y) * width + x;
      float h = 0.0f, m = 0.0f, k = 0.0f;
      // The position sum in SIMD lanes (x, y, z, unused): per lane the
      // scalar expression's operations in its order, so the same bits.
      detail::f4 p = {0.0f, 0.0f, 0.0f, 0.0f};
      int used = 0;
      if (coverage[texel]) {
        for (int j = 0; j < spp; ++j) {
          const std::size_t s = texel * spp + static_cast<std::size_t>(j);
          const std::int32_t tri = sample_triangle[s];
          if (tri < 0) continue;
          ++used;
          const std::int32_t hit = hit_triangle[s];
          if (hit < 0) {
            // A miss: height and curvature 0, the low surface point.
            m += 1.0f;
            if (kPosition) {
              const glm::vec3 low =
                  interpolate(in.surface.position, 3 * static_cast<std::size_t>(tri), samples.bary[s]);
              p += detail::f4{low.x, low.y, low.z, 0.0f};
            }
            continue;
          }
          h += hit_distance[s];
          if (kPosition || kCurvature) {
            const std::uint32_t* c = &indices[3 * static_cast<std::size_t>(hit)];
            const glm::vec2 b = hit_bary[s];
            const float w = 1.0f - b.x - b.y;
            if (kPosition) {
              // Four floats from each corner: the fourth is the next
              // vertex's x (or pad_for_embree()'s spare one), never used.
              const auto corner = [&](std::uint32_t v) {
                detail::f4 q;
                std::memcpy(&q, &positions[v], sizeof(q));
                return q;
              };
              p += corner(c[0]) * detail::splat4(w) + corner(c[1]) * detail::splat4(b.x) +
                   corner(c[2]) * detail::splat4(b.y);
            }
            if (kCurvature)
              k += vertex_curvature[c[0]] * w + vertex_curvature[c[1]] * b.x + vertex_curvature[c[2]] * b.y;
          }
        }
      }
      // A covered texel has at least one sample in a chart (raster.hpp);
      // uncovered texels hold 0 (position: the box's corner).
      const float inv = used > 0 ? 1.0f / static_cast<float>(used) : 0.0f;
      if (height) height[x] = h * inv;
      if (miss) miss[x] = m * inv;
      if (kCurvature) curv[x] = k * inv;
      if (kPosition) {
        for (int a = 0; a < 3; ++a) {
          position[3 * x + a] =
              used > 0 ? std::clamp((p[a] * inv - box.min[a]) * inv_extent[a] + flat[a], 0.0f, 1.0f) : 0.0f;
        }
      }
    }
  }
}

struct OcclusionModule final : MapSet::Module {
  OcclusionModule() : Module(MapKind::ao) {}
  void encode_band(const BandInputs& in, const MapSettings&, EncodeStats&) override {
    texel_means<1>(in, image, {1.0f},
                   [&](std::size_t s, std::array<float, 1>& v) { v[0] = (*in.visibility)[s]; });
  }
};

struct ThicknessModule final : MapSet::Module {
  explicit ThicknessModule(float distance) : Module(MapKind::thickness), distance_(distance) {}
  void encode_band(const BandInputs& in, const MapSettings&, EncodeStats&) override {
    texel_means<1>(in, image, {0.0f},
                   [&](std::size_t s, std::array<float, 1>& v) { v[0] = (*in.thickness)[s]; });
  }
  void integer_mapping(float& scale, float& offset) const override {
    scale = distance_ > 0.0f && std::isfinite(1.0f / distance_) ? 1.0f / distance_ : 0.0f;
    offset = 0.0f;
  }
  float distance_;
};

// The high mesh's vertex colours at the hit, RGB; a miss is black.
struct VertexColorModule final : MapSet::Module {
  VertexColorModule() : Module(MapKind::vertex_color) {}
  void encode_band(const BandInputs& in, const MapSettings&, EncodeStats&) override {
    texel_means<3>(in, image, {0.0f, 0.0f, 0.0f}, [&](std::size_t s, std::array<float, 3>& v) {
      const std::int32_t hit = in.hits.triangle[s];
      v = {0.0f, 0.0f, 0.0f};
      if (hit < 0) return;
      const std::uint32_t* c = &in.high.indices[3 * static_cast<std::size_t>(hit)];
      const glm::vec2 b = in.hits.bary[s];
      const glm::vec4 color =
          in.high.colors[c[0]] * (1.0f - b.x - b.y) + in.high.colors[c[1]] * b.x + in.high.colors[c[2]] * b.y;
      v = {color.r, color.g, color.b};
    });
  }
};

// The colour of the part or material most of a texel's samples hit (ties:
// the first in the sample pattern's order); black where every sample
// missed. Never a blend of two colours, so the map is a mask. Figures: how
// many names have a colour, and whether they are materials (1) or parts (0).
struct IdModule final : MapSet::Module {
  IdModule() : Module(MapKind::id) {}
  void encode_band(const BandInputs& in, const MapSettings& settings, EncodeStats&) override {
    NMBAKE_CHECK(settings.triangle_id != nullptr && settings.id_colors != nullptr, "ids for an id map");
    const TexelSamples& samples = in.samples;
    const std::vector<std::uint32_t>& part = *settings.triangle_id;
    const std::vector<glm::vec3>& colors = *settings.id_colors;
    const int width = samples.width, spp = samples.samples;
    tbb::parallel_for(tbb::blocked_range<int>(0, samples.height), [&](const tbb::blocked_range<int>& rows) {
      std::vector<std::uint32_t> seen;
      for (int y = rows.begin(); y != rows.end(); ++y) {
        float* out = image.pixels.data() + static_cast<std::size_t>(in.out_row + y) * width * 3;
        for (int x = 0; x < width; ++x) {
          const std::size_t texel = static_cast<std::size_t>(y) * width + x;
          seen.clear();
          for (int k = 0; k < spp && samples.coverage[texel]; ++k) {
            const std::size_t s = texel * spp + static_cast<std::size_t>(k);
            if (samples.triangle[s] < 0 || in.hits.triangle[s] < 0) continue;
            seen.push_back(part[static_cast<std::size_t>(in.hits.triangle[s])]);
          }
          glm::vec3 value(0.0f);
          int best_count = 0;
          for (std::size_t i = 0; i < seen.size(); ++i) {
            const int count = static_cast<int>(std::count(seen.begin(), seen.end(), seen[i]));
            if (count > best_count) {
              best_count = count;
              value = colors[seen[i]];
            }
          }
          out[3 * x] = value.r;
          out[3 * x + 1] = value.g;
          out[3 * x + 2] = value.b;
        }
      }
    });
  }
};

}  // namespace

void encode_hit_values(const BandInputs& in, const MapSettings& settings, const HitValueImages& out,
                       int row_begin, int row_end) {
  NMBAKE_CHECK(0 <= row_begin && row_begin <= row_end && row_end <= in.samples.height, "rows of the band");
  if (out.position && out.curvature) return hit_values<true, true>(in, settings, out, row_begin, row_end);
  if (out.position) return hit_values<true, false>(in, settings, out, row_begin, row_end);
  if (out.curvature) return hit_values<false, true>(in, settings, out, row_begin, row_end);
  hit_values<false, false>(in, settings, out, row_begin, row_end);
}

std::unique_ptr<MapSet::Module> make_value_module(MapKind map, const MapSettings& settings) {
  switch (map) {
    case MapKind::height: {
      auto m = std::make_unique<HeightModule>();
      m->given = settings.height_range;
      return m;
    }
    case MapKind::curvature: {
      auto m = std::make_unique<CurvatureModule>();
      m->given = settings.curvature_range;
      return m;
    }
    case MapKind::position:
      return std::make_unique<PositionModule>();
    case MapKind::miss:
      return std::make_unique<MissModule>();
    case MapKind::ao:
      return std::make_unique<OcclusionModule>();
    case MapKind::thickness:
      return std::make_unique<ThicknessModule>(settings.thickness.distance);
    case MapKind::vertex_color:
      return std::make_unique<VertexColorModule>();
    case MapKind::id:
      return std::make_unique<IdModule>();
    default:
      return nullptr;
  }
}

std::unique_ptr<MapSet::Module> make_direction_module(MapKind map);
std::unique_ptr<MapSet::Module> make_transfer_module(MapKind map);

std::unique_ptr<MapSet::Module> make_map_module(MapKind map, const MapSettings& settings) {
  if (auto m = make_direction_module(map)) return m;
  if (auto m = make_value_module(map, settings)) return m;
  if (auto m = make_transfer_module(map)) return m;
  NMBAKE_CHECK(false, "a module for every implemented map");
  return nullptr;
}

}  // namespace nmbake
