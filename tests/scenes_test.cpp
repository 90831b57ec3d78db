// Tests of the scene generators (tools/gen): analytic normals against finite
// differences, cube-sphere topology and UV atlas, winding, determinism.
#include "scenes.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>
#include <map>
#include <numbers>
#include <numeric>
#include <tuple>
#include <vector>

#include "hard_scenes.hpp"
#include "lab_scenes.hpp"
#include "nmbake/load.hpp"
#include "noise.hpp"
#include "test_util.hpp"

namespace {

using nmbake::Mesh;
namespace scenes = nmbake::scenes;

constexpr double kDegree = std::numbers::pi / 180.0;

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  const double c = glm::dot(glm::normalize(a), glm::normalize(b));
  const double s = glm::length(glm::cross(glm::normalize(a), glm::normalize(b)));
  return std::atan2(s, c) / kDegree;
}

// Deterministic directions: a Fibonacci sphere plus points right next to cube
// edges and corners, where the gnomonic map is most skewed.
std::vector<glm::dvec3> test_directions() {
  std::vector<glm::dvec3> out;
  const int count = 400;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / count;
    const double r = std::sqrt(1.0 - z * z);
    out.push_back({r * std::cos(golden * i), r * std::sin(golden * i), z});
  }
  for (double e : {0.999, 1.0, 1.001}) {
    for (double t : {-0.9, -0.3, 0.0, 0.5, 0.97}) {
      out.push_back(glm::normalize(glm::dvec3(1.0, e, t)));
      out.push_back(glm::normalize(glm::dvec3(-e, t, -1.0)));
      out.push_back(glm::normalize(glm::dvec3(t, -1.0, e)));
    }
    out.push_back(glm::normalize(glm::dvec3(1.0, e, 1.0)));
    out.push_back(glm::normalize(glm::dvec3(-1.0, -e, 1.0)));
  }
  return out;
}

void expect_finite(const Mesh& mesh) {
  for (const glm::vec3& p : mesh.positions)
    ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
  for (const glm::vec3& n : mesh.normals) {
    ASSERT_TRUE(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z));
    ASSERT_NEAR(glm::length(n), 1.0f, 1e-5f);
  }
  for (const glm::vec2& t : mesh.uvs) ASSERT_TRUE(std::isfinite(t.x) && std::isfinite(t.y));
  for (std::uint32_t i : mesh.indices) ASSERT_LT(i, mesh.vertex_count());
}

template <typename T>
bool bitwise_equal(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

bool meshes_identical(const Mesh& a, const Mesh& b) {
  return bitwise_equal(a.positions, b.positions) && bitwise_equal(a.normals, b.normals) &&
         bitwise_equal(a.uvs, b.uvs) && bitwise_equal(a.indices, b.indices);
}

using PositionKey = std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>;
PositionKey bits_of(const glm::vec3& p) {
  std::uint32_t x, y, z;
  std::memcpy(&x, &p.x, 4);
  std::memcpy(&y, &p.y, 4);
  std::memcpy(&z, &p.z, 4);
  return {x, y, z};
}

// Welds bitwise-equal positions and checks that every directed edge appears
// once and its reverse once: closed, manifold, consistently oriented.
void expect_watertight(const Mesh& mesh) {
  std::map<PositionKey, std::uint32_t> ids;
  std::vector<std::uint32_t> welded(mesh.vertex_count());
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    welded[v] =
        ids.try_emplace(bits_of(mesh.positions[v]), static_cast<std::uint32_t>(ids.size())).first->second;
  }
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = welded[mesh.indices[3 * t + k]], b = welded[mesh.indices[3 * t + (k + 1) % 3]];
      ASSERT_NE(a, b) << "degenerate triangle " << t;
      ++directed[{a, b}];
    }
  }
  std::size_t bad = 0;
  for (const auto& [edge, count] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    if (count != 1 || reverse == directed.end() || reverse->second != 1) ++bad;
  }
  EXPECT_EQ(bad, 0u) << "of " << directed.size() << " directed edges";
  // Closed genus-0 surface: V - E + F = 2.
  const long long v = static_cast<long long>(ids.size()), e = static_cast<long long>(directed.size() / 2),
                  f = static_cast<long long>(mesh.triangle_count());
  EXPECT_EQ(v - e + f, 2);
}

