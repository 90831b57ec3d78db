// Tests of the tangents stage: exact tiny cases, and every corner of several
// meshes against the reference MikkTSpace (the npm package `mikktspace`, a
// WASM build of the reference, run by tests/mikktspace_ref/reference.js).
#include "nmbake/tangents.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <string>
#include <vector>

#include "nmbake/mesh.hpp"
#include "test_util.hpp"

namespace {

using nmbake::Mesh;
using nmbake::TangentStats;

constexpr float pi = 3.14159265358979f;

std::uint32_t add_vertex(Mesh& mesh, glm::vec3 p, glm::vec3 n, glm::vec2 uv) {
  mesh.positions.push_back(p);
  mesh.normals.push_back(glm::normalize(n));
  mesh.uvs.push_back(uv);
  return static_cast<std::uint32_t>(mesh.positions.size() - 1);
}

void add_triangle(Mesh& mesh, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  mesh.indices.insert(mesh.indices.end(), {a, b, c});
}

// Area-weighted smooth normals, written here so the test does not depend on
// another stage.
void smooth_normals(Mesh& mesh) {
  std::vector<glm::vec3> sum(mesh.vertex_count(), glm::vec3(0.0f));
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    const std::uint32_t* v = &mesh.indices[3 * t];
    const glm::vec3 n =
        glm::cross(mesh.positions[v[1]] - mesh.positions[v[0]], mesh.positions[v[2]] - mesh.positions[v[0]]);
    for (int i = 0; i < 3; ++i) sum[v[i]] += n;
  }
  for (std::size_t v = 0; v < sum.size(); ++v) {
    mesh.normals[v] = glm::length(sum[v]) > 0.0f ? glm::normalize(sum[v]) : glm::vec3(0.0f, 0.0f, 1.0f);
  }
}

// Deterministic pseudo-random numbers in [-1, 1] (no seeding per run).
struct Lcg {
  std::uint32_t state = 12345u;
  float next() {
    state = state * 1664525u + 1013904223u;
    return static_cast<float>(state >> 8) / static_cast<float>(1u << 23) - 1.0f;
  }
};

// A (cells x cells) grid over [-1, 1]^2, z = height(x, y), the diagonal
// alternating between cells, smooth normals.
Mesh make_grid(int cells, const std::function<float(float, float)>& height,
               const std::function<glm::vec2(float, float)>& uv) {
  Mesh mesh;
  for (int j = 0; j <= cells; ++j) {
    for (int i = 0; i <= cells; ++i) {
      const float x = -1.0f + 2.0f * static_cast<float>(i) / static_cast<float>(cells);
      const float y = -1.0f + 2.0f * static_cast<float>(j) / static_cast<float>(cells);
      add_vertex(mesh, {x, y, height(x, y)}, {0.0f, 0.0f, 1.0f}, uv(x, y));
    }
  }
  const auto at = [&](int i, int j) { return static_cast<std::uint32_t>(j * (cells + 1) + i); };
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) {
      if ((i + j) % 2 == 0) {
        add_triangle(mesh, at(i, j), at(i + 1, j), at(i + 1, j + 1));
        add_triangle(mesh, at(i, j), at(i + 1, j + 1), at(i, j + 1));
      } else {
        add_triangle(mesh, at(i, j), at(i + 1, j), at(i, j + 1));
        add_triangle(mesh, at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
      }
    }
  }
  smooth_normals(mesh);
  return mesh;
}

float wave(float x, float y) { return 0.25f * std::sin(2.0f * x + 0.5f) * std::cos(1.5f * y); }
glm::vec2 planar_uv(float x, float y) { return {0.5f * x + 0.5f, 0.5f * y + 0.5f}; }

// Every corner its own vertex: welding must happen by value.
Mesh unweld(const Mesh& mesh) {
  Mesh out;
  for (const std::uint32_t v : mesh.indices) {
    out.positions.push_back(mesh.positions[v]);
    out.normals.push_back(mesh.normals[v]);
    out.uvs.push_back(mesh.uvs[v]);
    out.indices.push_back(static_cast<std::uint32_t>(out.indices.size()));
  }
  return out;
}

