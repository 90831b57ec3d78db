// Tests of the mesh utilities: validation, area-weighted and averaged
// normals with their fallbacks, bounds, Embree padding.
#include "nmbake/mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <string>

namespace nmbake {
namespace {

void expect_near3(const glm::vec3& actual, const glm::vec3& expected, float tolerance = 1e-6f) {
  EXPECT_NEAR(actual.x, expected.x, tolerance);
  EXPECT_NEAR(actual.y, expected.y, tolerance);
  EXPECT_NEAR(actual.z, expected.z, tolerance);
}

Mesh triangle() {
  Mesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.indices = {0, 1, 2};
  return mesh;
}

void expect_invalid(const Mesh& mesh, const std::string& reason) {
  const Status status = validate_mesh(mesh, "m.obj");
  ASSERT_FALSE(status.is_ok()) << reason;
  EXPECT_EQ(status.code(), StatusCode::bad_input);
  EXPECT_EQ(status.message().rfind("m.obj: ", 0), 0u) << status.message();
  EXPECT_NE(status.message().find(reason), std::string::npos) << status.message() << " lacks " << reason;
}

TEST(ValidateMesh, AcceptsAGoodMeshAndRejectsEachDefect) {
  EXPECT_TRUE(validate_mesh(triangle(), "m.obj").is_ok());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  Mesh mesh = triangle();
  mesh.indices.clear();
  expect_invalid(mesh, "no triangles");
  mesh = triangle();
  mesh.indices.push_back(0);
  expect_invalid(mesh, "index count 4 is not a multiple of 3");
  mesh = triangle();
  mesh.indices[2] = 3;
  expect_invalid(mesh, "triangle 0 refers to vertex 3 of 3");
  mesh = triangle();
  mesh.positions[1].y = nan;
  expect_invalid(mesh, "vertex 1 has a non-finite position");
  mesh = triangle();
  mesh.normals = {{0, 0, 1}, {0, 0, 1}};
  expect_invalid(mesh, "2 normals for 3 vertices");
  mesh.normals.push_back({0, inf, 1});
  expect_invalid(mesh, "vertex 2 has a non-finite normal");
  mesh = triangle();
  mesh.uvs = {{0, 0}, {1, 0}, {0, 1}, {1, 1}};
  expect_invalid(mesh, "4 UVs for 3 vertices");
  mesh.uvs = {{0, 0}, {nan, 0}, {0, 1}};
  expect_invalid(mesh, "vertex 1 has a non-finite UV");
}

// Two triangles at a right angle with different areas sharing the edge
// (0,0,0)-(0,2,0), plus a triangle with no area owning vertex 4 alone.
Mesh hinge() {
  Mesh mesh;
  mesh.positions = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 1}, {5, 5, 5}};
  mesh.indices = {0, 1, 2,   // cross (2,0,0)x(0,2,0) = (0,0,4)
                  0, 2, 3,   // cross (0,2,0)x(0,0,1) = (2,0,0)
                  4, 4, 1};  // a sliver: no weight
  return mesh;
}

TEST(ComputeVertexNormals, AreaWeightedSumOfCrossProducts) {
  Mesh mesh = hinge();
  MeshStats stats;
  compute_vertex_normals(mesh, stats);
  ASSERT_EQ(mesh.normals.size(), 5u);
  const glm::vec3 shared = glm::vec3(2, 0, 4) / std::sqrt(20.0f);
  expect_near3(mesh.normals[0], shared);
  expect_near3(mesh.normals[2], shared);
  expect_near3(mesh.normals[1], {0, 0, 1});
  expect_near3(mesh.normals[3], {1, 0, 0});
  // Only the degenerate triangle touches vertex 4: the fixed fallback.
  EXPECT_EQ(mesh.normals[4], glm::vec3(0, 0, 1));
  EXPECT_EQ(stats.zero_area_triangles, 1u);
  EXPECT_EQ(stats.zero_length_normals, 1u);
  EXPECT_EQ(stats.normals_computed, 5u);
}