// Every triangle's geometric normal points away from the origin.
void expect_outward(const Mesh& mesh) {
  std::size_t inward = 0;
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    const glm::dvec3 a(mesh.positions[mesh.indices[3 * t]]), b(mesh.positions[mesh.indices[3 * t + 1]]),
        c(mesh.positions[mesh.indices[3 * t + 2]]);
    if (!(glm::dot(glm::cross(b - a, c - a), a + b + c) > 0.0)) ++inward;
  }
  EXPECT_EQ(inward, 0u);
}

// ---------------------------------------------------------------------------

TEST(ScenesNoise, DeterministicAndBounded) {
  using namespace nmbake::noise;
  EXPECT_EQ(hash(1, 2, 3, 4), hash(1, 2, 3, 4));
  EXPECT_NE(hash(1, 2, 3), hash(1, 3, 2));
  EXPECT_NE(hash(1, 2), hash(2, 2));
  EXPECT_EQ(gradient_noise(7, {3.0, -2.0, 5.0}), 0.0);  // zero on the lattice
  double lo = 1.0, hi = -1.0, sum = 0.0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const glm::dvec3 p(0.37 * i, -0.11 * i + 3.3, 0.053 * i);
    const double g = gradient_noise(11, p), f = fbm(11, p), v = value_noise(11, p);
    ASSERT_GE(g, -1.0);
    ASSERT_LE(g, 1.0);
    ASSERT_GE(f, -1.0);
    ASSERT_LE(f, 1.0);
    ASSERT_GE(v, -1.0);
    ASSERT_LE(v, 1.0);
    lo = std::min(lo, g);
    hi = std::max(hi, g);
    sum += g;
    ASSERT_LT(unit_from_hash(hash(5, static_cast<std::uint32_t>(i))), 1.0);
  }
  EXPECT_LT(lo, -0.5);  // not a constant field
  EXPECT_GT(hi, 0.5);
  EXPECT_LT(std::abs(sum / n), 0.05);
  EXPECT_NE(fbm(1, {0.3, 0.4, 0.5}), fbm(2, {0.3, 0.4, 0.5}));
}

TEST(ScenesHeightfield, NormalMatchesFiniteDifferences) {
  const scenes::HeightfieldParams p;
  const float step = 5e-4f;
  double worst = 0.0;
  for (int j = 0; j <= 40; ++j) {
    for (int i = 0; i <= 40; ++i) {
      const float x = 0.01f + 0.98f * i / 40.0f, y = 0.01f + 0.98f * j / 40.0f;
      // Differences over the float arguments actually passed, so the rounding
      // of x +- step does not count as slope.
      const float xp = x + step, xm = x - step, yp = y + step, ym = y - step;
      const double hx =
          (double(scenes::heightfield_height(p, xp, y)) - scenes::heightfield_height(p, xm, y)) /
          (double(xp) - double(xm));
      const double hy =
          (double(scenes::heightfield_height(p, x, yp)) - scenes::heightfield_height(p, x, ym)) /
          (double(yp) - double(ym));
      const glm::dvec3 fd(-hx, -hy, 1.0);
      worst = std::max(worst, angle_deg(fd, glm::dvec3(scenes::heightfield_normal(p, x, y))));
    }
  }
  EXPECT_LT(worst, 0.01);
}

TEST(ScenesHeightfield, SlopesAreModerate) {
  const scenes::HeightfieldParams p;
  double steepest = 0.0;
  for (int j = 0; j <= 300; ++j) {
    for (int i = 0; i <= 300; ++i) {
      const glm::vec3 n = scenes::heightfield_normal(p, i / 300.0f, j / 300.0f);
      steepest = std::max(steepest, std::acos(std::clamp(double(n.z), -1.0, 1.0)) / kDegree);
    }
  }
  EXPECT_GT(steepest, 15.0);
  EXPECT_LT(steepest, 32.0);
}