// Hard edges (a normal per face) and per-face UVs, some faces rotated or
// mirrored in UV space.
Mesh make_cube() {
  Mesh mesh;
  const glm::vec3 normals[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (int f = 0; f < 6; ++f) {
    const glm::vec3 n = normals[f];
    const glm::vec3 u = std::fabs(n.x) > 0.5f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
    const glm::vec3 v = glm::cross(n, u);
    const glm::vec3 corners[4] = {n - u - v, n + u - v, n + u + v, n - u + v};
    glm::vec2 uvs[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    if (f == 2) {  // rotated by 90 degrees
      for (glm::vec2& t : uvs) t = {1.0f - t.y, t.x};
    }
    if (f == 3 || f == 5) {  // mirrored
      for (glm::vec2& t : uvs) t.x = 1.0f - t.x;
    }
    std::uint32_t id[4];
    for (int k = 0; k < 4; ++k) {
      id[k] =
          add_vertex(mesh, 0.5f * corners[k], n, glm::vec2(0.25f, 0.3f) * uvs[k] + glm::vec2(0.3f * f, 0.0f));
    }
    add_triangle(mesh, id[0], id[1], id[2]);
    add_triangle(mesh, id[0], id[2], id[3]);
  }
  return mesh;
}

// UV sphere: the seam column is duplicated (same position and normal,
// u = 0 and u = 1), each pole has one vertex per segment.
Mesh make_sphere(int segments, int rings) {
  Mesh mesh;
  for (int r = 0; r <= rings; ++r) {
    for (int s = 0; s <= segments; ++s) {
      const float theta = pi * static_cast<float>(r) / static_cast<float>(rings);
      const float phi = 2.0f * pi * static_cast<float>(s) / static_cast<float>(segments);
      const glm::vec3 p{std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
      float u = static_cast<float>(s) / static_cast<float>(segments);
      if (r == 0 || r == rings) u += 0.5f / static_cast<float>(segments);
      add_vertex(mesh, p, p, {u, 1.0f - static_cast<float>(r) / static_cast<float>(rings)});
    }
  }
  const auto at = [&](int s, int r) { return static_cast<std::uint32_t>(r * (segments + 1) + s); };
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      if (r != 0) add_triangle(mesh, at(s, r), at(s + 1, r), at(s + 1, r + 1));
      if (r != rings - 1) add_triangle(mesh, at(s, r), at(s + 1, r + 1), at(s, r + 1));
    }
  }
  return mesh;
}

// Degenerate UV and position cases, built around a wavy grid:
//   * a triangle whose UVs are collinear (zero UV area) and one with two
//     equal UVs, each still sharing an edge with ordinary triangles;
//   * a triangle with a repeated vertex (zero position area);
//   * a sliver (three distinct collinear positions, non-zero UV area);
//   * an isolated triangle whose three UVs are equal.
Mesh make_degenerate() {
  Mesh mesh = make_grid(4, wave, planar_uv);
  const auto replace_uv_of_corner = [&](std::size_t triangle, int corner, glm::vec2 uv) {
    const std::uint32_t v = mesh.indices[3 * triangle + corner];
    mesh.indices[3 * triangle + corner] = add_vertex(mesh, mesh.positions[v], mesh.normals[v], uv);
  };
  {  // collinear UVs: the third UV on the line through the first two
    const std::size_t t = 5;
    const glm::vec2 a = mesh.uvs[mesh.indices[3 * t]];
    const glm::vec2 b = mesh.uvs[mesh.indices[3 * t + 1]];
    replace_uv_of_corner(t, 2, a + 0.5f * (b - a));
  }
  {  // two equal UVs
    const std::size_t t = 18;
    replace_uv_of_corner(t, 2, mesh.uvs[mesh.indices[3 * t]]);
  }
  // repeated vertex
  add_triangle(mesh, mesh.indices[3 * 10], mesh.indices[3 * 10], mesh.indices[3 * 10 + 1]);
  {  // sliver on a boundary edge (so it is the edge's second triangle): two
     // grid vertices and their midpoint, with a UV that keeps the orientation
    const std::uint32_t a = mesh.indices[0];
    const std::uint32_t b = mesh.indices[1];
    const std::uint32_t m = add_vertex(mesh, 0.5f * (mesh.positions[a] + mesh.positions[b]), mesh.normals[a],
                                       0.5f * (mesh.uvs[a] + mesh.uvs[b]) + glm::vec2(0.03f, -0.05f));
    add_triangle(mesh, b, a, m);
  }
  {  // isolated, all UVs equal
    const std::uint32_t a = add_vertex(mesh, {3.0f, 0.0f, 0.0f}, {0.3f, 0.1f, 1.0f}, {0.9f, 0.9f});
    const std::uint32_t b = add_vertex(mesh, {4.0f, 0.0f, 0.0f}, {0.3f, 0.1f, 1.0f}, {0.9f, 0.9f});
    const std::uint32_t c = add_vertex(mesh, {3.0f, 1.0f, 0.0f}, {0.3f, 0.1f, 1.0f}, {0.9f, 0.9f});
    add_triangle(mesh, a, b, c);
  }
  return mesh;
}

// Jittered positions, normals and UVs (some UV triangles flip), plus three
// triangles sharing one edge (non-manifold); the third is seen edge-on from
// its vertex normals, so neither we nor the reference find a tangent there.
Mesh make_noisy() {
  Lcg rng;
  Mesh mesh = make_grid(
      10, [&](float, float) { return 0.15f * rng.next(); },
      [&](float x, float y) { return planar_uv(x, y) + 0.06f * glm::vec2(rng.next(), rng.next()); });
  for (glm::vec3& p : mesh.positions) p += 0.05f * glm::vec3(rng.next(), rng.next(), 0.0f);
  for (glm::vec3& n : mesh.normals)
    n = glm::normalize(n + 0.3f * glm::vec3(rng.next(), rng.next(), rng.next()));
  const std::uint32_t a = add_vertex(mesh, {2, 0, 0}, {0, 0, 1}, {0.1f, 0.1f});
  const std::uint32_t b = add_vertex(mesh, {2, 1, 0}, {0, 0, 1}, {0.1f, 0.3f});
  add_triangle(mesh, a, b, add_vertex(mesh, {3, 0.5f, 0.1f}, {0, 0, 1}, {0.3f, 0.2f}));
  add_triangle(mesh, b, a, add_vertex(mesh, {1, 0.5f, 0.2f}, {0, 0, 1}, {0.0f, 0.25f}));
  add_triangle(mesh, b, a, add_vertex(mesh, {2, 0.5f, 1.0f}, {0, 0, 1}, {0.2f, 0.15f}));
  return mesh;
}

// The noisy mesh with the UV triangles of every seventh triangle collapsed
// (third UV = first UV): such triangles have no orientation of their own and
// take the one of the first group that reaches them, among neighbours of
// both orientations.
Mesh make_noisy_collapsed() {
  Mesh mesh = make_noisy();
  for (std::size_t t = 3; t < mesh.triangle_count(); t += 7) {
    const std::uint32_t v = mesh.indices[3 * t + 2];
    mesh.indices[3 * t + 2] =
        add_vertex(mesh, mesh.positions[v], mesh.normals[v], mesh.uvs[mesh.indices[3 * t]]);
  }
  return mesh;
}

// ---------------------------------------------------------------------------
// The reference, through node.

struct Reference {
  std::string error;  // empty on success
  std::vector<glm::vec4> tangents;
};

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ')) s.pop_back();
  return s;
}

