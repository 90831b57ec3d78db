// Unwrap: generated meshes (sphere, torus, box with hard edges, a noisy
// holed surface) and real ones from Debian's assimp-testmodels, checked for
// folds and overlaps (by the unwrapper's own measure and independently by
// the rasterizer), preserved geometry, hard edges as chart boundaries,
// determinism; plus the CLI and an auto-unwrapped bake scored against the
// analytic sphere.
#include "nmbake/unwrap.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <glm/geometric.hpp>
#include <map>

#include "nmbake/bake.hpp"
#include "nmbake/load.hpp"
#include "nmbake/raster.hpp"
#include "scenes.hpp"
#include "score.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

std::uint32_t hash32(std::uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

Mesh make_torus(int major_segments, int minor_segments, float major_radius, float minor_radius) {
  Mesh m;
  constexpr float kTau = 6.28318530717958647692f;
  for (int i = 0; i < major_segments; ++i) {
    for (int j = 0; j < minor_segments; ++j) {
      const float a = kTau * i / major_segments, b = kTau * j / minor_segments;
      const glm::vec3 centre(std::cos(a) * major_radius, std::sin(a) * major_radius, 0.0f);
      const glm::vec3 n(std::cos(a) * std::cos(b), std::sin(a) * std::cos(b), std::sin(b));
      m.positions.push_back(centre + minor_radius * n);
      m.normals.push_back(n);
    }
  }
  auto id = [&](int i, int j) {
    return static_cast<std::uint32_t>((i % major_segments) * minor_segments + (j % minor_segments));
  };
  for (int i = 0; i < major_segments; ++i)
    for (int j = 0; j < minor_segments; ++j)
      m.indices.insert(m.indices.end(),
                       {id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j), id(i + 1, j + 1), id(i, j + 1)});
  return m;
}

// A box with one normal per face: vertices split at the edges (hard edges).
Mesh make_hard_box(int cells, const glm::vec3& size) {
  Mesh m;
  for (int face = 0; face < 6; ++face) {
    const int axis = face / 2;
    const float sign = face % 2 == 0 ? 1.0f : -1.0f;
    glm::vec3 n(0.0f), u(0.0f), v(0.0f);
    n[axis] = sign;
    u[(axis + 1) % 3] = 1.0f;
    v[(axis + 2) % 3] = 1.0f;
    if (sign < 0.0f) std::swap(u, v);  // keep counter-clockwise seen from outside
    const std::uint32_t base = static_cast<std::uint32_t>(m.positions.size());
    for (int j = 0; j <= cells; ++j)
      for (int i = 0; i <= cells; ++i) {
        const glm::vec3 p = 0.5f * n + (static_cast<float>(i) / cells - 0.5f) * u +
                            (static_cast<float>(j) / cells - 0.5f) * v;
        m.positions.push_back(p * size);
        m.normals.push_back(n);
      }
    for (int j = 0; j < cells; ++j)
      for (int i = 0; i < cells; ++i) {
        const std::uint32_t a = base + j * (cells + 1) + i;
        m.indices.insert(m.indices.end(), {a, a + 1, a + cells + 2, a, a + cells + 2, a + cells + 1});
      }
  }
  return m;
}

// A bumpy grid, vertices jittered in the plane, diagonals chosen at random
// and about 8% of the triangles removed (holes, a ragged border): the kind of
// irregular surface a decimator leaves.
Mesh make_noisy_surface(int cells) {
  Mesh m;
  for (int j = 0; j <= cells; ++j)
    for (int i = 0; i <= cells; ++i) {
      const std::uint32_t h = hash32(static_cast<std::uint32_t>(j * 7919 + i));
      const float jx = ((h & 0xff) / 255.0f - 0.5f) * 0.6f, jy = (((h >> 8) & 0xff) / 255.0f - 0.5f) * 0.6f;
      const float x = (i + (i > 0 && i < cells ? jx : 0.0f)) / cells,
                  y = (j + (j > 0 && j < cells ? jy : 0.0f)) / cells;
      const float z =
          0.15f * std::sin(6.0f * x) * std::cos(5.0f * y) + 0.01f * (((h >> 16) & 0xff) / 255.0f - 0.5f);
      m.positions.emplace_back(x, y, z);
    }
  for (int j = 0; j < cells; ++j)
    for (int i = 0; i < cells; ++i) {
      const std::uint32_t a = j * (cells + 1) + i, b = a + 1, c = a + cells + 2, d = a + cells + 1;
      const std::uint32_t h = hash32(static_cast<std::uint32_t>(j * 104729 + i) + 17u);
      const std::uint32_t tris[2][3] = {{a, b, c}, {a, c, d}};
      const std::uint32_t flipped[2][3] = {{a, b, d}, {b, c, d}};
      for (int t = 0; t < 2; ++t) {
        if (((h >> (8 + t * 8)) & 0xff) < 20) continue;  // removed
        const auto& tri = (h & 1) ? flipped[t] : tris[t];
        m.indices.insert(m.indices.end(), tri, tri + 3);
      }
    }
  // Drop vertices no triangle uses (validate_mesh does not require it, but
  // the loader's meshes never have any).
  std::vector<std::int64_t> remap(m.positions.size(), -1);
  Mesh out;
  for (std::uint32_t& index : m.indices) {
    if (remap[index] < 0) {
      remap[index] = static_cast<std::int64_t>(out.positions.size());
      out.positions.push_back(m.positions[index]);
    }
    out.indices.push_back(static_cast<std::uint32_t>(remap[index]));
  }
  return out;
}