TEST(ScenesHeightfield, MeshesFollowTheContract) {
  scenes::HeightfieldParams p;
  p.size = 2.0f;
  p.low_cells = 3;
  p.high_cells = 40;
  const scenes::ScenePair pair = scenes::make_heightfield(p);
  expect_finite(pair.low);
  expect_finite(pair.high);

  ASSERT_EQ(pair.low.vertex_count(), 16u);
  ASSERT_EQ(pair.low.triangle_count(), 18u);
  ASSERT_TRUE(pair.low.has_uvs());
  for (std::size_t v = 0; v < pair.low.vertex_count(); ++v) {
    const glm::vec3 q = pair.low.positions[v];
    EXPECT_EQ(q.z, 0.0f);
    EXPECT_FLOAT_EQ(pair.low.uvs[v].x, q.x / p.size);
    EXPECT_FLOAT_EQ(pair.low.uvs[v].y, q.y / p.size);
    EXPECT_EQ(pair.low.normals[v], glm::vec3(0, 0, 1));
  }
  EXPECT_EQ(pair.low.positions.back(), glm::vec3(2.0f, 2.0f, 0.0f));  // exact far corner

  ASSERT_EQ(pair.high.vertex_count(), 41u * 41u);
  ASSERT_EQ(pair.high.triangle_count(), 2u * 40u * 40u);
  EXPECT_FALSE(pair.high.has_uvs());
  for (std::size_t v = 0; v < pair.high.vertex_count(); ++v) {
    const glm::vec3 q = pair.high.positions[v];
    EXPECT_EQ(q.z, scenes::heightfield_height(p, q.x, q.y));
    EXPECT_EQ(pair.high.normals[v], scenes::heightfield_normal(p, q.x, q.y));
  }
  // Counter-clockwise seen from +z: positive signed area in xy (and in uv).
  for (const Mesh* mesh : {&pair.low, &pair.high}) {
    for (std::size_t t = 0; t < mesh->triangle_count(); ++t) {
      const glm::vec3 a = mesh->positions[mesh->indices[3 * t]],
                      b = mesh->positions[mesh->indices[3 * t + 1]],
                      c = mesh->positions[mesh->indices[3 * t + 2]];
      ASSERT_GT((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x), 0.0f);
      ASSERT_GT(glm::cross(b - a, c - a).z, 0.0f);
    }
  }
}

TEST(ScenesSphere, NormalMatchesFiniteDifferences) {
  for (const float amplitude : {0.03f, 0.1f}) {
    scenes::SphereParams p;
    p.amplitude = amplitude;
    p.radius = 2.0f;
    const double step = 3e-3;
    double worst = 0.0;
    for (const glm::dvec3& d : test_directions()) {
      const glm::dvec3 helper = std::abs(d.x) < 0.6 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
      const glm::dvec3 e1 = glm::normalize(glm::cross(d, helper)), e2 = glm::cross(d, e1);
      // The surface point at the float direction the function really sees.
      const auto surface = [&](double a, double b) {
        const glm::vec3 df(glm::normalize(d + a * e1 + b * e2));
        return glm::dvec3(df) / glm::length(glm::dvec3(df)) * double(scenes::sphere_radius(p, df));
      };
      const glm::dvec3 ta = surface(step, 0) - surface(-step, 0), tb = surface(0, step) - surface(0, -step);
      const glm::dvec3 fd = glm::cross(ta, tb);
      ASSERT_GT(glm::dot(fd, d), 0.0);
      worst = std::max(worst, angle_deg(fd, glm::dvec3(scenes::sphere_normal(p, glm::vec3(d)))));
    }
    EXPECT_LT(worst, 0.01) << "amplitude " << amplitude;
  }
}

TEST(ScenesSphere, MeshesFollowTheContract) {
  scenes::SphereParams p;
  p.low_cells = 5;
  p.high_cells = 24;
  p.radius = 3.0f;
  const scenes::ScenePair pair = scenes::make_displaced_sphere(p);
  expect_finite(pair.low);
  expect_finite(pair.high);
  ASSERT_EQ(pair.low.triangle_count(), 6u * 2u * 25u);
  ASSERT_EQ(pair.high.triangle_count(), 6u * 2u * 24u * 24u);
  EXPECT_TRUE(pair.low.has_uvs());
  EXPECT_FALSE(pair.high.has_uvs());
  for (std::size_t v = 0; v < pair.low.vertex_count(); ++v) {
    const glm::vec3 q = pair.low.positions[v];
    EXPECT_NEAR(glm::length(q), 3.0f, 1e-5f);
    EXPECT_LT(angle_deg(glm::dvec3(pair.low.normals[v]), glm::dvec3(q)), 1e-4);
  }
  double lo = 1e9, hi = 0.0;
  for (std::size_t v = 0; v < pair.high.vertex_count(); ++v) {
    const glm::vec3 q = pair.high.positions[v];
    const glm::vec3 d = q / glm::length(q);
    EXPECT_NEAR(glm::length(q), scenes::sphere_radius(p, d), 1e-5f);
    EXPECT_LT(angle_deg(glm::dvec3(pair.high.normals[v]), glm::dvec3(scenes::sphere_normal(p, d))), 1e-3);
    lo = std::min(lo, double(glm::length(q)));
    hi = std::max(hi, double(glm::length(q)));
  }
  // The displacement is visible but stays a few percent of the radius.
  EXPECT_GT(hi - lo, 0.02 * 3.0);
  EXPECT_LT(hi - lo, 0.12 * 3.0);
  expect_watertight(pair.low);
  expect_watertight(pair.high);
  expect_outward(pair.low);
  expect_outward(pair.high);
  // High normals agree with the faces around them.
  for (std::size_t t = 0; t < pair.high.triangle_count(); ++t) {
    const std::uint32_t* tri = &pair.high.indices[3 * t];
    const glm::vec3 n = glm::cross(pair.high.positions[tri[1]] - pair.high.positions[tri[0]],
                                   pair.high.positions[tri[2]] - pair.high.positions[tri[0]]);
    for (int k = 0; k < 3; ++k) ASSERT_GT(glm::dot(n, pair.high.normals[tri[k]]), 0.0f);
  }
}