template <typename T>
void write_pod(std::ofstream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

Reference reference_tangents(const Mesh& mesh) {
  Reference result;
  const std::string setup_hint = " (run tools/setup-npm.sh to install the MikkTSpace reference)";
  const nmbake::test::CommandResult which = nmbake::test::run_command("command -v node");
  const std::string node = trim(which.output);
  if (which.exit_code != 0 || node.empty()) {
    result.error = "node was not found on PATH" + setup_hint;
    return result;
  }
  const std::filesystem::path dir =
      std::filesystem::path(nmbake::test::source_dir()) / "tests" / "mikktspace_ref";
  if (!std::filesystem::exists(dir / "node_modules" / "mikktspace" / "package.json")) {
    result.error =
        "the npm package mikktspace is missing from " + (dir / "node_modules").string() + setup_hint;
    return result;
  }

  nmbake::test::TempDir temp;
  const std::string in_path = temp.file("corners.bin");
  const std::string out_path = temp.file("tangents.bin");
  {
    std::ofstream out(in_path, std::ios::binary);
    const auto corner_count = static_cast<std::uint32_t>(mesh.indices.size());
    write_pod(out, corner_count);
    for (const std::uint32_t v : mesh.indices) write_pod(out, mesh.positions[v]);
    for (const std::uint32_t v : mesh.indices) write_pod(out, mesh.normals[v]);
    for (const std::uint32_t v : mesh.indices) write_pod(out, mesh.uvs[v]);
  }
  const nmbake::test::CommandResult run = nmbake::test::run_command(
      "'" + node + "' '" + (dir / "reference.js").string() + "' '" + in_path + "' '" + out_path + "'");
  if (run.exit_code != 0) {
    result.error =
        "reference.js failed (exit " + std::to_string(run.exit_code) + "): " + run.output + setup_hint;
    return result;
  }
  std::ifstream in(out_path, std::ios::binary);
  std::uint32_t corner_count = 0;
  in.read(reinterpret_cast<char*>(&corner_count), sizeof(corner_count));
  if (!in || corner_count != mesh.indices.size()) {
    result.error = "reference output has the wrong size";
    return result;
  }
  result.tangents.resize(corner_count);
  in.read(reinterpret_cast<char*>(result.tangents.data()),
          static_cast<std::streamsize>(corner_count * sizeof(glm::vec4)));
  if (!in) result.error = "reference output is truncated";
  return result;
}

float angle_degrees(glm::vec3 a, glm::vec3 b) {
  const float c = glm::dot(glm::normalize(a), glm::normalize(b));
  const float s = glm::length(glm::cross(glm::normalize(a), glm::normalize(b)));
  return std::atan2(s, c) * 180.0f / pi;
}

bool is_finite(const glm::vec4& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) && std::isfinite(v.w);
}