// Independent check by the bake's rasterizer: no sample inside two triangles.
RasterStats rasterize_uvs(const Mesh& mesh, int size) {
  LowSurface surface;
  for (std::uint32_t index : mesh.indices) surface.uv.push_back(mesh.uvs[index]);
  surface.position.resize(surface.uv.size());
  TexelSamples samples;
  RasterStats stats;
  rasterize(surface, size, size, 4, samples, stats);
  return stats;
}

// The checks every unwrap must pass; prints the figures.
UnwrapReport unwrap_and_check(const char* name, const Mesh& in, int size = 2048, int gutter = 4) {
  UnwrapOptions options;
  options.pack.resolution = size;
  options.pack.gutter = gutter;
  Mesh out;
  UnwrapReport report;
  const Status s = unwrap_mesh(in, options, out, report);
  EXPECT_TRUE(s.is_ok()) << name << ": " << s.message();
  if (!s) return report;
  std::printf("%-14s %s\n", name, report.summary_line().c_str());
  EXPECT_TRUE(validate_mesh(out, name).is_ok());
  EXPECT_EQ(report.flipped_triangles, 0u) << name;
  EXPECT_EQ(report.overlapping_triangles, 0u) << name;
  EXPECT_EQ(report.collapsed_triangles, 0u) << name;
  EXPECT_GT(report.utilization, 0.0);
  EXPECT_LE(report.utilization, 1.0);
  // Geometry preserved corner by corner, UVs in the unit square.
  EXPECT_EQ(out.triangle_count(), in.triangle_count());
  EXPECT_EQ(out.has_normals(), in.has_normals());
  std::size_t moved = 0, outside = 0;
  for (std::size_t c = 0; c < in.indices.size(); ++c) {
    if (out.positions[out.indices[c]] != in.positions[in.indices[c]]) ++moved;
    if (in.has_normals() && out.normals[out.indices[c]] != in.normals[in.indices[c]]) ++moved;
  }
  for (const glm::vec2& uv : out.uvs) {
    if (!(uv.x >= 0.0f && uv.x <= 1.0f && uv.y >= 0.0f && uv.y <= 1.0f)) ++outside;
  }
  EXPECT_EQ(moved, 0u) << name;
  EXPECT_EQ(outside, 0u) << name;
  const UvQuality quality = measure_uv_quality(out);
  EXPECT_EQ(quality.overlapping_triangles, 0u) << name;
  EXPECT_EQ(rasterize_uvs(out, 512).overlapping_samples, 0u) << name;
  return report;
}

TEST(Unwrap, SphereHasNoFoldsOrOverlaps) {
  const Mesh sphere = scenes::make_cube_sphere(
      16, [](const glm::vec3&) { return 1.0f; }, false, 0.0f);
  ASSERT_FALSE(sphere.has_uvs());
  const UnwrapReport r = unwrap_and_check("sphere", sphere);
  EXPECT_LE(r.stretch_l2, 1.15);
  EXPECT_GE(r.utilization, 0.70);  // issue 4 target (70.7% measured)
}

TEST(Unwrap, TorusHasNoFoldsOrOverlaps) {
  const UnwrapReport r = unwrap_and_check("torus", make_torus(64, 24, 1.0f, 0.35f));
  EXPECT_LE(r.stretch_l2, 1.15);
  EXPECT_GE(r.utilization, 0.74);  // issue 4 target 70% (75.2% measured)
}