TEST(ScenesCubeSphere, SeamsAreWatertightWithAndWithoutUvs) {
  scenes::SphereParams p;
  const auto radius = [&p](const glm::vec3& d) { return scenes::sphere_radius(p, d); };
  for (int cells : {1, 2, 7, 16}) {
    SCOPED_TRACE(cells);
    const Mesh split = scenes::make_cube_sphere(cells, radius, true, 0.02f);
    const Mesh welded = scenes::make_cube_sphere(cells, radius, false, 0.0f);
    EXPECT_EQ(split.vertex_count(), 6u * (cells + 1) * (cells + 1));
    // Without UVs seam vertices are shared: V = 6 n^2 + 2 for a closed cube.
    EXPECT_EQ(welded.vertex_count(), 6u * cells * cells + 2u);
    EXPECT_FALSE(welded.has_uvs());
    expect_watertight(split);
    expect_watertight(welded);
    expect_outward(split);
    expect_outward(welded);
    expect_finite(split);
    expect_finite(welded);
  }
}

TEST(ScenesCubeSphere, UvChartsAreInsideDisjointAndNotMirrored) {
  const float gutter = 0.01f;
  const int cells = 6;
  const Mesh mesh = scenes::make_cube_sphere(
      cells, [](const glm::vec3&) { return 1.0f; }, true, gutter);
  ASSERT_EQ(mesh.uvs.size(), mesh.vertex_count());
  // Charts = connected components of triangles sharing vertices.
  std::vector<std::uint32_t> parent(mesh.vertex_count());
  std::iota(parent.begin(), parent.end(), 0u);
  const auto find = [&](std::uint32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    parent[find(mesh.indices[3 * t + 1])] = find(mesh.indices[3 * t]);
    parent[find(mesh.indices[3 * t + 2])] = find(mesh.indices[3 * t]);
  }
  std::map<std::uint32_t, std::pair<glm::vec2, glm::vec2>> boxes;  // chart root -> uv bounds
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const glm::vec2 uv = mesh.uvs[v];
    EXPECT_GE(uv.x, gutter - 1e-6f);
    EXPECT_LE(uv.x, 1.0f - gutter + 1e-6f);
    EXPECT_GE(uv.y, gutter - 1e-6f);
    EXPECT_LE(uv.y, 1.0f - gutter + 1e-6f);
    auto [it, inserted] = boxes.try_emplace(find(static_cast<std::uint32_t>(v)), uv, uv);
    it->second.first = glm::min(it->second.first, uv);
    it->second.second = glm::max(it->second.second, uv);
  }
  ASSERT_EQ(boxes.size(), 6u);
  std::vector<std::pair<glm::vec2, glm::vec2>> list;
  for (const auto& entry : boxes) list.push_back(entry.second);
  for (std::size_t a = 0; a < list.size(); ++a) {
    // Each chart fills its atlas cell minus the gutter.
    EXPECT_NEAR(list[a].second.x - list[a].first.x, 1.0f / 3.0f - 2 * gutter, 1e-5f);
    EXPECT_NEAR(list[a].second.y - list[a].first.y, 0.5f - 2 * gutter, 1e-5f);
    for (std::size_t b = a + 1; b < list.size(); ++b) {
      const bool apart = list[a].second.x + 2 * gutter <= list[b].first.x + 1e-6f ||
                         list[b].second.x + 2 * gutter <= list[a].first.x + 1e-6f ||
                         list[a].second.y + 2 * gutter <= list[b].first.y + 1e-6f ||
                         list[b].second.y + 2 * gutter <= list[a].first.y + 1e-6f;
      EXPECT_TRUE(apart) << "charts " << a << " and " << b << " overlap or touch";
    }
  }
  // Not mirrored: every triangle has positive UV area, and the UV directions
  // map to a right-handed frame seen from outside.
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    const std::uint32_t* tri = &mesh.indices[3 * t];
    const glm::vec2 e1 = mesh.uvs[tri[1]] - mesh.uvs[tri[0]], e2 = mesh.uvs[tri[2]] - mesh.uvs[tri[0]];
    const float uv_area = e1.x * e2.y - e1.y * e2.x;
    ASSERT_GT(uv_area, 0.0f) << "triangle " << t;
    const glm::vec3 p1 = mesh.positions[tri[1]] - mesh.positions[tri[0]];
    const glm::vec3 p2 = mesh.positions[tri[2]] - mesh.positions[tri[0]];
    // dP/du and dP/dv from the 2x2 system [e1 e2] -> [p1 p2].
    const glm::vec3 dpdu = (p1 * e2.y - p2 * e1.y) / uv_area;
    const glm::vec3 dpdv = (p2 * e1.x - p1 * e2.x) / uv_area;
    ASSERT_GT(glm::dot(glm::cross(dpdu, dpdv), mesh.positions[tri[0]]), 0.0f) << "triangle " << t;
  }
}

