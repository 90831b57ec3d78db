#include "nmbake/encode.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <iostream>

#include "nmbake/surface.hpp"

namespace nmbake {
namespace {

float angle_degrees(const glm::vec3& a, const glm::vec3& b) {
  const glm::dvec3 da(a), db(b);
  return static_cast<float>(glm::degrees(std::atan2(glm::length(glm::cross(da, db)), glm::dot(da, db))));
}

TEST(Encode, OrthonormalFrameIsIdentity) {
  glm::vec3 t;
  ASSERT_TRUE(world_to_tangent(glm::normalize(glm::vec3(0.3f, -0.2f, 0.9f)), {1, 0, 0}, {0, 0, 1}, 1.0f,
                               TangentEncode::inverse, t));
  EXPECT_NEAR(t.x, glm::normalize(glm::vec3(0.3f, -0.2f, 0.9f)).x, 1e-6f);
  EXPECT_NEAR(t.y, glm::normalize(glm::vec3(0.3f, -0.2f, 0.9f)).y, 1e-6f);
}

TEST(Encode, MirroredSignFlipsBitangent) {
  glm::vec3 t;
  ASSERT_TRUE(world_to_tangent({0, 1, 0}, {1, 0, 0}, {0, 0, 1}, -1.0f, TangentEncode::inverse, t));
  // B = -cross(N, T) = -(0, 1, 0): a world +y normal is tangent-space -y.
  EXPECT_NEAR(t.y, -1.0f, 1e-6f);
}

// The exact inverse survives the MikkTSpace decode for skewed, unnormalised
// frames, which is the whole point; the transpose does not.
TEST(Encode, InverseRoundTripsThroughDecodeOnSkewedFrames) {
  const glm::vec3 T(1.3f, 0.4f, 0.2f);   // not unit, not orthogonal to N
  const glm::vec3 N(0.1f, 0.2f, 0.85f);  // interpolated normals are shorter than 1
  float worst_inverse = 0.0f, worst_transpose = 0.0f;
  for (int i = 0; i < 200; ++i) {
    const float a = 0.1f * i, b = 0.037f * i;
    const glm::vec3 n = glm::normalize(glm::vec3(0.4f * std::cos(a), 0.4f * std::sin(b), 1.0f) + 0.2f * N);
    glm::vec3 t;
    ASSERT_TRUE(world_to_tangent(n, T, N, 1.0f, TangentEncode::inverse, t));
    worst_inverse = std::max(worst_inverse, angle_degrees(tangent_to_world(t, T, N, 1.0f), n));
    world_to_tangent(n, T, N, 1.0f, TangentEncode::transpose, t);
    worst_transpose = std::max(worst_transpose, angle_degrees(tangent_to_world(t, T, N, 1.0f), n));
  }
  EXPECT_LT(worst_inverse, 1e-3f);
  EXPECT_GT(worst_transpose, 1.0f);
}

TEST(Encode, SingularFrameFallsBackWithoutNaN) {
  glm::vec3 t;
  EXPECT_FALSE(
      world_to_tangent({0, 0, 1}, {0, 0, 1}, {0, 0, 1}, 1.0f, TangentEncode::inverse, t));  // T parallel N
  EXPECT_TRUE(std::isfinite(t.x) && std::isfinite(t.y) && std::isfinite(t.z));
  EXPECT_NEAR(glm::length(t), 1.0f, 1e-5f);
  EXPECT_FALSE(world_to_tangent({0, 0, 1}, {0, 0, 0}, {0, 0, 0}, 1.0f, TangentEncode::inverse, t));
  EXPECT_TRUE(std::isfinite(t.x) && std::isfinite(t.y) && std::isfinite(t.z));
}

// A two-triangle quad in the xy plane with u = x, v = y: the tangent frame is
// the identity, so the encoded colour is 0.5 n + 0.5 of the high normal.
struct QuadFixture {
  LowSurface surface;
  Mesh high;
  TexelSamples samples;
  Hits hits;
  QuadFixture() {
    const glm::vec3 p[4] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    const int tri[6] = {0, 1, 2, 0, 2, 3};
    for (int c : tri) {
      surface.position.push_back(p[c]);
      surface.uv.push_back({p[c].x, p[c].y});
      surface.normal.push_back({0, 0, 1});
      surface.cage_normal.push_back({0, 0, 1});
      surface.tangent.push_back({1, 0, 0, 1});
    }
    high.positions = {{0, 0, 0.1f}, {1, 0, 0.1f}, {0, 1, 0.1f}};
    high.indices = {0, 1, 2};
    high.normals = {glm::normalize(glm::vec3(0.5f, 0.0f, 1.0f)), glm::normalize(glm::vec3(0.5f, 0.0f, 1.0f)),
                    glm::normalize(glm::vec3(0.5f, 0.0f, 1.0f))};
    samples.width = 2;
    samples.height = 1;
    samples.samples = 1;
    samples.triangle = {0, 0};
    samples.bary = {{0.2f, 0.2f}, {0.3f, 0.1f}};
    samples.coverage = {1, 1};
    hits.triangle = {0, -1};  // texel 1 missed
    hits.bary = {{0.3f, 0.3f}, {0, 0}};
    hits.distance = {0.0f, 0.0f};
  }
};

TEST(Encode, TangentSpaceColoursAndMisses) {
  QuadFixture f;
  Image image;
  EncodeStats stats;
  encode(f.surface, f.samples, f.high, f.hits, EncodeOptions{}, image, stats);
  const glm::vec3 n = glm::normalize(glm::vec3(0.5f, 0.0f, 1.0f));
  EXPECT_NEAR(image.at(0, 0)[0], 0.5f * n.x + 0.5f, 1e-6f);
  EXPECT_NEAR(image.at(0, 0)[1], 0.5f, 1e-6f);
  EXPECT_NEAR(image.at(0, 0)[2], 0.5f * n.z + 0.5f, 1e-6f);
  // The miss keeps the low normal: (0, 0, 1).
  EXPECT_FLOAT_EQ(image.at(1, 0)[0], 0.5f);
  EXPECT_FLOAT_EQ(image.at(1, 0)[1], 0.5f);
  EXPECT_FLOAT_EQ(image.at(1, 0)[2], 1.0f);
}

TEST(Encode, GreenDownNegatesY) {
  QuadFixture f;
  f.high.normals.assign(3, glm::normalize(glm::vec3(0.0f, 0.5f, 1.0f)));
  Image up, down;
  EncodeStats stats;
  EncodeOptions options;
  encode(f.surface, f.samples, f.high, f.hits, options, up, stats);
  options.green = GreenChannel::down;
  encode(f.surface, f.samples, f.high, f.hits, options, down, stats);
  EXPECT_GT(up.at(0, 0)[1], 0.6f);
  EXPECT_NEAR(down.at(0, 0)[1], 1.0f - up.at(0, 0)[1], 1e-6f);
  EXPECT_FLOAT_EQ(down.at(0, 0)[0], up.at(0, 0)[0]);
}

TEST(Encode, FaceNormalsIgnoreVertexNormals) {
  QuadFixture f;
  Image image;
  EncodeStats stats;
  EncodeOptions options;
  options.high_normals = HighNormals::face;
  encode(f.surface, f.samples, f.high, f.hits, options, image, stats);
  EXPECT_NEAR(image.at(0, 0)[0], 0.5f, 1e-6f);  // the high triangle is flat, facing +z
  EXPECT_NEAR(image.at(0, 0)[2], 1.0f, 1e-6f);
}

TEST(Encode, ObjectSpaceStoresWorldNormal) {
  QuadFixture f;
  // Rotate the low frame: object space must not care.
  for (auto& t : f.surface.tangent) t = {0, 1, 0, 1};
  Image image;
  EncodeStats stats;
  EncodeOptions options;
  options.space = NormalSpace::object;
  encode(f.surface, f.samples, f.high, f.hits, options, image, stats);
  const glm::vec3 n = glm::normalize(glm::vec3(0.5f, 0.0f, 1.0f));
  EXPECT_NEAR(image.at(0, 0)[0], 0.5f * n.x + 0.5f, 1e-6f);
  EXPECT_NEAR(image.at(1, 0)[2], 1.0f, 1e-6f);  // miss: the low normal (0, 0, 1)
}

TEST(Encode, ZeroLengthHighNormalFallsBackToFace) {
  QuadFixture f;
  f.high.normals = {{1, 0, 0}, {-1, 0, 0}, {0, 0, 0}};
  f.hits.bary[0] = {0.5f, 0.0f};  // (1,0,0) and (-1,0,0) cancel
  Image image;
  EncodeStats stats;
  encode(f.surface, f.samples, f.high, f.hits, EncodeOptions{}, image, stats);
  EXPECT_EQ(stats.zero_high_normals, 1u);
  EXPECT_NEAR(image.at(0, 0)[2], 1.0f, 1e-6f);
}

// The four-lane path (tangent space, smooth normals, inverse) against a
// reference written here from world_to_tangent(): random skewed and mirrored
// frames, one singular frame, a zero-length high normal, misses and samples
// outside the chart mixed into the lanes, at 1 and 4 samples per texel and
// a row length that leaves a scalar tail.
TEST(Encode, FourLanePathMatchesThePerSampleReference) {
  std::uint32_t h = 2024;
  auto rnd = [&] { return static_cast<float>((h = h * 1664525u + 1013904223u) >> 8) / 16777216.0f; };
  LowSurface surface;
  const int low_triangles = 7;
  for (int t = 0; t < low_triangles; ++t) {
    for (int c = 0; c < 3; ++c) {
      surface.position.push_back({rnd(), rnd(), rnd()});
      surface.uv.push_back({rnd(), rnd()});
      surface.normal.push_back({0.3f * (rnd() - 0.5f), 0.3f * (rnd() - 0.5f), 0.5f + rnd()});
      surface.cage_normal.push_back(surface.normal.back());
      // Skewed, unnormalised tangents; triangles 2 and 5 mirrored.
      surface.tangent.push_back(
          {0.5f + rnd(), rnd() - 0.5f, rnd() - 0.5f, (t == 2 || t == 5) ? -1.0f : 1.0f});
    }
  }
  // Triangle 3: the tangent parallel to the normal (a singular frame).
  for (int c = 0; c < 3; ++c) surface.tangent[9 + c] = glm::vec4(surface.normal[9 + c], 1.0f);
  fill_corner_bitangents(surface);
  Mesh high;
  for (int v = 0; v < 30; ++v) {
    high.positions.push_back({rnd(), rnd(), rnd()});
    high.normals.push_back(glm::normalize(glm::vec3(rnd() - 0.5f, rnd() - 0.5f, 1.0f)));
  }
  high.normals[4] = -high.normals[5];  // triangle 1 (vertices 3, 4, 5): zero normal halfway from 4 to 5
  for (std::uint32_t t = 0; t < 10; ++t)
    high.indices.insert(high.indices.end(), {3 * t, 3 * t + 1, 3 * t + 2});

  for (int spp : {1, 4, 16}) {
    SCOPED_TRACE("spp " + std::to_string(spp));
    TexelSamples samples;
    samples.width = 37;
    samples.height = 3;
    samples.samples = spp;
    Hits hits;
    const std::size_t count = static_cast<std::size_t>(samples.width) * samples.height * spp;
    for (std::size_t s = 0; s < count; ++s) {
      const float r = rnd();
      const bool same_as_last =
          s % spp != 0 && samples.triangle.back() >= 0 && rnd() < 0.8f;  // as rasters do
      if (same_as_last) {
        samples.triangle.push_back(samples.triangle.back());
      } else {
        samples.triangle.push_back(
            r < 0.05f ? -1 : static_cast<std::int32_t>(rnd() * low_triangles) % low_triangles);
      }
      const float bu = rnd(), bv = rnd() * (1.0f - bu);
      samples.bary.push_back({bu, bv});
      const float m = rnd();
      hits.triangle.push_back(m < 0.08f ? -1 : static_cast<std::int32_t>(rnd() * 10) % 10);
      hits.bary.push_back(hits.triangle.back() == 1 && m < 0.3f ? glm::vec2(0.5f, 0.5f)
                                                                : glm::vec2(rnd() * 0.5f, rnd() * 0.5f));
      hits.distance.push_back(0.0f);
    }
    samples.coverage.assign(static_cast<std::size_t>(samples.width) * samples.height, 0);
    for (std::size_t t = 0; t < samples.coverage.size(); ++t)
      for (int k = 0; k < spp; ++k) samples.coverage[t] |= samples.triangle[t * spp + k] >= 0 ? 1 : 0;

    // Every engine decode (preset.hpp) in lanes: the bytes and counts of the
    // per-sample path (which the reference below checks for the default).
    for (const NormalDecode decode :
         {NormalDecode{Bitangent::vertex, false, false}, NormalDecode{Bitangent::pixel, true, false},
          NormalDecode{Bitangent::vertex, true, true}}) {
      SCOPED_TRACE(std::string("decode ") + to_string(decode.bitangent) +
                   (decode.unit_frame ? " unit" : " raw"));
      EncodeOptions options;
      options.decode = decode;
      Image reference;
      EncodeStats reference_stats;
      detail::encode_in_lanes(surface, samples, high, hits, options, reference, reference_stats, 1);
      EXPECT_GT(reference_stats.singular_frames, 0u);
      for (const int lanes : {4, 8}) {
        if (lanes == 8 && !detail::encode_has_eight_lanes()) continue;
        Image in_lanes;
        EncodeStats lane_stats;
        detail::encode_in_lanes(surface, samples, high, hits, options, in_lanes, lane_stats, lanes);
        ASSERT_EQ(in_lanes.pixels.size(), reference.pixels.size());
        EXPECT_EQ(0, std::memcmp(in_lanes.pixels.data(), reference.pixels.data(),
                                 in_lanes.pixels.size() * sizeof(float)))
            << lanes << " lanes";
        EXPECT_EQ(lane_stats.singular_frames, reference_stats.singular_frames);
        EXPECT_EQ(lane_stats.zero_high_normals, reference_stats.zero_high_normals);
        EXPECT_EQ(lane_stats.below_horizon, reference_stats.below_horizon);
      }
    }

    Image image;
    EncodeStats stats;
    encode(surface, samples, high, hits, EncodeOptions{}, image, stats);
    // Row blocks on the calling thread (the map set's encoding): uneven
    // ones, an empty one, backwards, give the band's bytes and counts.
    {
      Image blocks;
      blocks.width = samples.width;
      blocks.height = samples.height;
      blocks.channels = 3;
      blocks.pixels.assign(image.pixels.size(), -1.0f);
      EncodeStats block_stats;
      for (const auto& [begin, end] : {std::pair{2, 3}, std::pair{1, 1}, std::pair{0, 2}}) {
        encode_rows(surface, samples, high, hits, EncodeOptions{}, blocks, block_stats, begin, end);
      }
      EXPECT_EQ(0,
                std::memcmp(blocks.pixels.data(), image.pixels.data(), image.pixels.size() * sizeof(float)));
      EXPECT_EQ(block_stats.singular_frames, stats.singular_frames);
      EXPECT_EQ(block_stats.zero_high_normals, stats.zero_high_normals);
      EXPECT_EQ(block_stats.zero_results, stats.zero_results);
      EXPECT_GT(block_stats.singular_frames, 0u);
    }
    // Bit for bit the per-sample path, at four and at eight lanes, both for
    // groups on one low triangle (interpolated across the lanes) and mixed ones.
    for (const int lanes : {4, 8}) {
      SCOPED_TRACE("lanes " + std::to_string(lanes));
      if (lanes == 8 && !detail::encode_has_eight_lanes()) {
        std::cout << "[ note ] no AVX2 here: eight lanes not tested\n";
        continue;
      }
      Image in_lanes, reference;
      EncodeStats lane_stats, reference_stats;
      detail::encode_in_lanes(surface, samples, high, hits, EncodeOptions{}, in_lanes, lane_stats, lanes);
      detail::encode_in_lanes(surface, samples, high, hits, EncodeOptions{}, reference, reference_stats, 1);
      ASSERT_EQ(in_lanes.pixels.size(), reference.pixels.size());
      EXPECT_EQ(0, std::memcmp(in_lanes.pixels.data(), reference.pixels.data(),
                               in_lanes.pixels.size() * sizeof(float)));
      EXPECT_EQ(lane_stats.singular_frames, reference_stats.singular_frames);
      EXPECT_EQ(lane_stats.zero_high_normals, reference_stats.zero_high_normals);
      if (lanes == 8) {
        EXPECT_EQ(
            0, std::memcmp(image.pixels.data(), in_lanes.pixels.data(), image.pixels.size() * sizeof(float)));
      }
    }

    std::uint64_t singular = 0, zero_high = 0;
    auto lerp = [](const auto& c0, const auto& c1, const auto& c2, glm::vec2 b) {
      return c0 * (1.0f - b.x - b.y) + c1 * b.x + c2 * b.y;
    };
    for (std::size_t texel = 0; texel < samples.coverage.size(); ++texel) {
      glm::vec3 expected(0.0f, 0.0f, 1.0f);
      if (samples.coverage[texel]) {
        glm::vec3 sum(0.0f);
        for (int k = 0; k < spp; ++k) {
          const std::size_t s = texel * spp + k;
          const std::int32_t tri = samples.triangle[s];
          if (tri < 0) continue;
          const std::size_t base = 3 * static_cast<std::size_t>(tri);
          if (hits.triangle[s] < 0) {
            sum += glm::vec3(0.0f, 0.0f, 1.0f);
            continue;
          }
          const std::uint32_t* v = &high.indices[3 * static_cast<std::size_t>(hits.triangle[s])];
          glm::vec3 n = lerp(high.normals[v[0]], high.normals[v[1]], high.normals[v[2]], hits.bary[s]);
          if (glm::dot(n, n) <= 1e-24f) {
            ++zero_high;
            n = glm::normalize(glm::cross(high.positions[v[1]] - high.positions[v[0]],
                                          high.positions[v[2]] - high.positions[v[0]]));
          }
          const glm::vec3 N =
              lerp(surface.normal[base], surface.normal[base + 1], surface.normal[base + 2], samples.bary[s]);
          const glm::vec4 T = lerp(surface.tangent[base], surface.tangent[base + 1],
                                   surface.tangent[base + 2], samples.bary[s]);
          glm::vec3 t;
          if (!world_to_tangent(n, glm::vec3(T), N, T.w < 0.0f ? -1.0f : 1.0f, TangentEncode::inverse, t))
            ++singular;
          sum += t;
        }
        expected = glm::normalize(sum);
      }
      const float* p = &image.pixels[texel * 3];
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(p[c], 0.5f * expected[c] + 0.5f, 2e-6f) << "texel " << texel << " channel " << c;
    }
    EXPECT_EQ(stats.singular_frames, singular);
    EXPECT_EQ(stats.zero_high_normals, zero_high);
    EXPECT_GT(singular, 0u);
    EXPECT_GT(zero_high, 0u);
  }
}

}  // namespace
}  // namespace nmbake