TEST(Unwrap, HardEdgesAreChartBoundaries) {
  const Mesh box = make_hard_box(6, {1.0f, 2.0f, 0.5f});
  const UnwrapReport r = unwrap_and_check("hard box", box);
  EXPECT_EQ(r.boundary_edges_kept, 12u * 6u);  // 12 box edges of 6 segments
  EXPECT_EQ(r.chart_count, 6u);                // flat faces need no cut
  EXPECT_NEAR(r.stretch_l2, 1.0, 1e-3);        // and no stretch
  EXPECT_GE(r.utilization, 0.7);
  UnwrapOptions options;
  Mesh out;
  UnwrapReport again;
  ASSERT_TRUE(unwrap_mesh(box, options, out, again).is_ok());
  // A UV vertex shared by two triangles never crosses a hard edge.
  std::map<std::uint32_t, glm::vec3> normal_of_vertex;
  for (std::size_t t = 0; t < out.triangle_count(); ++t) {
    const glm::vec3 n = box.normals[box.indices[3 * t]];
    for (int k = 0; k < 3; ++k) {
      const auto [it, inserted] = normal_of_vertex.emplace(out.indices[3 * t + k], n);
      EXPECT_EQ(it->second, n) << "triangle " << t;
    }
  }
}

TEST(Unwrap, NoisyHoledSurfaceHasNoFoldsOrOverlaps) {
  const Mesh surface = make_noisy_surface(60);
  const UnwrapReport r = unwrap_and_check("noisy surface", surface);
  EXPECT_LE(r.stretch_l2, 1.15);
  EXPECT_GE(r.utilization, 0.70);  // issue 4 target (70.7% measured; the holes inside charts are lost)
}

TEST(Unwrap, ExistingUvSeamsAreKept) {
  // The sphere scene's low mesh has one UV chart per cube face: re-unwrapping
  // keeps those 6 cuts (and may add its own).
  scenes::SphereParams params;
  params.high_cells = 8;
  const scenes::ScenePair scene = scenes::make_displaced_sphere(params);
  const UnwrapReport r = unwrap_and_check("sphere re-uv", scene.low);
  EXPECT_GE(r.boundary_edges_kept, 12u * static_cast<unsigned>(params.low_cells));
  EXPECT_GE(r.chart_count, 6u);
  EXPECT_GE(r.utilization, 0.75);  // issue 4 target 70% (77.5% measured)
}

TEST(Unwrap, SameAtlasForAnyThreadCount) {
  const Mesh torus = make_torus(48, 20, 1.0f, 0.4f);
  UnwrapOptions options;
  options.pack.resolution = 1024;
  Mesh a, b;
  UnwrapReport ra, rb;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    ASSERT_TRUE(unwrap_mesh(torus, options, a, ra).is_ok());
  }
  ASSERT_TRUE(unwrap_mesh(torus, options, b, rb).is_ok());
  EXPECT_EQ(a.indices, b.indices);
  EXPECT_EQ(a.uvs, b.uvs);
  EXPECT_EQ(a.positions, b.positions);
}

TEST(Unwrap, DegenerateAndNonManifoldInputHasDefinedResults) {
  // Three triangles on one edge (non-manifold) plus a zero-area triangle.
  Mesh m;
  m.positions = {{0, 0, 0},    {1, 0, 0}, {0.5f, 1, 0}, {0.5f, -1, 0},
                 {0.5f, 0, 1}, {2, 0, 0}, {3, 0, 0},    {4, 0, 0}};
  m.indices = {0, 1, 2, 1, 0, 3, 0, 1, 4, 5, 6, 7};
  const UnwrapReport r = unwrap_and_check("degenerate", m, 256, 2);
  EXPECT_EQ(r.nonmanifold_faces, 1u);
  EXPECT_EQ(r.zero_area_triangles, 1u);
}

TEST(Unwrap, TooSmallAtlasIsReportedNotCrashed) {
  UnwrapOptions options;
  options.pack.resolution = 8;
  options.pack.gutter = 2;
  Mesh out;
  UnwrapReport r;
  Mesh islands;  // 100 separate triangles: 100 charts, at most 9 fit
  for (std::uint32_t i = 0; i < 100; ++i) {
    const float x = static_cast<float>(i) * 2.0f;
    islands.positions.insert(islands.positions.end(), {{x, 0, 0}, {x + 1, 0, 0}, {x, 1, 0}});
    islands.indices.insert(islands.indices.end(), {3 * i, 3 * i + 1, 3 * i + 2});
  }
  const Status s = unwrap_mesh(islands, options, out, r);
  EXPECT_EQ(s.code(), StatusCode::bad_input);
  EXPECT_NE(s.message().find("do not fit"), std::string::npos) << s.message();
}