// Zero position area or zero UV area: the reference has no gradient of its
// own for the triangle.
bool is_degenerate(const Mesh& mesh, std::size_t t) {
  const std::uint32_t* v = &mesh.indices[3 * t];
  const glm::vec3 cross =
      glm::cross(mesh.positions[v[1]] - mesh.positions[v[0]], mesh.positions[v[2]] - mesh.positions[v[0]]);
  const glm::vec2 e1 = mesh.uvs[v[1]] - mesh.uvs[v[0]];
  const glm::vec2 e2 = mesh.uvs[v[2]] - mesh.uvs[v[0]];
  return glm::length(cross) < 1e-6f || std::fabs(e1.x * e2.y - e1.y * e2.x) < 1e-9f;
}

// Compares every corner with the reference:
//   * corners of ordinary triangles: within 0.01 degrees, same sign;
//   * every corner: finite, unit, orthogonal to N, sign +-1;
//   * where the reference has no tangent: it writes exactly (1, 0, 0, -1) for
//     a corner it never reached (degenerate triangles only) and a zero vector
//     where every contribution had zero weight (e.g. a triangle seen edge-on
//     from its vertex normal); there we expect our fallback with sign +1, and
//     their number must be stats.fallback_tangents.
void check_against_reference(const std::string& name, const Mesh& mesh, TangentStats* stats_out = nullptr) {
  std::vector<glm::vec4> tangents;
  TangentStats stats;
  nmbake::compute_tangents(mesh, tangents, stats);
  ASSERT_EQ(tangents.size(), mesh.indices.size());
  if (stats_out) *stats_out = stats;

  const Reference reference = reference_tangents(mesh);
  ASSERT_TRUE(reference.error.empty()) << reference.error;

  float max_angle = 0.0f;
  std::size_t compared_count = 0;
  std::uint64_t reference_without_space_count = 0;
  for (std::size_t c = 0; c < tangents.size(); ++c) {
    const glm::vec4 mine = tangents[c];
    const glm::vec4 ref = reference.tangents[c];
    const glm::vec3 n = mesh.normals[mesh.indices[c]];
    SCOPED_TRACE(name + " corner " + std::to_string(c) + " (triangle " + std::to_string(c / 3) + ")");
    ASSERT_TRUE(is_finite(mine));
    EXPECT_NEAR(glm::length(glm::vec3(mine)), 1.0f, 1e-4f);
    EXPECT_TRUE(mine.w == 1.0f || mine.w == -1.0f) << mine.w;
    EXPECT_LT(std::fabs(glm::dot(glm::vec3(mine), n)), 1e-4f);

    const bool reference_without_space =
        glm::vec3(ref) == glm::vec3(0.0f) ||
        (is_degenerate(mesh, c / 3) && ref == glm::vec4(1.0f, 0.0f, 0.0f, -1.0f));
    if (reference_without_space) {
      ++reference_without_space_count;
      EXPECT_EQ(mine.w, 1.0f);
      continue;
    }
    ASSERT_TRUE(is_finite(ref));
    const float angle = angle_degrees(glm::vec3(mine), glm::vec3(ref));
    max_angle = std::max(max_angle, angle);
    ++compared_count;
    EXPECT_LT(angle, 0.01f) << "mine (" << mine.x << ", " << mine.y << ", " << mine.z << ") reference ("
                            << ref.x << ", " << ref.y << ", " << ref.z << ")";
    EXPECT_EQ(mine.w, ref.w);
  }
  EXPECT_EQ(stats.fallback_tangents, reference_without_space_count);
  std::printf(
      "[ tangents ] %-14s %6zu corners compared, max angle %.2e deg, %llu fallback, %llu degenerate, "
      "%llu degenerate UV\n",
      name.c_str(), compared_count, static_cast<double>(max_angle),
      static_cast<unsigned long long>(stats.fallback_tangents),
      static_cast<unsigned long long>(stats.degenerate_triangles),
      static_cast<unsigned long long>(stats.degenerate_uv_triangles));
}

