#include "nmbake/trace.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <string>

#include "hard_scenes.hpp"
#include "lab_scenes.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

using test::low_quad;

// Adds a square [-1,2]^2 at height z, facing +z (or -z when flipped).
void add_layer(Mesh& m, float z, bool flipped) {
  const auto base = static_cast<std::uint32_t>(m.positions.size());
  m.positions.insert(m.positions.end(), {{-1, -1, z}, {2, -1, z}, {2, 2, z}, {-1, 2, z}});
  if (flipped) {
    m.indices.insert(m.indices.end(), {base, base + 2, base + 1, base, base + 3, base + 2});
  } else {
    m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  }
}

TexelSamples samples_at(const std::vector<glm::vec2>& uv) {
  TexelSamples t;
  t.width = static_cast<int>(uv.size());
  t.height = 1;
  t.samples = 1;
  for (const glm::vec2& p : uv) {
    // On triangle 0 (corners (0,0), (1,0), (1,1)): p = b1 (1,0) + b2 (1,1).
    t.triangle.push_back(0);
    t.bary.push_back({p.x - p.y, p.y});
  }
  t.coverage.assign(uv.size(), 1);
  return t;
}

TEST(Trace, MakeRayFollowsTheAveragedCage) {
  const LowSurface s = low_quad();
  RayOptions o;
  o.front = 0.5f;
  o.back = 0.25f;
  bool fallback = true;
  const Ray r = make_ray(s, 0, {0.25f, 0.25f}, o, fallback);
  EXPECT_FALSE(fallback);
  EXPECT_NEAR(r.surface_point.x, 0.5f, 1e-6f);
  EXPECT_NEAR(r.surface_point.y, 0.25f, 1e-6f);
  EXPECT_NEAR(r.origin.z, 0.5f, 1e-6f);
  EXPECT_NEAR(r.direction.z, -1.0f, 1e-6f);
  EXPECT_NEAR(r.tfar, 0.75f, 1e-6f);
}

TEST(Trace, ZeroNormalUsesFaceNormal) {
  LowSurface s = low_quad();
  s.cage_normal.assign(6, glm::vec3(0.0f));
  RayOptions o;
  o.front = 1.0f;
  bool fallback = false;
  const Ray r = make_ray(s, 0, {0.3f, 0.3f}, o, fallback);
  EXPECT_TRUE(fallback);
  EXPECT_NEAR(r.direction.z, -1.0f, 1e-6f);
}

