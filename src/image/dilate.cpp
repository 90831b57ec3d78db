// Stage "dilate": edge padding ("texture margin", "edge padding" in texture
// bakers such as Blender's bake margin), as iterative 8-neighbour dilation of
// the chart coverage, one ring per pass; a filled texel takes the normalised
// mean of its covered neighbours' unit vectors (decoded rgb -> 2 rgb - 1).
//
// Why a frontier: on an ordinary map most texels are either inside a chart or
// far from every chart, so a full-image scan per pass would spend nearly all
// its time on texels that cannot change. After one full scan finds the
// texels next to the charts, pass k touches only the ring it fills and
// finds ring k + 1 among that ring's neighbours.
//
// Determinism: a pass first computes every value of its ring into a separate
// buffer from texels covered before the pass (the "second buffer"), then
// stores them; each value is a fixed-order sum over one texel's neighbours,
// so neither thread count nor texel order changes a bit. Work is split into
// fixed-size chunks whose outputs are concatenated in chunk order.
#include "nmbake/dilate.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace nmbake {

namespace {

// Neighbour order is part of the contract (fallback = first covered one).
constexpr int neighbour_count = 8;
constexpr int neighbour_dx[neighbour_count] = {-1, 0, 1, -1, 1, -1, 0, 1};
constexpr int neighbour_dy[neighbour_count] = {-1, -1, -1, 0, 0, 1, 1, 1};

// Coverage states while dilate() runs; only 0 and 1 are visible outside.
constexpr std::uint8_t state_empty = 0;
constexpr std::uint8_t state_covered = 1;
constexpr std::uint8_t state_filled_this_pass = 2;

// Texels per chunk of frontier work, rows per chunk of the initial scan:
// large enough to amortise scheduling, small enough to balance two cores.
constexpr std::size_t frontier_chunk_size = 2048;
constexpr int scan_chunk_rows = 8;
constexpr std::size_t kPrefetchAhead = 8;

// Below this squared length the neighbours' vectors cancelled.
constexpr float min_sum_length_squared = 1e-12f;

struct Grid {
  int width;
  int height;
  std::uint8_t* state;