// ---------------------------------------------------------------------------
// Exact cases.

Mesh flat_quad(bool mirror_u) {
  Mesh mesh;
  const glm::vec3 p[4] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (const glm::vec3& q : p) add_vertex(mesh, q, {0, 0, 1}, {mirror_u ? 1.0f - q.x : q.x, q.y});
  add_triangle(mesh, 0, 1, 2);
  add_triangle(mesh, 0, 2, 3);
  return mesh;
}

TEST(TangentsExact, FlatQuadWithUAlongX) {
  std::vector<glm::vec4> tangents;
  TangentStats stats;
  nmbake::compute_tangents(flat_quad(false), tangents, stats);
  ASSERT_EQ(tangents.size(), 6u);
  for (const glm::vec4& t : tangents) {
    EXPECT_NEAR(t.x, 1.0f, 1e-6f);
    EXPECT_NEAR(t.y, 0.0f, 1e-6f);
    EXPECT_NEAR(t.z, 0.0f, 1e-6f);
    EXPECT_EQ(t.w, 1.0f);
  }
  EXPECT_EQ(stats.fallback_tangents, 0u);
  EXPECT_EQ(stats.degenerate_triangles, 0u);
  EXPECT_EQ(stats.degenerate_uv_triangles, 0u);
}

TEST(TangentsExact, MirroredUGivesNegativeSign) {
  std::vector<glm::vec4> tangents;
  TangentStats stats;
  nmbake::compute_tangents(flat_quad(true), tangents, stats);
  ASSERT_EQ(tangents.size(), 6u);
  for (const glm::vec4& t : tangents) {
    // u grows along -x; B = w * cross(N, T) = -cross(z, -x) = +y, where v grows.
    EXPECT_NEAR(t.x, -1.0f, 1e-6f);
    EXPECT_NEAR(t.y, 0.0f, 1e-6f);
    EXPECT_NEAR(t.z, 0.0f, 1e-6f);
    EXPECT_EQ(t.w, -1.0f);
  }
  EXPECT_EQ(stats.fallback_tangents, 0u);
}