// trace() builds its rays 4 lanes at a time; every lane must be the ray
// make_ray() gives for that sample, whatever its place in a packet (partial
// packets and groups, empty samples between) and including fallback lanes.
// Checked against an analytic plane: the hit distance and the hit point.
// trace() against make_ray() sample by sample, on a plane z = h that ends at
// x = edge (rays past it miss): hit points, distances, misses and counts.
// Random empty samples (15%) and fallback lanes (triangle 1, 20%) break up
// the texels, so packets mix whole texels, partial ones and runs that are
// not consecutive samples.
void check_packets_against_make_ray(int samples_per_texel, int width, int height) {
  SCOPED_TRACE(testing::Message() << samples_per_texel << " spp, " << width << " x " << height);
  LowSurface s = low_quad();
  // Tilted, unequal corner normals on triangle 0: every sample's ray differs.
  s.cage_normal[0] = {0.3f, 0.0f, 1.0f};
  s.cage_normal[1] = {0.0f, -0.2f, 1.0f};
  s.cage_normal[2] = {-0.1f, 0.15f, 0.9f};
  // Triangle 1 has no usable averaged normal: its rays take the face normal.
  for (int c = 3; c < 6; ++c) s.cage_normal[c] = glm::vec3(0.0f);
  Mesh high;
  const float h = -0.15f, edge = 0.55f;
  high.positions = {{-5, -5, h}, {edge, -5, h}, {edge, 6, h}, {-5, 6, h}};
  high.indices = {0, 1, 2, 0, 2, 3};
  pad_for_embree(high);
  HighScene scene;
  ASSERT_TRUE(HighScene::build(high, BuildQuality::medium, false, scene).is_ok());

  TexelSamples t;
  t.width = width;
  t.height = height;
  t.samples = samples_per_texel;
  std::uint32_t state = 12345u;
  const auto next = [&state] {
    state = state * 1664525u + 1013904223u;
    return static_cast<float>(state >> 8) / 16777216.0f;
  };
  std::size_t traced = 0, fallbacks = 0;
  for (int i = 0; i < t.width * t.height * t.samples; ++i) {
    const float r = next();
    const std::int32_t tri = r < 0.15f ? -1 : r < 0.35f ? 1 : 0;
    float b1 = next(), b2 = next();
    if (b1 + b2 > 1.0f) b1 = 1.0f - b1, b2 = 1.0f - b2;
    t.triangle.push_back(tri);
    t.bary.push_back({b1, b2});
    traced += tri >= 0;
    fallbacks += tri == 1;
  }
  t.coverage.assign(static_cast<std::size_t>(t.width) * t.height, 1);
  RayOptions o;
  o.front = 0.4f;
  o.back = 0.6f;

  Hits hits;
  TraceStats stats;
  trace(scene, s, t, o, hits, stats);
  EXPECT_EQ(stats.samples, traced);
  EXPECT_EQ(stats.rays, traced);
  EXPECT_EQ(stats.hits + stats.misses, traced);
  EXPECT_EQ(stats.ray_fallbacks, fallbacks);
  std::size_t hit_count = 0, expected_misses = 0;
  for (std::size_t i = 0; i < t.triangle.size(); ++i) {
    if (t.triangle[i] < 0) {
      EXPECT_EQ(hits.triangle[i], -1) << "sample " << i;
      continue;
    }
    hit_count += hits.triangle[i] >= 0;
    bool fallback = false;
    const Ray ray = make_ray(s, t.triangle[i], t.bary[i], o, fallback);
    EXPECT_EQ(fallback, t.triangle[i] == 1);
    const float t_hit = (ray.origin.z - h) / -ray.direction.z;
    const glm::vec3 expected = ray.origin + t_hit * ray.direction;
    if (expected.x > edge + 1e-4f) {
      ++expected_misses;
      EXPECT_EQ(hits.triangle[i], -1) << "sample " << i;
      continue;
    }
    if (expected.x > edge - 1e-4f) continue;  // on the edge: either
    ASSERT_GE(hits.triangle[i], 0) << "sample " << i;
    const std::uint32_t* c = &high.indices[3 * static_cast<std::size_t>(hits.triangle[i])];
    const glm::vec2 b = hits.bary[i];
    const glm::vec3 got =
        high.positions[c[0]] * (1.0f - b.x - b.y) + high.positions[c[1]] * b.x + high.positions[c[2]] * b.y;
    EXPECT_NEAR(got.x, expected.x, 1e-4f) << "sample " << i;
    EXPECT_NEAR(got.y, expected.y, 1e-4f) << "sample " << i;
    EXPECT_NEAR(hits.distance[i], ray.t_surface - t_hit, 1e-5f) << "sample " << i;
  }
  EXPECT_EQ(stats.hits, hit_count);
  EXPECT_GT(expected_misses, traced / 5);  // the edge is in the middle of the map
  EXPECT_LT(expected_misses, traced * 4 / 5);
}

TEST(Trace, PacketRaysAreMakeRayLaneByLane) {
  check_packets_against_make_ray(4, 23, 3);  // a tile row of 16 texels and one of 7
  check_packets_against_make_ray(1, 37, 19);
  check_packets_against_make_ray(16, 21, 5);
  check_packets_against_make_ray(64, 6, 5);
}