TEST(ScenesDeterminism, TwoCallsGiveIdenticalMeshes) {
  scenes::HeightfieldParams hp;
  hp.high_cells = 64;
  const scenes::ScenePair h1 = scenes::make_heightfield(hp), h2 = scenes::make_heightfield(hp);
  EXPECT_TRUE(meshes_identical(h1.low, h2.low));
  EXPECT_TRUE(meshes_identical(h1.high, h2.high));
  scenes::SphereParams sp;
  sp.high_cells = 32;
  const scenes::ScenePair s1 = scenes::make_displaced_sphere(sp), s2 = scenes::make_displaced_sphere(sp);
  EXPECT_TRUE(meshes_identical(s1.low, s2.low));
  EXPECT_TRUE(meshes_identical(s1.high, s2.high));
  scenes::MoonParams mp;
  mp.high_cells = 24;
  mp.low_cells = 4;
  const scenes::ScenePair m1 = scenes::make_moon(mp), m2 = scenes::make_moon(mp);
  EXPECT_TRUE(meshes_identical(m1.low, m2.low));
  EXPECT_TRUE(bitwise_equal(m1.high.positions, m2.high.positions));
  EXPECT_TRUE(bitwise_equal(m1.high.indices, m2.high.indices));
}

TEST(ScenesDeterminism, MoonIsTheSameWithOneAndTwoThreads) {
  scenes::MoonParams p;
  p.high_cells = 40;
  p.low_cells = 6;
  scenes::ScenePair one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = scenes::make_moon(p);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    two = scenes::make_moon(p);
  }
  EXPECT_TRUE(meshes_identical(one.low, two.low));
  // The high normals come from compute_vertex_normals (another stage): only
  // the generator's own output is compared here.
  EXPECT_TRUE(bitwise_equal(one.high.positions, two.high.positions));
  EXPECT_TRUE(bitwise_equal(one.high.indices, two.high.indices));
}