TEST(TangentsExact, SmoothVertexAveragesByCornerAngle) {
  // Two triangles of one UV orientation meet at the origin with 90 and 135
  // degree corners; their own tangents are +x and (1, 1) / sqrt(2).
  Mesh mesh;
  add_vertex(mesh, {0, 0, 0}, {0, 0, 1}, {0, 0});
  add_vertex(mesh, {1, 0, 0}, {0, 0, 1}, {1, 0});
  add_vertex(mesh, {0, 1, 0}, {0, 0, 1}, {0, 1});
  add_vertex(mesh, {-1, -1, 0}, {0, 0, 1}, {-1, 0});  // u = x, v = y - x: dP/du = (1, 1)
  add_triangle(mesh, 0, 1, 2);
  add_triangle(mesh, 0, 2, 3);
  std::vector<glm::vec4> tangents;
  TangentStats stats;
  nmbake::compute_tangents(mesh, tangents, stats);
  // Weights pi/2 and 3 pi/4: the sum is along 2 (1, 0) + 3 (1, 1) / sqrt(2).
  const float s = std::sqrt(0.5f);
  const glm::vec3 expected = glm::normalize(glm::vec3(2.0f + 3.0f * s, 3.0f * s, 0.0f));
  for (const std::size_t c : {std::size_t{0}, std::size_t{3}}) {
    EXPECT_NEAR(tangents[c].x, expected.x, 1e-6f) << c;
    EXPECT_NEAR(tangents[c].y, expected.y, 1e-6f) << c;
    EXPECT_NEAR(tangents[c].z, 0.0f, 1e-6f) << c;
    EXPECT_EQ(tangents[c].w, 1.0f) << c;
  }
  EXPECT_NEAR(tangents[1].x, 1.0f, 1e-6f);  // corner only in the first triangle
  EXPECT_NEAR(tangents[5].x, s, 1e-6f);     // corner only in the second triangle
  EXPECT_NEAR(tangents[5].y, s, 1e-6f);
  EXPECT_EQ(stats.fallback_tangents, 0u);
}

TEST(TangentsExact, DegenerateInputGivesNoNaN) {
  Mesh mesh;
  // Zero UV area everywhere, and a triangle with a repeated position.
  add_vertex(mesh, {0, 0, 0}, {0, 0, 1}, {0.5f, 0.5f});
  add_vertex(mesh, {1, 0, 0}, {0, 0, 1}, {0.5f, 0.5f});
  add_vertex(mesh, {0, 1, 0}, {0, 0, 1}, {0.5f, 0.5f});
  add_vertex(mesh, {0, 0, 0}, {1, 0, 0}, {0.1f, 0.2f});
  add_vertex(mesh, {0, 0, 0}, {1, 0, 0}, {0.3f, 0.2f});
  add_vertex(mesh, {0, 1, 1}, {1, 0, 0}, {0.2f, 0.9f});
  add_triangle(mesh, 0, 1, 2);
  add_triangle(mesh, 3, 4, 5);
  std::vector<glm::vec4> tangents;
  TangentStats stats;
  nmbake::compute_tangents(mesh, tangents, stats);
  ASSERT_EQ(tangents.size(), 6u);
  for (std::size_t c = 0; c < tangents.size(); ++c) {
    const glm::vec4 t = tangents[c];
    ASSERT_TRUE(is_finite(t)) << c;
    EXPECT_NEAR(glm::length(glm::vec3(t)), 1.0f, 1e-6f) << c;
    EXPECT_NEAR(glm::dot(glm::vec3(t), mesh.normals[mesh.indices[c]]), 0.0f, 1e-6f) << c;
    EXPECT_EQ(t.w, 1.0f) << c;
  }
  // The documented fallback: the axis least aligned with N, orthogonalised.
  EXPECT_EQ(glm::vec3(tangents[0]), glm::vec3(1, 0, 0));  // N = +z
  EXPECT_EQ(glm::vec3(tangents[3]), glm::vec3(0, 1, 0));  // N = +x
  EXPECT_EQ(stats.fallback_tangents, 6u);
  EXPECT_EQ(stats.degenerate_triangles, 1u);
  EXPECT_EQ(stats.degenerate_uv_triangles, 1u);
}

TEST(TangentsExact, EmptyMesh) {
  std::vector<glm::vec4> tangents(3);
  TangentStats stats;
  stats.fallback_tangents = 7;
  nmbake::compute_tangents(Mesh{}, tangents, stats);
  EXPECT_TRUE(tangents.empty());
  EXPECT_EQ(stats.fallback_tangents, 0u);
}