// The rays trace() builds in SIMD lanes are make_ray()'s bit for bit, for
// both cages and every sample count, on a low mesh of many small triangles
// (packets mix lanes on one triangle and lanes on several).
TEST(Trace, PacketRaysEqualMakeRayBitForBit) {
  // A bumpy 8 x 8 grid of quads, with normals that differ per corner.
  LowSurface s;
  const auto height = [](float x, float y) { return 0.1f * std::sin(7.0f * x) * std::cos(5.0f * y); };
  const auto normal = [](float x, float y) {
    return glm::normalize(glm::vec3(-0.7f * std::cos(7.0f * x) * std::cos(5.0f * y),
                                    0.5f * std::sin(7.0f * x) * std::sin(5.0f * y), 1.0f));
  };
  const int n = 8;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const glm::vec2 q[4] = {{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}};
      for (int c : {0, 1, 2, 0, 2, 3}) {
        const glm::vec2 uv = q[c] / static_cast<float>(n);
        s.position.push_back({uv.x, uv.y, height(uv.x, uv.y)});
        s.uv.push_back(uv);
        s.normal.push_back(normal(uv.x, uv.y));
        s.cage_normal.push_back(normal(uv.x + 0.01f, uv.y - 0.02f) * 1.3f);
        s.tangent.push_back({1, 0, 0, 1});
      }
    }
  }
  s.cage_normal[7] = glm::vec3(0.0f);  // a fallback corner
  for (int spp : {1, 4, 16, 64}) {
    TexelSamples t;
    RasterStats raster_stats;
    rasterize(s, 37, 21, spp, t, raster_stats);
    for (std::size_t i = 0; i < t.triangle.size(); i += 11) t.triangle[i] = -1;  // holes
    for (CageMode cage : {CageMode::averaged, CageMode::interpolated}) {
      SCOPED_TRACE(testing::Message() << spp << " spp, cage " << static_cast<int>(cage));
      RayOptions o;
      o.cage = cage;
      o.front = 0.3f;
      o.back = 0.45f;
      const std::vector<PacketRay> rays = packet_rays(s, t, o);
      ASSERT_EQ(rays.size(), t.triangle.size());
      std::size_t compared = 0;
      for (std::size_t i = 0; i < rays.size(); ++i) {
        ASSERT_EQ(rays[i].traced, t.triangle[i] >= 0) << "sample " << i;
        if (!rays[i].traced) continue;
        bool fallback = false;
        const Ray ray = make_ray(s, t.triangle[i], t.bary[i], o, fallback);
        for (int k = 0; k < 3; ++k) {
          ASSERT_EQ(rays[i].origin[k], ray.origin[k]) << "sample " << i;
          ASSERT_EQ(rays[i].direction[k], ray.direction[k]) << "sample " << i;
        }
        ASSERT_EQ(rays[i].tnear, 0.0f);
        ASSERT_EQ(rays[i].tfar, ray.tfar);
        ++compared;
      }
      EXPECT_GT(compared, t.triangle.size() / 2);
    }
  }
}

TEST(Trace, FirstAndNearestHits) {
  const LowSurface s = low_quad();
  Mesh high;
  add_layer(high, 0.4f, false);    // far outside: first from the cage
  add_layer(high, -0.05f, false);  // just inside: nearest to the low surface
  pad_for_embree(high);
  HighScene scene;
  ASSERT_TRUE(HighScene::build(high, BuildQuality::medium, false, scene).is_ok());
  const TexelSamples t = samples_at({{0.5f, 0.25f}, {0.9f, 0.1f}});
  RayOptions o;
  o.front = 0.5f;
  o.back = 0.1f;

  Hits hits;
  TraceStats stats;
  trace(scene, s, t, o, hits, stats);
  EXPECT_EQ(stats.hits, 2u);
  EXPECT_EQ(stats.misses, 0u);
  EXPECT_EQ(hits.triangle[0] / 2, 0);  // layer 0
  EXPECT_NEAR(hits.distance[0], 0.4f, 1e-5f);

  o.hit = HitRule::nearest;
  Hits nearest;
  TraceStats nstats;
  trace(scene, s, t, o, nearest, nstats);
  EXPECT_EQ(nstats.rays, 4u);  // two per sample
  EXPECT_EQ(nearest.triangle[0] / 2, 1);
  EXPECT_NEAR(nearest.distance[0], -0.05f, 1e-5f);
  EXPECT_NEAR(nearest.distance[1], -0.05f, 1e-5f);
}