TEST(ComputeVertexNormals, SliversAndFarAwayOrTinyMeshes) {
  // Collinear points are degenerate even when not exactly zero in float.
  Mesh sliver;
  sliver.positions = {{0, 0, 0}, {1, 1e-9f, 0}, {2, 0, 0}};
  sliver.indices = {0, 1, 2};
  MeshStats stats;
  compute_vertex_normals(sliver, stats);
  EXPECT_EQ(stats.zero_area_triangles, 1u);
  EXPECT_EQ(stats.zero_length_normals, 3u);
  // Coordinates near the float limits: the cross product must not overflow
  // or underflow.
  for (const float scale : {1e30f, 1e-30f}) {
    Mesh mesh;
    mesh.positions = {{0, 0, 0}, {scale, 0, 0}, {0, 0, scale}};
    mesh.indices = {0, 1, 2};
    MeshStats scaled_stats;
    compute_vertex_normals(mesh, scaled_stats);
    expect_near3(mesh.normals[0], {0, -1, 0});
    EXPECT_EQ(scaled_stats.zero_area_triangles, 0u) << scale;
  }
}

TEST(NormalizeNormals, NormalisesAndReplacesZeroLength) {
  Mesh mesh = hinge();
  mesh.normals = {{0, 0, 3}, {0, 0, 0}, {1e-30f, 0, 0}, {3e30f, 4e30f, 0}, {0, 0, 0}};
  MeshStats stats;
  normalize_normals(mesh, stats);
  EXPECT_EQ(mesh.normals[0], glm::vec3(0, 0, 1));
  expect_near3(mesh.normals[1], {0, 0, 1});  // computed: the first triangle's direction
  EXPECT_EQ(mesh.normals[2], glm::vec3(1, 0, 0));
  expect_near3(mesh.normals[3], {0.6f, 0.8f, 0});
  EXPECT_EQ(mesh.normals[4], glm::vec3(0, 0, 1));  // nothing to compute from: fallback
  EXPECT_EQ(stats.zero_length_normals, 2u);
  EXPECT_EQ(stats.normals_computed, 1u);
  for (const glm::vec3& n : mesh.normals) EXPECT_NEAR(glm::length(n), 1.0f, 1e-6f);
}

TEST(NormalizeNormals, ComputesWhenNoneWereLoaded) {
  Mesh mesh = triangle();
  MeshStats stats;
  normalize_normals(mesh, stats);
  ASSERT_EQ(mesh.normals.size(), 3u);
  EXPECT_EQ(mesh.normals[1], glm::vec3(0, 0, 1));
  EXPECT_EQ(stats.normals_computed, 3u);
}

// A cube of side 2 around the origin with split normals: 4 vertices per
// face, each face's diagonal through the corners with an even number of
// positive coordinates, so every cube corner touches the same number of
// triangles of each of its three faces and area weighting is symmetric.
Mesh split_cube() {
  Mesh mesh;
  for (int axis = 0; axis < 3; ++axis) {
    for (const float sign : {1.0f, -1.0f}) {
      glm::vec3 n(0.0f);
      n[axis] = sign;
      glm::vec3 u(0.0f);
      glm::vec3 v(0.0f);
      u[(axis + 1) % 3] = 1.0f;
      v[(axis + 2) % 3] = 1.0f;
      if (sign < 0) std::swap(u, v);  // keep u x v = n: counter-clockwise outside
      const glm::vec3 corners[4] = {n - u - v, n + u - v, n + u + v, n - u + v};
      const auto base = static_cast<std::uint32_t>(mesh.positions.size());
      for (const glm::vec3& corner : corners) {
        mesh.positions.push_back(corner);
        mesh.normals.push_back(n);
      }
      auto even = [](const glm::vec3& p) { return (int(p.x > 0) + int(p.y > 0) + int(p.z > 0)) % 2 == 0; };
      const std::uint32_t first = even(corners[0]) ? 0 : 1;
      const std::uint32_t q[4] = {base + first, base + (first + 1) % 4, base + (first + 2) % 4,
                                  base + (first + 3) % 4};
      mesh.indices.insert(mesh.indices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
    }
  }
  return mesh;
}

TEST(AveragedNormals, CubeCornersPointAlongTheDiagonal) {
  const Mesh mesh = split_cube();
  ASSERT_EQ(mesh.vertex_count(), 24u);
  // The cube is closed and outward facing.
  MeshStats stats;
  Mesh check = mesh;
  compute_vertex_normals(check, stats);
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) expect_near3(check.normals[i], mesh.normals[i]);

  MeshStats averaged_stats;
  const std::vector<glm::vec3> averaged = averaged_normals(mesh, averaged_stats);
  ASSERT_EQ(averaged.size(), 24u);
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    const glm::vec3 diagonal = glm::normalize(mesh.positions[i]);  // corners are (+-1, +-1, +-1)
    expect_near3(averaged[i], diagonal);
  }
  EXPECT_EQ(averaged_stats.zero_length_normals, 0u);
  EXPECT_EQ(averaged_stats.zero_area_triangles, 0u);
  // The mesh's own (split) normals are untouched.
  EXPECT_EQ(mesh.normals[0], glm::vec3(1, 0, 0));
}