// Real meshes from Debian's assimp-testmodels (tools/setup installs it), at
// the target size (2048², gutter 4) and, for the sanitizer build
// (which skips `Heavy`), at 1024², gutter 2.
void unwrap_assimp_models(int size, int gutter, double wuson_floor, double spider_floor) {
  const std::string root = "/usr/share/assimp/models/";
  if (!std::filesystem::exists(root)) GTEST_SKIP() << "assimp-testmodels is not installed (tools/setup)";
  for (const auto& [file, floor] :
       {std::pair{"OBJ/WusonOBJ.obj", wuson_floor}, std::pair{"OBJ/spider.obj", spider_floor}}) {
    Mesh mesh;
    LoadStats stats;
    // As `nmbake unwrap` loads it: the file's UV seams and hard edges are chart boundaries.
    const Status s = load_mesh(root + file, LoadOptions{true, true}, mesh, stats);
    ASSERT_TRUE(s.is_ok()) << s.message();
    const UnwrapReport r = unwrap_and_check(file, mesh, size, gutter);
    EXPECT_LE(r.stretch_l2, 1.15) << file;
    EXPECT_GE(r.utilization, floor) << file;
  }
}

// Measured: Wuson 81.3%, spider 70.4% (215 charts, most forced by the
// model's hard edges and UV seams).
TEST(Unwrap, AssimpTestModelsAtTargetSizeHeavy) { unwrap_assimp_models(2048, 4, 0.79, 0.70); }

// Measured: Wuson 80.3%, spider 68.7%.
// Release pass only (Heavy): 57 s there, 121 s under ASan, which the other
// Unwrap tests already take through the same code.
TEST(Unwrap, AssimpTestModelsHeavy) { unwrap_assimp_models(1024, 2, 0.79, 0.675); }

TEST(UnwrapCli, WritesMeshAndReport) {
  test::TempDir dir;
  ASSERT_TRUE(save_mesh(dir.file("torus.obj"), make_torus(32, 12, 1.0f, 0.3f)).is_ok());
  const auto r =
      test::run_command(test::cli_path() + " unwrap " + dir.file("torus.obj") + " -o " +
                        dir.file("torus_uv.ply") + " --size 512 --gutter 2 --report " + dir.file("r.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("charts"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("0 overlapping"), std::string::npos) << r.output;
  Mesh out;
  LoadStats stats;
  ASSERT_TRUE(load_mesh(dir.file("torus_uv.ply"), LoadOptions{}, out, stats).is_ok());
  EXPECT_TRUE(out.has_uvs());
  EXPECT_TRUE(std::filesystem::exists(dir.file("r.json")));
  const auto bad =
      test::run_command(test::cli_path() + " unwrap " + dir.file("missing.obj") + " -o " + dir.file("x.obj"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
}

// The displaced sphere baked from a low mesh without UVs: the auto-unwrapped
// mesh written beside the map scores within the core accuracy bounds.
TEST(UnwrapEndToEnd, AutoUnwrappedSphereMatchesAnalyticNormals) {
  test::TempDir dir;
  scenes::SphereParams params;
  params.high_cells = 192;
  scenes::ScenePair scene = scenes::make_displaced_sphere(params);
  // Strip the UVs (and the seams they made: weld the faces' copies back).
  Mesh bare = scenes::make_cube_sphere(
      params.low_cells, [&](const glm::vec3&) { return params.radius; }, false, 0.0f);
  ASSERT_FALSE(bare.has_uvs());
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), bare).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), scene.high).is_ok());

  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.ply")};
  o.outputs = {{dir.file("map.exr"), PixelFormat::exr_float}};
  o.width = o.height = 256;
  o.samples = 4;
  o.padding = 0;
  BakeReport report;
  const Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  EXPECT_TRUE(report.unwrapped);
  EXPECT_EQ(report.unwrapped_low_path, dir.file("map_low_uv.obj"));
  EXPECT_EQ(report.unwrap.overlapping_triangles, 0u);
  EXPECT_EQ(report.raster.overlapping_samples, 0u);
  EXPECT_EQ(report.trace.misses, 0u);
  EXPECT_NE(report.to_json().find("\"unwrap\""), std::string::npos);
  std::printf("%s\n", report.summary_line().c_str());

  Mesh low;
  LoadStats load_stats;
  ASSERT_TRUE(load_mesh(report.unwrapped_low_path, LoadOptions{}, low, load_stats).is_ok());
  ASSERT_TRUE(low.has_uvs() && low.has_normals());
  Image map;
  ASSERT_TRUE(read_image(dir.file("map.exr"), map).is_ok());
  const scenes::AngularError e = scenes::score_sphere(params, low, map, o.samples, report.front, report.back);
  std::printf("auto-unwrapped displaced sphere 256^2 x4: %s\n", e.to_text().c_str());
  EXPECT_GT(e.texels, 256u * 256u / 3u);
  EXPECT_EQ(e.non_finite, 0u);
  EXPECT_LT(e.mean, 0.1);
  EXPECT_LT(e.p99, 1.0);
}

}  // namespace
}  // namespace nmbake