TEST(ScenesMoon, SizeReliefAndSanity) {
  scenes::MoonParams p;
  p.radius = 2.0f;
  p.high_cells = 64;
  p.low_cells = 8;
  const scenes::ScenePair pair = scenes::make_moon(p);
  ASSERT_EQ(pair.high.triangle_count(), 12u * 64u * 64u);
  ASSERT_EQ(pair.high.vertex_count(), 6u * 64u * 64u + 2u);
  ASSERT_EQ(pair.high.normals.size(), pair.high.vertex_count());
  EXPECT_FALSE(pair.high.has_uvs());
  ASSERT_EQ(pair.low.triangle_count(), 12u * 8u * 8u);
  EXPECT_TRUE(pair.low.has_uvs());
  for (const glm::vec3& q : pair.low.positions) EXPECT_NEAR(glm::length(q), 2.0f, 1e-5f);
  for (const glm::vec3& q : pair.high.positions) {
    ASSERT_TRUE(std::isfinite(q.x) && std::isfinite(q.y) && std::isfinite(q.z));
  }
  expect_watertight(pair.high);
  expect_watertight(pair.low);
  expect_outward(pair.high);

  double lo = 1e9, hi = -1e9;
  for (const glm::vec3& q : pair.high.positions) {
    const double h = glm::length(glm::dvec3(q)) / 2.0 - 1.0;
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
  EXPECT_GE(lo, -double(scenes::moon_relief_limit) - 1e-6);
  EXPECT_LE(hi, double(scenes::moon_relief_limit) + 1e-6);
  EXPECT_GT(hi - lo, 0.01);  // craters are really there: at least 1 % relief
  EXPECT_LT(lo, -0.005);     // bowls below the datum
  EXPECT_GT(hi, 0.001);      // rims above it

  // The default moon has the documented size (counted, not generated).
  const scenes::MoonParams defaults;
  EXPECT_EQ(12ll * defaults.high_cells * defaults.high_cells, 1997568ll);
}

TEST(ScenesMoon, CratersDependOnSeedAndDiffer) {
  scenes::MoonParams a;
  scenes::MoonParams b = a;
  b.seed = 2;
  const scenes::MoonSurface sa(a), sb(b);
  int differing = 0;
  for (const glm::dvec3& d : test_directions()) {
    const float ra = sa.radius(glm::vec3(d)), rb = sb.radius(glm::vec3(d));
    ASSERT_TRUE(std::isfinite(ra));
    ASSERT_EQ(ra, sa.radius(glm::vec3(d)));
    if (ra != rb) ++differing;
  }
  EXPECT_GT(differing, 300);

  // Noise distortion: a lone crater is not radially symmetric. Its centre is
  // the unique minimum of its profile (the distortion is multiplicative).
  scenes::MoonParams lone;
  lone.crater_count = 1;
  scenes::MoonParams none = lone;
  none.crater_count = 0;
  const scenes::MoonSurface surface(lone), plain(none);
  const auto crater = [&](const glm::dvec3& d) {
    return surface.relative_height(d) - plain.relative_height(d);
  };
  // A Fibonacci grid finer than the smallest crater radius (0.015 rad).
  glm::dvec3 centre(0, 0, 1);
  double deepest = 1.0;
  const int count = 120000;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / count, r = std::sqrt(1.0 - z * z);
    const glm::dvec3 d(r * std::cos(golden * i), r * std::sin(golden * i), z);
    const double h = crater(d);
    if (h < deepest) deepest = h, centre = d;
  }
  ASSERT_LT(deepest, -0.001);
  // Heights on rings around the centre vary with the azimuth by a sizeable
  // part of the depth somewhere (a plain brush would give ~0).
  const glm::dvec3 e1 = glm::normalize(glm::cross(centre, glm::dvec3(0.3, 0.5, 0.8)));
  const glm::dvec3 e2 = glm::cross(centre, e1);
  double widest = 0.0;
  for (double rho = 0.002; rho < 0.2; rho += 0.002) {
    double lo = 1.0, hi = -1.0;
    for (int k = 0; k < 64; ++k) {
      const double phi = 2.0 * std::numbers::pi * k / 64;
      const glm::dvec3 d = glm::normalize(centre + std::tan(rho) * (std::cos(phi) * e1 + std::sin(phi) * e2));
      lo = std::min(lo, crater(d));
      hi = std::max(hi, crater(d));
    }
    widest = std::max(widest, hi - lo);
  }
  EXPECT_GT(widest, 0.3 * -deepest);
}