TEST(Trace, MissesAreCountedAndMarked) {
  const LowSurface s = low_quad();
  Mesh high;
  add_layer(high, 2.0f, false);  // out of reach
  pad_for_embree(high);
  HighScene scene;
  ASSERT_TRUE(HighScene::build(high, BuildQuality::low, false, scene).is_ok());
  TexelSamples t = samples_at({{0.5f, 0.25f}, {0.5f, 0.25f}});
  t.triangle[1] = -1;  // an empty sample: not traced at all
  RayOptions o;
  o.front = 0.5f;
  o.back = 0.5f;
  Hits hits;
  TraceStats stats;
  trace(scene, s, t, o, hits, stats);
  EXPECT_EQ(stats.samples, 1u);
  EXPECT_EQ(stats.misses, 1u);
  EXPECT_EQ(hits.triangle[0], -1);
  EXPECT_EQ(hits.triangle[1], -1);
}

TEST(Trace, IgnoreBackfacesSkipsFlippedLayer) {
  const LowSurface s = low_quad();
  Mesh high;
  add_layer(high, 0.3f, true);  // faces -z: seen from the cage it is a back face
  add_layer(high, 0.1f, false);
  pad_for_embree(high);
  RayOptions o;
  o.front = 0.5f;
  o.back = 0.1f;
  const TexelSamples t = samples_at({{0.5f, 0.25f}});
  for (bool ignore : {false, true}) {
    HighScene scene;
    ASSERT_TRUE(HighScene::build(high, BuildQuality::medium, ignore, scene).is_ok());
    Hits hits;
    TraceStats stats;
    trace(scene, s, t, o, hits, stats);
    ASSERT_GE(hits.triangle[0], 0);
    EXPECT_EQ(hits.triangle[0] / 2, ignore ? 1 : 0);
  }
}

TEST(Trace, CageMeshRaysStartOnTheCage) {
  LowSurface s = low_quad();
  for (const glm::vec3& p : s.position) s.cage_position.push_back(p + glm::vec3(0.0f, 0.0f, 0.3f));
  Mesh high;
  add_layer(high, 0.2f, false);
  add_layer(high, 0.5f, false);  // above the cage: never seen
  pad_for_embree(high);
  HighScene scene;
  ASSERT_TRUE(HighScene::build(high, BuildQuality::medium, false, scene).is_ok());
  RayOptions o;
  o.cage = CageMode::mesh;
  o.back = 0.1f;
  const TexelSamples t = samples_at({{0.5f, 0.25f}});
  Hits hits;
  TraceStats stats;
  trace(scene, s, t, o, hits, stats);
  ASSERT_GE(hits.triangle[0], 0);
  EXPECT_EQ(hits.triangle[0] / 2, 0);
  EXPECT_NEAR(hits.distance[0], 0.2f, 1e-5f);
}

TEST(Trace, EstimatedDistancesCoverTheOffset) {
  const LowSurface s = low_quad();
  Mesh high;
  // A high surface 0.03 above the low one over x < 0.5 and 0.05 below over x >= 0.5.
  high.positions = {{-1, -1, 0.03f},    {0.5f, -1, 0.03f}, {0.5f, 2, 0.03f}, {-1, 2, 0.03f},
                    {0.5f, -1, -0.05f}, {2, -1, -0.05f},   {2, 2, -0.05f},   {0.5f, 2, -0.05f}};
  high.indices = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
  pad_for_embree(high);
  HighScene scene;
  ASSERT_TRUE(HighScene::build(high, BuildQuality::medium, false, scene).is_ok());
  const DistanceEstimate e = estimate_distances(scene, s, std::sqrt(2.0f));
  EXPECT_GT(e.probes, 1000u);
  EXPECT_GE(e.front, 0.03f);
  EXPECT_LT(e.front, 0.1f);
  EXPECT_GE(e.back, 0.05f);
  EXPECT_LT(e.back, 0.12f);
}

}  // namespace
}  // namespace nmbake