  bool inside(int x, int y) const { return x >= 0 && y >= 0 && x < width && y < height; }
};

// Appends, in row-major order, the empty texels of rows [row_begin, row_end)
// that touch a covered texel.
void scan_rows(const Grid& grid, int row_begin, int row_end, std::vector<std::uint32_t>& out) {
  const int w = grid.width;
  for (int y = row_begin; y < row_end; ++y) {
    const std::uint8_t* up = y > 0 ? grid.state + static_cast<std::size_t>(y - 1) * w : nullptr;
    const std::uint8_t* row = grid.state + static_cast<std::size_t>(y) * w;
    const std::uint8_t* down =
        y + 1 < grid.height ? grid.state + static_cast<std::size_t>(y + 1) * w : nullptr;
    // Rolling OR of the 3-texel columns x-1, x, x+1 keeps this one load per texel.
    auto column = [&](int x) -> std::uint8_t {
      if (x < 0 || x >= w) return 0;
      return static_cast<std::uint8_t>((up ? up[x] : 0) | row[x] | (down ? down[x] : 0));
    };
    std::uint8_t left = 0;
    std::uint8_t centre = column(0);
    for (int x = 0; x < w; ++x) {
      const std::uint8_t right = column(x + 1);
      if (row[x] == state_empty && (left | centre | right) != 0) {
        out.push_back(static_cast<std::uint32_t>(static_cast<std::size_t>(y) * w + x));
      }
      left = centre;
      centre = right;
    }
  }
}

// The neighbours of one frontier texel covered before this pass, in the
// fixed neighbour order (found once for every layer).
struct Neighbours {
  std::uint32_t index[neighbour_count];
  int count;
};

Neighbours covered_neighbours(const Grid& grid, std::uint32_t index) {
  Neighbours n;
  n.count = 0;
  const int x = static_cast<int>(index % static_cast<std::uint32_t>(grid.width));
  const int y = static_cast<int>(index / static_cast<std::uint32_t>(grid.width));
  for (int k = 0; k < neighbour_count; ++k) {
    const int nx = x + neighbour_dx[k];
    const int ny = y + neighbour_dy[k];
    if (!grid.inside(nx, ny)) continue;
    const std::size_t at = static_cast<std::size_t>(ny) * grid.width + nx;
    if (grid.state[at] != state_covered) continue;
    n.index[n.count++] = static_cast<std::uint32_t>(at);
  }
  return n;
}

// The mean of the neighbours' values, channel by channel, summed in
// registers (summing into `out`, which may alias the image for all the
// compiler knows, stored every addition; the same sums in the same order).
template <int kChannels>
void mean_of(const float* pixels, const Neighbours& n, float* out) {
  float sum[kChannels] = {};
  for (int k = 0; k < n.count; ++k) {
    const float* p = pixels + std::size_t{n.index[k]} * kChannels;
    for (int c = 0; c < kChannels; ++c) sum[c] += p[c];
  }
  for (int c = 0; c < kChannels; ++c) out[c] = sum[c] / static_cast<float>(n.count);
}

// The value of one frontier texel from its covered neighbours, for
// DilateMode::mean and ::nearest. Never a fallback.
bool fill_plain(const Image& image, const Neighbours& n, float* out, DilateMode mode) {
  const int channels = image.channels;
  NMBAKE_DCHECK(n.count > 0, "a frontier texel has no covered neighbour");
  if (n.count == 0) {
    std::fill(out, out + channels, 0.0f);
    return false;
  }
  if (mode == DilateMode::nearest) {
    const float* p = image.pixels.data() + std::size_t{n.index[0]} * channels;
    std::copy(p, p + channels, out);
    return false;
  }
  switch (channels) {
    case 1:
      mean_of<1>(image.pixels.data(), n, out);
      break;
    case 3:
      mean_of<3>(image.pixels.data(), n, out);
      break;
    default:
      for (int c = 0; c < channels; ++c) out[c] = 0.0f;
      for (int k = 0; k < n.count; ++k) {
        const float* p = image.pixels.data() + std::size_t{n.index[k]} * channels;
        for (int c = 0; c < channels; ++c) out[c] += p[c];
      }
      for (int c = 0; c < channels; ++c) out[c] /= static_cast<float>(n.count);
  }
  return false;
}

// The value of one frontier texel from its covered neighbours, for
// DilateMode::unit_vector. Returns whether the cancelled-vectors fallback
// was taken.
bool fill_value(const Image& image, const Neighbours& n, float* out) {
  const int channels = image.channels;
  NMBAKE_DCHECK(n.count > 0, "a frontier texel has no covered neighbour");
  if (n.count == 0) {
    std::fill(out, out + channels, 0.0f);
    return false;
  }
  float sum[3] = {0.0f, 0.0f, 0.0f};
  for (int c = 3; c < channels; ++c) out[c] = 0.0f;
  for (int k = 0; k < n.count; ++k) {
    const float* p = image.pixels.data() + std::size_t{n.index[k]} * channels;
    for (int c = 0; c < 3; ++c) sum[c] += 2.0f * p[c] - 1.0f;
    for (int c = 3; c < channels; ++c) out[c] += p[c];
  }
  const float length_squared = sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2];
  if (!(length_squared >= min_sum_length_squared)) {
    const float* first = image.pixels.data() + std::size_t{n.index[0]} * channels;
    std::copy(first, first + channels, out);
    return true;
  }
  // Division (not multiplication by 1/length) keeps k equal unit vectors exact.
  const float length = std::sqrt(length_squared);
  for (int c = 0; c < 3; ++c) out[c] = 0.5f * (sum[c] / length) + 0.5f;
  for (int c = 3; c < channels; ++c) out[c] /= static_cast<float>(n.count);
  return false;
}

}  // namespace

void dilate(Image& image, std::vector<std::uint8_t>& coverage, int padding, DilateStats& stats,
            DilateMode mode) {
  dilate(std::vector<DilateLayer>{{&image, mode}}, coverage, padding, stats);
}