TEST(ScenesCli, WritesBothFilesAndRejectsBadUsage) {
  const nmbake::test::TempDir dir;
  const std::string out = dir.file("out");
  const nmbake::test::CommandResult ok = nmbake::test::run_command(
      nmbake::test::gen_path() + " heightfield --out-dir " + out + " --high-cells 10 --low-cells 2");
  ASSERT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_NE(ok.output.find("heightfield_low.obj: 8 triangles"), std::string::npos) << ok.output;
  EXPECT_NE(ok.output.find("heightfield_high.ply: 200 triangles"), std::string::npos) << ok.output;
  nmbake::Mesh low, high;
  nmbake::LoadStats stats;
  ASSERT_TRUE(nmbake::load_mesh(out + "/heightfield_low.obj", {}, low, stats).is_ok());
  ASSERT_TRUE(nmbake::load_mesh(out + "/heightfield_high.ply", {}, high, stats).is_ok());
  EXPECT_EQ(low.triangle_count(), 8u);
  EXPECT_TRUE(low.has_uvs());
  EXPECT_EQ(high.triangle_count(), 200u);
  EXPECT_TRUE(high.has_normals());

  for (const std::string& args : {std::string("moon"), "moon --out-dir " + out + " --high-cells 0",
                                  "sphere --out-dir " + out + " --amplitude 2", std::string("nonsense")}) {
    const nmbake::test::CommandResult bad = nmbake::test::run_command(nmbake::test::gen_path() + " " + args);
    EXPECT_EQ(bad.exit_code, 2) << args << ": " << bad.output;
  }
}

// --- Hard-edged and concave scenes (hard_scenes.hpp) -----------------------

// The distance of a profile against a dense polyline of it, its sign against
// the closed polygon (even-odd), and its normal against the gradient.
TEST(ScenesHard, RevolvedProfileDistanceIsExact) {
  for (const scenes::RevolveParams& p : {scenes::bowl_params(), scenes::cylinder_params()}) {
    const scenes::RevolveProfile profile(p.profile);
    std::vector<glm::dvec2> dense;
    for (const auto& e : profile.elements()) {
      for (int j = 0; j < 4000; ++j) dense.push_back(e.point(j / 4000.0));
    }
    dense.push_back(profile.elements().back().b);
    const auto inside = [&](const glm::dvec2& q) {  // closed along the axis
      bool in = false;
      for (std::size_t i = 0; i < dense.size(); ++i) {
        const glm::dvec2 a = dense[i], b = dense[(i + 1) % dense.size()];
        if ((a.y > q.y) != (b.y > q.y) && q.x < a.x + (q.y - a.y) * (b.x - a.x) / (b.y - a.y)) in = !in;
      }
      return in;
    };
    double worst = 0.0, worst_angle = 0.0;
    for (int i = 0; i < 3000; ++i) {
      const glm::dvec2 q(0.013 + 1.1 * std::fmod(0.7548776662 * (i + 1), 1.0),
                         -0.95 + 1.9 * std::fmod(0.5698402910 * (i + 1), 1.0));
      double near = 1e9;
      for (const glm::dvec2& d : dense) near = std::min(near, glm::length(q - d));
      glm::dvec2 n;
      const double sd = profile.signed_distance(q, &n);
      if (near < 0.002) continue;  // the polyline's own error
      worst = std::max(worst, std::fabs(std::fabs(sd) - near));
      EXPECT_EQ(sd < 0.0, inside(q)) << q.x << " " << q.y;
      // The gradient of the field at q, by central differences.
      const double h = 1e-6;
      const glm::dvec2 g((profile.signed_distance(q + glm::dvec2(h, 0), nullptr) -
                          profile.signed_distance(q - glm::dvec2(h, 0), nullptr)) /
                             (2 * h),
                         (profile.signed_distance(q + glm::dvec2(0, h), nullptr) -
                          profile.signed_distance(q - glm::dvec2(0, h), nullptr)) /
                             (2 * h));
      if (std::fabs(glm::length(g) - 1.0) > 1e-3) continue;  // on a medial axis
      // Nearest to a sharp corner, the gradient points from the corner.
      bool corner = false;
      for (std::size_t k = 0; k + 1 < profile.elements().size(); ++k) {
        const auto& e = profile.elements()[k];
        if (glm::dot(e.normal_at(1.0), profile.elements()[k + 1].normal_at(0.0)) < 1.0 - 1e-9 &&
            std::fabs(glm::length(q - e.b) - std::fabs(sd)) < 1e-9)
          corner = true;
      }
      if (corner) continue;
      worst_angle =
          std::max(worst_angle, std::acos(std::clamp(glm::dot(glm::normalize(g), n), -1.0, 1.0)) / kDegree);
    }
    EXPECT_LT(worst, 1e-4);
    EXPECT_LT(worst_angle, 0.01);
  }
}