namespace nmbake {
namespace {

// The low box of the lab (2 x 2 quads per face, split normals) as a surface.
LowSurface box_surface(int low_cells = 2) {
  scenes::BoxParams p;
  p.low_cells = low_cells;
  p.high_cells = 8;
  SurfaceStats stats;
  return build_low_surface(scenes::make_box(p).low, nullptr, stats);
}

TEST(Trace, HardEdgesAreFoundOnlyWhereNormalsSplit) {
  const LowSurface box = box_surface(2);
  // 12 cube edges of 2 segments each; every triangle touches one.
  EXPECT_EQ(box.hard_edge_a.size(), 24u);
  ASSERT_EQ(box.hard_corners.size(), box.triangle_count());
  for (std::size_t t = 0; t < box.triangle_count(); ++t) EXPECT_NE(box.hard_corners[t], 0) << t;
  // A smooth cube sphere (seams split for UVs, not normals): none.
  scenes::SphereParams p;
  p.low_cells = 3;
  SurfaceStats stats;
  const LowSurface sphere = build_low_surface(scenes::make_displaced_sphere(p).low, nullptr, stats);
  EXPECT_TRUE(sphere.hard_edge_a.empty());
  EXPECT_TRUE(sphere.hard_corners.empty());
}

// The banded cage: the averaged cage's direction on a hard edge, the face
// normal a band away from it, the averaged cage's rays bit for bit on
// triangles with no hard corner, and no jump between neighbouring triangles.
TEST(Trace, BandedCageFollowsTheAveragedCageOnlyNearHardEdges) {
  LowSurface box = box_surface(4);
  RayOptions banded;
  banded.cage = CageMode::banded;
  banded.front = 0.02f;
  banded.back = 0.08f;
  banded.edge_band = 2.0f;  // a band of 0.2 (cells are 0.5 wide)
  prepare_edge_band(box, edge_band_reach(banded));
  RayOptions averaged = banded;
  averaged.cage = CageMode::averaged;
  std::size_t on_edge = 0, beyond = 0, inner = 0;
  for (std::size_t t = 0; t < box.triangle_count(); ++t) {
    const glm::vec3 face = box.normal[3 * t];
    for (const glm::vec2 b : {glm::vec2(0.0f, 0.0f), glm::vec2(1.0f, 0.0f), glm::vec2(0.0f, 1.0f),
                              glm::vec2(0.2f, 0.3f), glm::vec2(0.45f, 0.1f), glm::vec2(0.5f, 0.5f)}) {
      bool fallback = false;
      const Ray rb = make_ray(box, static_cast<std::int32_t>(t), b, banded, fallback);
      const Ray ra = make_ray(box, static_cast<std::int32_t>(t), b, averaged, fallback);
      // The distance from the point to the box's nearest edge.
      const glm::vec3 q = glm::abs(rb.surface_point);
      float d = 1e9f;
      for (int k = 0; k < 3; ++k) {
        if (face[k] != 0.0f) continue;  // the face's own axis
        d = std::min(d, 1.0f - q[k]);
      }
      if (box.hard_corners[t] == 0) {
        ++inner;
        EXPECT_EQ(rb.direction, ra.direction) << t;  // bit for bit
      } else if (d < 1e-6f) {
        ++on_edge;
        EXPECT_NEAR(glm::length(rb.direction - ra.direction), 0.0f, 1e-6f) << t;
      } else if (d >= 0.2f) {
        ++beyond;
        EXPECT_NEAR(glm::length(rb.direction + face), 0.0f, 1e-6f) << t;
      }
    }
  }
  EXPECT_GT(on_edge, 50u);
  EXPECT_GT(beyond, 50u);
  EXPECT_GT(inner, 20u);
  // Continuity: the two triangles of every quad agree along their diagonal,
  // and neighbouring quads along their shared side.
  float worst = 0.0f;
  for (std::size_t t = 0; t + 1 < box.triangle_count(); t += 2) {
    for (float s : {0.05f, 0.3f, 0.61f, 0.9f}) {
      // Quad corners a b c d as triangles (a b c) and (a c d): diagonal a-c.
      bool fallback = false;
      const glm::vec3 a = box.position[3 * t], c = box.position[3 * t + 2];
      ASSERT_EQ(box.position[3 * t + 3], a);
      ASSERT_EQ(box.position[3 * t + 4], c);
      // On the diagonal: weight s on corner 2 of triangle t, and on corner 1 of triangle t + 1.
      const Ray first = make_ray(box, static_cast<std::int32_t>(t), {0.0f, s}, banded, fallback);
      const Ray second = make_ray(box, static_cast<std::int32_t>(t + 1), {s, 0.0f}, banded, fallback);
      ASSERT_NEAR(glm::length(first.surface_point - second.surface_point), 0.0f, 1e-6f);
      worst = std::max(worst, glm::length(first.direction - second.direction));
    }
  }
  EXPECT_LT(worst, 1e-5f);
}

// The banded cage's rays built in SIMD lanes (four lanes on one triangle with
// a hard corner: banded_axes(); lanes of several triangles: build_ray()) are
// make_ray()'s bit for bit: on hard edges, in the smoothstep between the
// averaged and the face's own normals, a band away, and with no band. Low
// meshes: the lab box with every triangle on a hard edge, a finer one with
// inner triangles too (packets that mix both), the box turned so its edges
// follow no axis, and the cylinder and the panel of the lab (long thin and
// fanned triangles, hard rims).
void check_banded_packets(const char* name, LowSurface surface, float edge_band, int width, int height,
                          bool beyond = true) {
  RayOptions o;
  o.cage = CageMode::banded;
  o.front = 0.03f;
  o.back = 0.12f;
  o.edge_band = edge_band;
  prepare_edge_band(surface, edge_band_reach(o));
  RayOptions own = o, averaged = o;
  own.edge_band = 0.0f;  // the face's own normals at hard corners everywhere
  averaged.cage = CageMode::averaged;
  std::size_t compared = 0, blended = 0, on_own = 0;
  for (int spp : {1, 4, 16, 64}) {
    SCOPED_TRACE(testing::Message() << name << ", " << spp << " spp, band " << edge_band);
    TexelSamples t;
    RasterStats raster_stats;
    rasterize(surface, spp == 64 ? width / 4 : width, spp == 64 ? height / 4 : height, spp, t, raster_stats);
    const std::vector<PacketRay> rays = packet_rays(surface, t, o);
    ASSERT_EQ(rays.size(), t.triangle.size());
    for (std::size_t i = 0; i < rays.size(); ++i) {
      ASSERT_EQ(rays[i].traced, t.triangle[i] >= 0) << "sample " << i;
      if (!rays[i].traced) continue;
      bool fallback = false;
      const Ray ray = make_ray(surface, t.triangle[i], t.bary[i], o, fallback);
      for (int k = 0; k < 3; ++k) {
        ASSERT_EQ(rays[i].origin[k], ray.origin[k]) << "sample " << i << ", triangle " << t.triangle[i];
        ASSERT_EQ(rays[i].direction[k], ray.direction[k]) << "sample " << i << ", triangle " << t.triangle[i];
      }
      ++compared;
      if (surface.hard_corners[static_cast<std::size_t>(t.triangle[i])] == 0) continue;
      const Ray f = make_ray(surface, t.triangle[i], t.bary[i], own, fallback);
      const Ray a = make_ray(surface, t.triangle[i], t.bary[i], averaged, fallback);
      const bool is_own = ray.direction == f.direction, is_averaged = ray.direction == a.direction;
      on_own += is_own ? 1 : 0;
      blended += !is_own && !is_averaged ? 1 : 0;
    }
  }
  SCOPED_TRACE(testing::Message() << name << ", band " << edge_band);
  EXPECT_GT(compared, 4000u);
  if (edge_band > 0.0f) {
    EXPECT_GT(blended, 500u);  // lanes in the smoothstep: the distance arithmetic counts
    if (beyond) {
      EXPECT_GT(on_own, 100u);  // lanes a band away
    }
  } else {
    EXPECT_EQ(blended, 0u);
  }
}

// The lab box turned about a skew axis: hard edges along no axis.
LowSurface turned_box_surface() {
  scenes::BoxParams p;
  p.low_cells = 3;
  p.high_cells = 8;
  Mesh low = scenes::make_box(p).low;
  const glm::vec3 axis = glm::normalize(glm::vec3(0.3f, -0.8f, 0.52f));
  const float c = std::cos(0.7f), s = std::sin(0.7f);
  const auto turn = [&](glm::vec3 v) {  // Rodrigues
    return v * c + glm::cross(axis, v) * s + axis * glm::dot(axis, v) * (1.0f - c);
  };
  for (glm::vec3& v : low.positions) v = turn(v) + glm::vec3(0.37f, -1.21f, 2.9f);
  for (glm::vec3& n : low.normals) n = turn(n);
  SurfaceStats stats;
  return build_low_surface(low, nullptr, stats);
}

LowSurface lab_low_surface(const std::string& name) {
  scenes::ScenePair pair;
  if (name == "panel") {
    scenes::PanelParams p = scenes::panel_params();
    p.high_cells = 16;
    pair = scenes::make_panel(p);
  } else {
    scenes::RevolveParams p = name == "bowl" ? scenes::bowl_params() : scenes::cylinder_params();
    p.high_segments = 32;
    p.high_step = 0.1;
    pair = scenes::make_revolved(p);
  }
  SurfaceStats stats;
  return build_low_surface(pair.low, nullptr, stats);
}

TEST(Trace, BandedPacketRaysEqualMakeRayBitForBit) {
  for (float band : {2.0f, 0.7f, 0.0f}) {
    check_banded_packets("box 3", box_surface(3), band, 61, 43);
    check_banded_packets("box 4", box_surface(4), band, 64, 40);
  }
  check_banded_packets("turned box", turned_box_surface(), 2.0f, 61, 43);
  check_banded_packets("turned box", turned_box_surface(), 0.7f, 59, 47);
  check_banded_packets("cylinder", lab_low_surface("cylinder"), 2.0f, 64, 64, false);
  check_banded_packets("panel", lab_low_surface("panel"), 2.0f, 64, 64, false);
  check_banded_packets("bowl", lab_low_surface("bowl"), 4.0f, 64, 64, false);
}

// A pit deeper than `back`: every ray misses, the retry (out and in up to
// its reach from the low surface) finds the floor; and it sees only its
// own bake group's triangles.
TEST(Trace, MissesAreRetriedWithinTheirGroup) {
  LowSurface s = low_quad();
  Mesh high;
  add_layer(high, -0.3f, false);  // group 0: the pit's floor
  add_layer(high, -0.2f, false);  // group 1: closer, but another group's
  pad_for_embree(high);
  const TexelSamples t = samples_at({{0.5f, 0.25f}, {0.9f, 0.1f}, {0.7f, 0.5f}});
  RayOptions o;
  o.front = 0.05f;
  o.back = 0.1f;
  for (bool grouped : {false, true}) {
    SCOPED_TRACE(grouped ? "grouped" : "one group");
    HighScene scene;
    SceneGroups groups;
    groups.first_triangle = {0, 2, 4};
    ASSERT_TRUE(HighScene::build(high, BuildQuality::low, false, scene, BvhMemory::automatic,
                                 grouped ? &groups : nullptr)
                    .is_ok());
    RayOptions ro = o;
    if (grouped) {
      s.group.assign(s.triangle_count(), 0);
      ro.groups = {{o.front, o.back}, {o.front, o.back}};
    } else {
      s.group.clear();
    }
    Hits hits;
    TraceStats stats;
    trace(scene, s, t, ro, hits, stats);
    EXPECT_EQ(stats.misses, 3u);
    EXPECT_EQ(stats.retried, 0u);
    ro.retry_reach = 1.0f;
    trace(scene, s, t, ro, hits, stats = TraceStats{});
    EXPECT_EQ(stats.misses, 0u);
    EXPECT_EQ(stats.hits, 3u);
    EXPECT_EQ(stats.retried, 3u);
    EXPECT_EQ(stats.retry_hits, 3u);
    EXPECT_EQ(stats.rays, 3u + 6u);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(hits.distance[i], grouped ? -0.3f : -0.2f, 1e-5f);
      EXPECT_EQ(hits.triangle[i] / 2, grouped ? 0 : 1);
    }
    // Out of reach: still a miss, counted once.
    ro.retry_reach = 0.15f;
    trace(scene, s, t, ro, hits, stats = TraceStats{});
    EXPECT_EQ(stats.misses, 3u);
    EXPECT_EQ(stats.retried, 3u);
    EXPECT_EQ(stats.retry_hits, 0u);
  }
}

}  // namespace
}  // namespace nmbake
