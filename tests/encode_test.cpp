#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include "nmbake/encode.hpp"

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
  EXPECT_FALSE(world_to_tangent({0, 0, 1}, {0, 0, 1}, {0, 0, 1}, 1.0f, TangentEncode::inverse, t));  // T parallel N
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

}  // namespace
}  // namespace nmbake