void dilate(const std::vector<DilateLayer>& layers, std::vector<std::uint8_t>& coverage, int padding,
            DilateStats& stats) {
  stats = DilateStats{};
  NMBAKE_CHECK(!layers.empty(), "dilate: at least one image");
  const Image& image = *layers.front().image;
  for (const DilateLayer& layer : layers) {
    NMBAKE_CHECK(layer.image->width == image.width && layer.image->height == image.height,
                 "dilate: the images have one size");
    NMBAKE_CHECK(layer.image->pixels.size() ==
                     static_cast<std::size_t>(image.width) * image.height * layer.image->channels,
                 "dilate: pixel buffer does not match the size");
    NMBAKE_CHECK(layer.image->channels >= (layer.mode == DilateMode::unit_vector ? 3 : 1),
                 "dilate: a unit-vector image needs at least 3 channels (a vector per texel)");
  }
  NMBAKE_CHECK(image.width >= 0 && image.height >= 0, "dilate: negative image size");
  const std::size_t texel_count =
      static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height);
  NMBAKE_CHECK(texel_count <= std::numeric_limits<std::uint32_t>::max(),
               "dilate: image too large for 32-bit indices");
  NMBAKE_CHECK(coverage.size() == texel_count, "dilate: coverage does not have one entry per texel");
  NMBAKE_CHECK(
      std::none_of(coverage.begin(), coverage.end(), [](std::uint8_t c) { return c > state_covered; }),
      "dilate: coverage entries must be 0 or 1");
  if (padding <= 0 || texel_count == 0) return;

  const Grid grid{image.width, image.height, coverage.data()};

  // Reused for every pass: the ring being filled, the next ring, the ring's
  // new values, and per-chunk outputs (their capacity is kept).
  std::vector<std::uint32_t> frontier;
  std::vector<std::uint32_t> next_frontier;
  std::vector<std::vector<float>> values(layers.size());
  std::vector<std::vector<std::uint32_t>> chunk_lists;
  std::vector<std::uint64_t> chunk_fallback_counts;

  auto gather_chunks = [&](std::size_t chunk_count, std::vector<std::uint32_t>& out) {
    std::size_t total = 0;
    for (std::size_t i = 0; i < chunk_count; ++i) total += chunk_lists[i].size();
    out.clear();
    out.reserve(total);
    for (std::size_t i = 0; i < chunk_count; ++i)
      out.insert(out.end(), chunk_lists[i].begin(), chunk_lists[i].end());
  };

  {
    const std::size_t chunk_count =
        (static_cast<std::size_t>(image.height) + scan_chunk_rows - 1) / scan_chunk_rows;
    chunk_lists.resize(chunk_count);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, chunk_count), [&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) {
            chunk_lists[i].clear();
            const int row_begin = static_cast<int>(i) * scan_chunk_rows;
            scan_rows(grid, row_begin, std::min(row_begin + scan_chunk_rows, image.height), chunk_lists[i]);
          }
        });
    gather_chunks(chunk_count, frontier);
  }

  for (int pass = 0; pass < padding && !frontier.empty(); ++pass) {
    const std::size_t ring_count = frontier.size();
    const std::size_t chunk_count = (ring_count + frontier_chunk_size - 1) / frontier_chunk_size;
    if (chunk_lists.size() < chunk_count) chunk_lists.resize(chunk_count);
    chunk_fallback_counts.assign(chunk_count, 0);
    for (std::size_t l = 0; l < layers.size(); ++l) values[l].resize(ring_count * layers[l].image->channels);

    auto for_each_chunk = [&](auto&& body) {
      tbb::parallel_for(
          tbb::blocked_range<std::size_t>(0, chunk_count), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
              body(i, i * frontier_chunk_size, std::min((i + 1) * frontier_chunk_size, ring_count));
            }
          });
    };

    // 1. Values from texels covered before the pass; the images are not written.
    for_each_chunk([&](std::size_t chunk, std::size_t begin, std::size_t end) {
      std::uint64_t fallback_count = 0;
      std::vector<Neighbours> neighbours(end - begin);
      for (std::size_t j = begin; j < end; ++j) neighbours[j - begin] = covered_neighbours(grid, frontier[j]);
      // Texel by texel, every layer: the layers' reads of one texel's
      // neighbours are in flight together, and those of the texel eight
      // ahead are prefetched (ring texels lie apart along the charts'
      // edges: every neighbour read missed the cache; BM_Dilate/set 29-31
      // -> 22-23 ms with mean_of()'s register sums, neither alone gained).
      for (std::size_t j = begin; j < end; ++j) {
        const Neighbours& n = neighbours[j - begin];
        if (j + kPrefetchAhead < end) {
          const Neighbours& ahead = neighbours[j + kPrefetchAhead - begin];
          for (std::size_t l = 0; l < layers.size(); ++l) {
            const Image& layer = *layers[l].image;
            for (int k = 0; k < ahead.count; ++k) {
              __builtin_prefetch(layer.pixels.data() + std::size_t{ahead.index[k]} * layer.channels);
            }
          }
        }
        for (std::size_t l = 0; l < layers.size(); ++l) {
          const Image& layer = *layers[l].image;
          const DilateMode mode = layers[l].mode;
          float* value = values[l].data() + j * layer.channels;
          const bool fallback = mode == DilateMode::unit_vector ? fill_value(layer, n, value)
                                                                : fill_plain(layer, n, value, mode);
          if (fallback) ++fallback_count;
        }
      }
      chunk_fallback_counts[chunk] = fallback_count;
    });

    // 2. Store them; mark the ring so step 3 can tell it from older coverage.
    for_each_chunk([&](std::size_t, std::size_t begin, std::size_t end) {
      for (std::size_t j = begin; j < end; ++j) {
        const std::uint32_t index = frontier[j];
        for (std::size_t l = 0; l < layers.size(); ++l) {
          const int channels = layers[l].image->channels;
          std::copy_n(values[l].data() + j * channels, channels,
                      layers[l].image->pixels.data() + std::size_t{index} * channels);
        }
        coverage[index] = state_filled_this_pass;
      }
    });

    // 3. Next ring: empty neighbours of this ring. Each is listed once, by
    // its first neighbour (in the fixed order) that belongs to this ring.
    for_each_chunk([&](std::size_t chunk, std::size_t begin, std::size_t end) {
      std::vector<std::uint32_t>& out = chunk_lists[chunk];
      out.clear();
      for (std::size_t j = begin; j < end; ++j) {
        const std::uint32_t index = frontier[j];
        const int x = static_cast<int>(index % static_cast<std::uint32_t>(grid.width));
        const int y = static_cast<int>(index / static_cast<std::uint32_t>(grid.width));
        for (int k = 0; k < neighbour_count; ++k) {
          const int nx = x + neighbour_dx[k];
          const int ny = y + neighbour_dy[k];
          if (!grid.inside(nx, ny)) continue;
          const std::size_t candidate = static_cast<std::size_t>(ny) * grid.width + nx;
          if (coverage[candidate] != state_empty) continue;
          for (int m = 0; m < neighbour_count; ++m) {
            const int ox = nx + neighbour_dx[m];
            const int oy = ny + neighbour_dy[m];
            if (!grid.inside(ox, oy)) continue;
            const std::size_t owner = static_cast<std::size_t>(oy) * grid.width + ox;
            if (coverage[owner] == state_filled_this_pass) {
              if (owner == index) out.push_back(static_cast<std::uint32_t>(candidate));
              break;
            }
          }
        }
      }
    });

    // 4. The ring becomes ordinary coverage.
    for_each_chunk([&](std::size_t, std::size_t begin, std::size_t end) {
      for (std::size_t j = begin; j < end; ++j) coverage[frontier[j]] = state_covered;
    });

    stats.filled_texels += ring_count;
    for (std::size_t i = 0; i < chunk_count; ++i) stats.fallback_texels += chunk_fallback_counts[i];
    gather_chunks(chunk_count, next_frontier);
    frontier.swap(next_frontier);
  }
}

}  // namespace nmbake
