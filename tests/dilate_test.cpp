// Tests of the "dilate" stage: exact shapes and values on tiny images, the
// fallback for cancelling vectors, agreement with a straightforward
// full-image reference, and byte-identical results for any thread count.
#include "nmbake/dilate.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace nmbake {
namespace {

Image blank(int width, int height, int channels, float value = 0.0f) {
  Image image;
  image.width = width;
  image.height = height;
  image.channels = channels;
  image.pixels.assign(static_cast<std::size_t>(width) * height * channels, value);
  return image;
}

void set_vector(Image& image, std::vector<std::uint8_t>& coverage, int x, int y, float nx, float ny,
                float nz) {
  float* p = image.at(x, y);
  p[0] = 0.5f * nx + 0.5f;
  p[1] = 0.5f * ny + 0.5f;
  p[2] = 0.5f * nz + 0.5f;
  coverage[static_cast<std::size_t>(y) * image.width + x] = 1;
}

// The contract written the obvious way: every pass scans every texel and
// reads a copy of the previous pass.
void reference_dilate(Image& image, std::vector<std::uint8_t>& coverage, int padding) {
  const int w = image.width;
  const int h = image.height;
  const int ch = image.channels;
  const int dx[8] = {-1, 0, 1, -1, 1, -1, 0, 1};
  const int dy[8] = {-1, -1, -1, 0, 0, 1, 1, 1};
  for (int pass = 0; pass < padding; ++pass) {
    const Image before = image;
    const std::vector<std::uint8_t> covered_before = coverage;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if (covered_before[static_cast<std::size_t>(y) * w + x]) continue;
        float sum[3] = {0, 0, 0};
        std::vector<float> extra(ch > 3 ? ch - 3 : 0, 0.0f);
        const float* first = nullptr;
        int n = 0;
        for (int k = 0; k < 8; ++k) {
          const int nx = x + dx[k];
          const int ny = y + dy[k];
          if (nx < 0 || ny < 0 || nx >= w || ny >= h ||
              !covered_before[static_cast<std::size_t>(ny) * w + nx])
            continue;
          const float* p = before.at(nx, ny);
          if (!first) first = p;
          for (int c = 0; c < 3; ++c) sum[c] += 2.0f * p[c] - 1.0f;
          for (int c = 3; c < ch; ++c) extra[c - 3] += p[c];
          ++n;
        }
        if (n == 0) continue;
        float* out = image.at(x, y);
        const float len2 = sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2];
        if (len2 < 1e-12f) {
          for (int c = 0; c < ch; ++c) out[c] = first[c];
        } else {
          const float len = std::sqrt(len2);
          for (int c = 0; c < 3; ++c) out[c] = 0.5f * (sum[c] / len) + 0.5f;
          for (int c = 3; c < ch; ++c) out[c] = extra[c - 3] / static_cast<float>(n);
        }
        coverage[static_cast<std::size_t>(y) * w + x] = 1;
      }
    }
  }
}

// Small discs ("charts") of unit vectors that vary texel to texel, from a
// fixed linear congruential sequence.
void make_charts(int width, int height, int channels, int chart_count, Image& image,
                 std::vector<std::uint8_t>& coverage) {
  image = blank(width, height, channels, 0.25f);
  coverage.assign(static_cast<std::size_t>(width) * height, 0);
  std::uint32_t state = 12345;
  auto next = [&]() {
    state = state * 1664525u + 1013904223u;
    return static_cast<float>(state >> 8) / static_cast<float>(1u << 24);
  };
  for (int chart = 0; chart < chart_count; ++chart) {
    const float cx = next() * width;
    const float cy = next() * height;
    const float r = 1.0f + next() * 6.0f;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        if ((x - cx) * (x - cx) + (y - cy) * (y - cy) > r * r) continue;
        float v[3] = {next() - 0.5f, next() - 0.5f, next() + 0.2f};
        const float len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        set_vector(image, coverage, x, y, v[0] / len, v[1] / len, v[2] / len);
        for (int c = 3; c < channels; ++c) image.at(x, y)[c] = next();
      }
    }
  }
}