TEST(AveragedNormals, NegativeZeroIsTheSamePoint) {
  Mesh mesh;
  // Two triangles at a right angle meeting at a point written once as +0 and
  // once as -0.
  mesh.positions = {{0.0f, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-0.0f, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  mesh.indices = {0, 1, 2, 3, 4, 5};
  MeshStats stats;
  const std::vector<glm::vec3> averaged = averaged_normals(mesh, stats);
  const glm::vec3 expected = glm::normalize(glm::vec3(1, 0, 1));
  expect_near3(averaged[0], expected);
  expect_near3(averaged[3], expected);
  expect_near3(averaged[4], expected);
  expect_near3(averaged[1], {0, 0, 1});
}

TEST(AveragedNormals, OppositeSheetsKeepTheirOwnNormals) {
  Mesh mesh;
  // The same triangle twice, once per side: the sums cancel exactly.
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.normals = {{0, 0, 2}, {0, 0, 2}, {0, 0, 2}, {0, 0, -1}, {0, 0, -1}, {0, 0, -1}};
  mesh.indices = {0, 1, 2, 3, 5, 4};
  MeshStats stats;
  const std::vector<glm::vec3> averaged = averaged_normals(mesh, stats);
  EXPECT_EQ(averaged[0], glm::vec3(0, 0, 1));
  EXPECT_EQ(averaged[5], glm::vec3(0, 0, -1));
  EXPECT_EQ(stats.zero_length_normals, 6u);
}

TEST(Bounds, BoxAndDiagonal) {
  Mesh mesh;
  mesh.positions = {{1, -2, 3}, {-1, 2, 0}, {0, 0, 15}};
  const Bounds bounds = compute_bounds(mesh);
  EXPECT_EQ(bounds.min, glm::vec3(-1, -2, 0));
  EXPECT_EQ(bounds.max, glm::vec3(1, 2, 15));
  EXPECT_FLOAT_EQ(bounds.diagonal(), std::sqrt(4.0f + 16.0f + 225.0f));
  EXPECT_EQ(compute_bounds(Mesh{}).diagonal(), 0.0f);
  // The extent is taken in double: no overflow of the intermediate squares.
  Bounds wide;
  wide.min = glm::vec3(-1e19f, 0, 0);
  wide.max = glm::vec3(1e19f, 0, 0);
  EXPECT_FLOAT_EQ(wide.diagonal(), 2e19f);
}

TEST(PadForEmbree, LeavesRoomBehindTheLastPosition) {
  Mesh mesh = triangle();
  mesh.positions.shrink_to_fit();
  pad_for_embree(mesh);
  EXPECT_GE(mesh.positions.capacity(), mesh.positions.size() + 1);
  EXPECT_EQ(mesh.positions.size(), 3u);
}

}  // namespace
}  // namespace nmbake