TEST(ScenesHard, MeshesAreClosedOutwardAndOnTheirSurface) {
  for (const std::string name : {"bowl", "cylinder", "panel", "box_r0.05"}) {
    SCOPED_TRACE(name);
    // The lab's scenes at a lower resolution (the generators are the same).
    scenes::ScenePair pair;
    if (name == "bowl" || name == "cylinder") {
      scenes::RevolveParams p = name == "bowl" ? scenes::bowl_params() : scenes::cylinder_params();
      p.high_segments = 96;
      p.high_step = 0.02;
      pair = scenes::make_revolved(p);
    } else if (name == "panel") {
      scenes::PanelParams p = scenes::panel_params();
      p.high_cells = 64;
      pair = scenes::make_panel(p);
    } else {
      scenes::BoxParams p;
      p.bevel = 0.05f;
      p.high_cells = 48;
      pair = scenes::make_box(p);
    }
    expect_finite(pair.low);
    expect_finite(pair.high);
    expect_watertight(pair.low);
    expect_watertight(pair.high);
    ASSERT_TRUE(pair.low.has_uvs());
    for (const glm::vec2& uv : pair.low.uvs) {
      ASSERT_GE(std::min(uv.x, uv.y), 0.0f);
      ASSERT_LE(std::max(uv.x, uv.y), 1.0f);
    }
    // Windings agree with the normals (outward), and the high vertices lie on
    // the true surface with its normals.
    for (const Mesh* m : {&pair.low, &pair.high}) {
      std::size_t against = 0;
      for (std::size_t t = 0; t < m->triangle_count(); ++t) {
        const std::uint32_t* v = &m->indices[3 * t];
        const glm::vec3 face =
            glm::cross(m->positions[v[1]] - m->positions[v[0]], m->positions[v[2]] - m->positions[v[0]]);
        if (glm::dot(face, m->normals[v[0]] + m->normals[v[1]] + m->normals[v[2]]) <= 0.0f) ++against;
      }
      EXPECT_EQ(against, 0u);
    }
    const auto truth = [&](const glm::dvec3& x, glm::dvec3& n) {
      if (name == "panel") {
        n = scenes::panel_normal(scenes::panel_params(), x);
        return scenes::panel_field(scenes::panel_params(), x);
      }
      if (name == "box_r0.05") {
        scenes::BoxParams b;
        b.bevel = 0.05f;
        n = scenes::box_normal(b, x);
        return scenes::box_field(b, x);
      }
      const scenes::RevolveProfile profile(
          (name == "bowl" ? scenes::bowl_params() : scenes::cylinder_params()).profile);
      n = scenes::revolve_normal(profile, x);
      return scenes::revolve_field(profile, x);
    };
    double worst = 0.0, worst_angle = 0.0;
    for (std::size_t v = 0; v < pair.high.vertex_count(); ++v) {
      glm::dvec3 n;
      worst = std::max(worst, std::fabs(truth(glm::dvec3(pair.high.positions[v]), n)));
      // At a crease the mesh has a vertex per side: the truth there is either
      // side's, or a hair inside on the vertex's side (or the other's, skipped).
      double a = angle_deg(n, glm::dvec3(pair.high.normals[v]));
      truth(glm::dvec3(pair.high.positions[v]) - 1e-5 * glm::dvec3(pair.high.normals[v]), n);
      a = std::min(a, angle_deg(n, glm::dvec3(pair.high.normals[v])));
      if (a < 10.0) worst_angle = std::max(worst_angle, a);
    }
    EXPECT_LT(worst, 2e-6);
    EXPECT_LT(worst_angle, 0.01);
  }
}

TEST(ScenesHard, PanelNormalMatchesTheFieldGradient) {
  const scenes::PanelParams p = scenes::panel_params();
  double worst = 0.0;
  for (int i = 0; i < 4000; ++i) {
    const double x = -0.99 + 1.98 * std::fmod(0.7548776662 * (i + 1), 1.0);
    const double z = -0.99 + 1.98 * std::fmod(0.5698402910 * (i + 1), 1.0);
    const glm::dvec3 q(x, p.top - scenes::panel_depth(p, x, z, nullptr, nullptr), z);
    const double h = 1e-7;
    glm::dvec3 g;
    for (int c = 0; c < 3; ++c) {
      glm::dvec3 e(0.0);
      e[c] = h;
      g[c] = (scenes::panel_field(p, q + e) - scenes::panel_field(p, q - e)) / (2 * h);
    }
    worst = std::max(worst, angle_deg(g, scenes::panel_normal(p, q)));
  }
  EXPECT_LT(worst, 0.01);
}

}  // namespace