TEST(Dilate, SingleTexelGrowsIntoSquares) {
  for (int padding : {1, 3}) {
    SCOPED_TRACE(padding);
    Image image = blank(11, 11, 3);
    std::vector<std::uint8_t> coverage(11 * 11, 0);
    set_vector(image, coverage, 5, 5, 0.0f, 0.0f, 1.0f);
    DilateStats stats;
    dilate(image, coverage, padding, stats);
    const int side = 2 * padding + 1;
    EXPECT_EQ(stats.filled_texels, static_cast<std::uint64_t>(side * side - 1));
    EXPECT_EQ(stats.fallback_texels, 0u);
    for (int y = 0; y < 11; ++y) {
      for (int x = 0; x < 11; ++x) {
        const bool inside = std::abs(x - 5) <= padding && std::abs(y - 5) <= padding;
        ASSERT_EQ(coverage[y * 11 + x], inside ? 1 : 0) << x << "," << y;
        const float* p = image.at(x, y);
        if (inside) {
          // k copies of (0,0,1) normalise back to exactly (0,0,1).
          EXPECT_EQ(p[0], 0.5f);
          EXPECT_EQ(p[1], 0.5f);
          EXPECT_EQ(p[2], 1.0f);
        } else {
          EXPECT_EQ(p[0], 0.0f);
          EXPECT_EQ(p[1], 0.0f);
          EXPECT_EQ(p[2], 0.0f);
        }
      }
    }
  }
}

TEST(Dilate, CornerTexelStaysInsideTheImage) {
  Image image = blank(4, 3, 3);
  std::vector<std::uint8_t> coverage(4 * 3, 0);
  set_vector(image, coverage, 3, 2, 1.0f, 0.0f, 0.0f);
  DilateStats stats;
  dilate(image, coverage, 1, stats);
  EXPECT_EQ(stats.filled_texels, 3u);
  const std::vector<std::uint8_t> expected = {0, 0, 0, 0,  //
                                              0, 0, 1, 1,  //
                                              0, 0, 1, 1};
  EXPECT_EQ(coverage, expected);
  EXPECT_EQ(image.at(2, 1)[0], 1.0f);
  EXPECT_EQ(image.at(2, 1)[1], 0.5f);
}

TEST(Dilate, MeanOfTwoNeighboursIsNormalised) {
  Image image = blank(3, 1, 3);
  std::vector<std::uint8_t> coverage(3, 0);
  set_vector(image, coverage, 0, 0, 1.0f, 0.0f, 0.0f);
  set_vector(image, coverage, 2, 0, 0.0f, 1.0f, 0.0f);
  DilateStats stats;
  dilate(image, coverage, 1, stats);
  EXPECT_EQ(stats.filled_texels, 1u);
  const float* p = image.at(1, 0);
  // normalize((1,1,0)) encoded; the plain mean would give 0.75.
  EXPECT_NEAR(p[0], 0.5f + 0.5f / std::sqrt(2.0f), 1e-6f);
  EXPECT_NEAR(p[1], 0.5f + 0.5f / std::sqrt(2.0f), 1e-6f);
  EXPECT_NEAR(p[2], 0.5f, 1e-6f);
}

TEST(Dilate, CancellingNeighboursCopyTheFirstInOrder) {
  // Left and right are opposite: the left one (earlier in row-major order) wins.
  Image image = blank(3, 1, 4);
  std::vector<std::uint8_t> coverage(3, 0);
  set_vector(image, coverage, 0, 0, 1.0f, 0.0f, 0.0f);
  image.at(0, 0)[3] = 0.25f;
  set_vector(image, coverage, 2, 0, -1.0f, 0.0f, 0.0f);
  image.at(2, 0)[3] = 0.75f;
  DilateStats stats;
  dilate(image, coverage, 1, stats);
  EXPECT_EQ(stats.fallback_texels, 1u);
  for (int c = 0; c < 4; ++c) EXPECT_EQ(image.at(1, 0)[c], image.at(0, 0)[c]) << c;

  // Up and down are opposite: up comes first.
  Image column = blank(1, 3, 3);
  std::vector<std::uint8_t> column_coverage(3, 0);
  set_vector(column, column_coverage, 0, 2, 0.0f, 0.0f, -1.0f);
  set_vector(column, column_coverage, 0, 0, 0.0f, 0.0f, 1.0f);
  dilate(column, column_coverage, 1, stats);
  EXPECT_EQ(stats.fallback_texels, 1u);
  EXPECT_EQ(column.at(0, 1)[2], 1.0f);
}