// Per-corner UVs (the high's: vertices not split at seams) give the frames
// of the same mesh with per-vertex UVs, corner for corner; triangles left
// out get zeros, and those kept the frames of the mesh they form alone.
TEST(TangentsExact, CornerUvsGiveThePerVertexFrames) {
  for (const Mesh& mesh : {make_sphere(12, 8), make_noisy(), make_degenerate()}) {
    std::vector<glm::vec4> expected, got;
    TangentStats expected_stats, got_stats;
    nmbake::compute_tangents(mesh, expected, expected_stats);
    Mesh corners = mesh;
    for (const std::uint32_t v : mesh.indices) corners.corner_uvs.push_back(mesh.uvs[v]);
    corners.uvs.clear();
    nmbake::compute_corner_uv_tangents(corners, {}, got, got_stats);
    ASSERT_EQ(got.size(), expected.size());
    for (std::size_t c = 0; c < got.size(); ++c) EXPECT_EQ(got[c], expected[c]) << c;
    EXPECT_EQ(got_stats.fallback_tangents, expected_stats.fallback_tangents);
    // Every other triangle: the others' corners are zero, the kept ones as
    // computed on the kept triangles alone.
    std::vector<std::uint8_t> selected(mesh.triangle_count());
    Mesh half = mesh;
    half.indices.clear();
    for (std::size_t t = 0; t < selected.size(); ++t) {
      selected[t] = t % 2 == 0;
      if (selected[t])
        half.indices.insert(half.indices.end(), &mesh.indices[3 * t], &mesh.indices[3 * t + 3]);
    }
    std::vector<glm::vec4> half_expected;
    nmbake::compute_tangents(half, half_expected, expected_stats);
    nmbake::compute_corner_uv_tangents(corners, selected, got, got_stats);
    for (std::size_t t = 0; t < selected.size(); ++t) {
      for (std::size_t k = 0; k < 3; ++k) {
        const glm::vec4 want = selected[t] ? half_expected[3 * (t / 2) + k] : glm::vec4(0.0f);
        EXPECT_EQ(got[3 * t + k], want) << t;
      }
    }
  }
}

// ---------------------------------------------------------------------------
// Against the reference.

TEST(TangentsReference, SmoothGrid) { check_against_reference("grid", make_grid(8, wave, planar_uv)); }

TEST(TangentsReference, UnweldedGridWeldsByValue) {
  const Mesh grid = make_grid(8, wave, planar_uv);
  check_against_reference("unwelded grid", unweld(grid));
  std::vector<glm::vec4> indexed, unwelded;
  TangentStats stats;
  nmbake::compute_tangents(grid, indexed, stats);
  nmbake::compute_tangents(unweld(grid), unwelded, stats);
  EXPECT_EQ(indexed, unwelded);
}

TEST(TangentsReference, HardEdgedCube) { check_against_reference("cube", make_cube()); }

TEST(TangentsReference, SphereWithSeam) { check_against_reference("sphere", make_sphere(12, 8)); }

TEST(TangentsReference, MirroredUV) {
  const Mesh mesh =
      make_grid(8, wave, [](float x, float y) { return glm::vec2(std::fabs(x), 0.5f * y + 0.5f); });
  check_against_reference("mirrored", mesh);
  std::vector<glm::vec4> tangents;
  TangentStats stats;
  nmbake::compute_tangents(mesh, tangents, stats);
  std::size_t negative_count = 0;
  for (const glm::vec4& t : tangents) negative_count += t.w < 0.0f ? 1 : 0;
  EXPECT_EQ(negative_count, tangents.size() / 2);  // the left half
}

TEST(TangentsReference, DegenerateTriangles) {
  TangentStats stats;
  check_against_reference("degenerate", make_degenerate(), &stats);
  EXPECT_EQ(stats.degenerate_triangles, 2u);     // repeated vertex, sliver
  EXPECT_EQ(stats.degenerate_uv_triangles, 3u);  // collinear UVs, two equal UVs, isolated
  EXPECT_GE(stats.fallback_tangents, 3u);        // at least the isolated triangle
}

TEST(TangentsReference, NoisyMesh) { check_against_reference("noisy", make_noisy()); }

TEST(TangentsReference, NoisyMeshWithCollapsedUVs) {
  TangentStats stats;
  check_against_reference("noisy+collapsed", make_noisy_collapsed(), &stats);
  EXPECT_EQ(stats.degenerate_uv_triangles, 29u);  // triangles 3, 10, ..., 199
}

}  // namespace