TEST(Dilate, ExtraChannelsTakeThePlainMean) {
  Image image = blank(3, 1, 4);
  std::vector<std::uint8_t> coverage(3, 0);
  set_vector(image, coverage, 0, 0, 0.0f, 0.0f, 1.0f);
  image.at(0, 0)[3] = 0.2f;
  set_vector(image, coverage, 2, 0, 0.0f, 0.0f, 1.0f);
  image.at(2, 0)[3] = 0.6f;
  DilateStats stats;
  dilate(image, coverage, 1, stats);
  EXPECT_NEAR(image.at(1, 0)[3], 0.4f, 1e-7f);
  EXPECT_EQ(image.at(1, 0)[2], 1.0f);
}

TEST(Dilate, NothingToDo) {
  Image image = blank(5, 5, 3, 0.3f);
  std::vector<std::uint8_t> coverage(25, 0);
  DilateStats stats;
  dilate(image, coverage, 4, stats);  // nothing covered
  EXPECT_EQ(stats.filled_texels, 0u);
  EXPECT_EQ(coverage, std::vector<std::uint8_t>(25, 0));

  set_vector(image, coverage, 2, 2, 0.0f, 0.0f, 1.0f);
  const Image before = image;
  dilate(image, coverage, 0, stats);  // no padding
  EXPECT_EQ(stats.filled_texels, 0u);
  EXPECT_EQ(image.pixels, before.pixels);

  std::vector<std::uint8_t> full(25, 1);
  dilate(image, full, 3, stats);  // everything covered
  EXPECT_EQ(stats.filled_texels, 0u);
  EXPECT_EQ(image.pixels, before.pixels);
}

TEST(Dilate, MatchesReferenceAndKeepsCoveredTexels) {
  for (int channels : {3, 4}) {
    SCOPED_TRACE(channels);
    Image image;
    std::vector<std::uint8_t> coverage;
    make_charts(64, 48, channels, 12, image, coverage);
    const Image original = image;
    const std::vector<std::uint8_t> original_coverage = coverage;

    Image expected = image;
    std::vector<std::uint8_t> expected_coverage = coverage;
    reference_dilate(expected, expected_coverage, 5);

    DilateStats stats;
    dilate(image, coverage, 5, stats);
    ASSERT_EQ(coverage, expected_coverage);
    std::uint64_t filled_count = 0;
    for (std::size_t t = 0; t < coverage.size(); ++t) {
      if (original_coverage[t]) {
        // Covered texels never change, bit for bit.
        ASSERT_EQ(std::memcmp(&image.pixels[t * channels], &original.pixels[t * channels],
                              sizeof(float) * channels),
                  0);
      } else if (coverage[t]) {
        ++filled_count;
      }
      for (int c = 0; c < channels; ++c) {
        ASSERT_FLOAT_EQ(image.pixels[t * channels + c], expected.pixels[t * channels + c]) << "texel " << t;
      }
    }
    EXPECT_EQ(stats.filled_texels, filled_count);
    EXPECT_GT(filled_count, 100u);
    EXPECT_LT(filled_count, coverage.size());  // padding 5 does not reach everywhere
  }
}

TEST(Dilate, SameBytesForAnyThreadCount) {
  // Large enough for several work chunks per pass.
  Image source;
  std::vector<std::uint8_t> source_coverage;
  make_charts(512, 384, 3, 150, source, source_coverage);

  std::vector<Image> results;
  std::vector<std::vector<std::uint8_t>> coverages;
  std::vector<DilateStats> all_stats;
  for (int threads : {1, 2, 3}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    Image image = source;
    std::vector<std::uint8_t> coverage = source_coverage;
    DilateStats stats;
    dilate(image, coverage, 10, stats);
    results.push_back(std::move(image));
    coverages.push_back(std::move(coverage));
    all_stats.push_back(stats);
  }
  EXPECT_GT(all_stats[0].filled_texels, 20000u);
  for (std::size_t i = 1; i < results.size(); ++i) {
    ASSERT_EQ(results[i].pixels.size(), results[0].pixels.size());
    EXPECT_EQ(std::memcmp(results[i].pixels.data(), results[0].pixels.data(),
                          results[0].pixels.size() * sizeof(float)),
              0);
    EXPECT_EQ(coverages[i], coverages[0]);
    EXPECT_EQ(all_stats[i].filled_texels, all_stats[0].filled_texels);
    EXPECT_EQ(all_stats[i].fallback_texels, all_stats[0].fallback_texels);
  }
}

}  // namespace
}  // namespace nmbake
