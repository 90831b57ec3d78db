// The high's normal textures in the normal bake (encode.hpp HighNormalMaps,
// src/maps/normal_maps.cpp): a bump held in a normal texture against the
// same bump modelled as geometry, the option's three words, determinism
// and the refusals.
//
// The scene: a flat low square [0, 1]^2 at z = 0 (UV = xy, so its tangent
// frame is x, y, z and a tangent-space texel is the world normal), under a
// high that covers [-0.1, 1.1]^2 with UV = xy too. The bump is
// h(x, y) = A sin(2 pi f x) cos(2 pi f y), periodic over the UV square so
// the texture may repeat. Textured: a flat 16 x 16 grid at z = 0.002 whose
// MTL names a 16-bit normal texture holding normalize(-dh/dx, -dh/dy, 1)
// (+Y up). Geometry: a 384 x 384 grid displaced by h, its normals computed
// by the loader (area-weighted). Rays run along z, so both bakes see the
// normal at the same (x, y).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <iterator>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>

#include "nmbake/bake.hpp"
#include "nmbake/image.hpp"
#include "nmbake/load.hpp"
#include "nmbake/task.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kAmplitude = 0.01, kFrequency = 2.0;

double bump(double x, double y) {
  return kAmplitude * std::sin(2 * kPi * kFrequency * x) * std::cos(2 * kPi * kFrequency * y);
}
glm::dvec3 bump_normal(double x, double y) {
  const double k = 2 * kPi * kFrequency;
  const double hx = kAmplitude * k * std::cos(k * x) * std::cos(k * y);
  const double hy = -kAmplitude * k * std::sin(k * x) * std::sin(k * y);
  return glm::normalize(glm::dvec3(-hx, -hy, 1.0));
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// A grid over [-0.1, 1.1]^2 of n x n cells at z = offset + (displaced ? h : 0), UV = xy.
Mesh grid(int n, bool displaced, float offset) {
  Mesh m;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const double x = -0.1 + 1.2 * i / n, y = -0.1 + 1.2 * j / n;
      m.positions.emplace_back(x, y, offset + (displaced ? bump(x, y) : 0.0));
      m.uvs.emplace_back(x, y);
    }
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const auto v = static_cast<std::uint32_t>(j * (n + 1) + i);
      const auto w = static_cast<std::uint32_t>(n + 1);
      for (const std::uint32_t k : {v, v + 1, v + w + 1, v, v + w + 1, v + w}) m.indices.push_back(k);
    }
  }
  m.materials = {{"skin", 0, static_cast<std::uint32_t>(m.triangle_count())}};
  return m;
}

Mesh low_square() {
  Mesh m;
  for (int k = 0; k < 4; ++k) {
    const float x = static_cast<float>(k == 1 || k == 2), y = static_cast<float>(k >= 2);
    m.positions.emplace_back(x, y, 0.0f);
    m.normals.emplace_back(0.0f, 0.0f, 1.0f);
    m.uvs.emplace_back(x, y);
  }
  m.indices = {0, 1, 2, 0, 2, 3};
  return m;
}

// The bump's normals as an n x n 16-bit PNG (rgb = 0.5 n + 0.5, +Y up, row 0 the top).
void write_normal_texture(const std::string& path, int n) {
  Image image;
  image.width = image.height = n;
  image.channels = 3;
  image.pixels.resize(static_cast<std::size_t>(n) * n * 3);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const glm::dvec3 t = bump_normal((i + 0.5) / n, 1.0 - (j + 0.5) / n);
      for (int c = 0; c < 3; ++c) image.at(i, j)[c] = static_cast<float>(0.5 * t[c] + 0.5);
    }
  }
  ASSERT_TRUE(write_image(image, path, PixelFormat::png16).is_ok());
}

// low.obj; textured.obj (+ .mtl naming `mtl_body`, e.g. "norm bump.png\n");
// bump.png; geometry.obj.
void write_scene(const test::TempDir& dir, const std::string& mtl_body) {
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), low_square()).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("textured.obj"), grid(16, false, 0.002f)).is_ok());
  test::write_text(dir.file("textured.obj"), "mtllib textured.mtl\n" + read_bytes(dir.file("textured.obj")));
  test::write_text(dir.file("textured.mtl"), "newmtl skin\nKd 0.8 0.8 0.8\n" + mtl_body);
  write_normal_texture(dir.file("bump.png"), 512);
}

BakeOptions normal_bake(const test::TempDir& dir, const std::string& high, const std::string& out) {
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file(high)};
  o.width = o.height = 128;
  o.samples = 4;
  o.padding = 0;
  o.rays.front = Distance{Distance::Kind::absolute, 0.05f};
  o.rays.back = Distance{Distance::Kind::absolute, 0.05f};
  o.outputs = {{dir.file(out), out.ends_with(".exr") ? PixelFormat::exr_float : PixelFormat::png16}};
  return o;
}

Status bake_to(const BakeOptions& o, BakeReport& report) { return bake(o, report); }

// Decoded normals of a float map (tangent space = world here).
glm::dvec3 texel_normal(const Image& map, int x, int y) {
  const float* p = map.at(x, y);
  return glm::normalize(glm::dvec3(2.0 * p[0] - 1.0, 2.0 * p[1] - 1.0, 2.0 * p[2] - 1.0));
}

TEST(HighNormalMaps, NormalTextureMatchesTheBumpModelledAsGeometry) {
  test::TempDir dir;
  write_scene(dir, "norm bump.png\n");
  ASSERT_TRUE(save_mesh(dir.file("geometry.obj"), grid(384, true, 0.0f)).is_ok());
  BakeReport textured_report, geometry_report;
  Status s = bake_to(normal_bake(dir, "textured.obj", "textured.exr"), textured_report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  s = bake_to(normal_bake(dir, "geometry.obj", "geometry.exr"), geometry_report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  EXPECT_TRUE(textured_report.high_normal_maps);
  EXPECT_FALSE(geometry_report.high_normal_maps);
  EXPECT_EQ(textured_report.high_normal_textures, 1u);
  EXPECT_EQ(textured_report.encode.high_normal_map_samples, 128u * 128u * 4u);
  EXPECT_EQ(textured_report.encode.high_normal_map_no_uv +
                textured_report.encode.high_normal_map_zero_normal +
                textured_report.encode.high_normal_map_degenerate_tangent +
                textured_report.encode.high_normal_map_tile_missing,
            0u);
  EXPECT_EQ(textured_report.trace.misses, 0u);
  EXPECT_EQ(textured_report.raster.covered_texels, 128u * 128u);
  Image textured, geometry;
  ASSERT_TRUE(read_image(dir.file("textured.exr"), textured).is_ok());
  ASSERT_TRUE(read_image(dir.file("geometry.exr"), geometry).is_ok());
  double sum = 0.0, largest = 0.0, bump_sum = 0.0;
  for (int y = 0; y < 128; ++y) {
    for (int x = 0; x < 128; ++x) {
      const glm::dvec3 a = texel_normal(textured, x, y), b = texel_normal(geometry, x, y);
      const double degrees = std::acos(std::clamp(glm::dot(a, b), -1.0, 1.0)) * 180.0 / kPi;
      sum += degrees;
      largest = std::max(largest, degrees);
      bump_sum += std::acos(std::clamp(b.z, -1.0, 1.0)) * 180.0 / kPi;
    }
  }
  const double mean = sum / (128.0 * 128.0);
  std::printf("normal texture vs geometry: mean %.4f deg, max %.4f deg (the bump itself: mean %.2f deg)\n",
              mean, largest, bump_sum / (128.0 * 128.0));
  // Measured: mean 0.0020 deg, max 0.0033 deg; the bump tilts the normal by 4.86 deg on average.
  EXPECT_LT(mean, 0.5);
  EXPECT_LT(largest, 1.0);
  EXPECT_GT(bump_sum / (128.0 * 128.0), 2.0);  // the bump is there to be matched
}

TEST(HighNormalMaps, OffAutoAndOn) {
  test::TempDir dir;
  write_scene(dir, "norm bump.png\n");
  BakeReport report;
  BakeOptions o = normal_bake(dir, "textured.obj", "auto.png");
  ASSERT_TRUE(bake_to(o, report).is_ok());
  EXPECT_TRUE(report.high_normal_maps);
  o = normal_bake(dir, "textured.obj", "on.png");
  o.high_normal_maps = HighNormalMaps::on;
  ASSERT_TRUE(bake_to(o, report).is_ok());
  o = normal_bake(dir, "textured.obj", "off.png");
  o.high_normal_maps = HighNormalMaps::off;
  ASSERT_TRUE(bake_to(o, report).is_ok());
  EXPECT_FALSE(report.high_normal_maps);
  EXPECT_EQ(report.encode.high_normal_map_samples, 0u);
  EXPECT_EQ(read_bytes(dir.file("auto.png")), read_bytes(dir.file("on.png")));
  EXPECT_NE(read_bytes(dir.file("off.png")), read_bytes(dir.file("on.png")));
  // Off: the flat high, (0, 0, 1) everywhere.
  Image off;
  ASSERT_TRUE(read_image(dir.file("off.png"), off).is_ok());
  for (std::size_t i = 0; i < off.pixels.size(); i += 3) {
    ASSERT_NEAR(off.pixels[i], 0.5f, 1e-4f);
    ASSERT_NEAR(off.pixels[i + 2], 1.0f, 1e-4f);
  }
}

// auto on a high whose materials have no normal texture, and on one without
// any material library (or with one that is missing): the bytes of off.
TEST(HighNormalMaps, AutoWithoutNormalTexturesGivesTheBytesOfOff) {
  test::TempDir dir;
  write_scene(dir, "map_Kd bump.png\n");  // a texture, but no normal texture
  ASSERT_TRUE(save_mesh(dir.file("geometry.obj"), grid(64, true, 0.0f)).is_ok());
  test::write_text(dir.file("geometry_lost.obj"), "mtllib lost.mtl\n" + read_bytes(dir.file("geometry.obj")));
  for (const char* high : {"textured.obj", "geometry.obj", "geometry_lost.obj"}) {
    BakeReport report;
    BakeOptions o = normal_bake(dir, high, "auto.png");
    Status s = bake_to(o, report);
    ASSERT_TRUE(s.is_ok()) << high << ": " << s.message();
    EXPECT_FALSE(report.high_normal_maps);
    EXPECT_EQ(report.high_load.unread_material_libraries, std::string(high) == "geometry_lost.obj" ? 1u : 0u);
    EXPECT_EQ(report.to_json().find("\"high_normal_maps\"") != std::string::npos,
              std::string(high) == "geometry_lost.obj");
    o = normal_bake(dir, high, "off.png");
    o.high_normal_maps = HighNormalMaps::off;
    ASSERT_TRUE(bake_to(o, report).is_ok());
    EXPECT_EQ(read_bytes(dir.file("auto.png")), read_bytes(dir.file("off.png"))) << high;
  }
}

TEST(HighNormalMaps, OneThreadTwoAndMergedTilesGiveTheSameBytes) {
  test::TempDir dir;
  write_scene(dir, "norm bump.png\n");
  for (const int threads : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(threads));
    BakeReport report;
    const Status s =
        bake_to(normal_bake(dir, "textured.obj", "t" + std::to_string(threads) + ".png"), report);
    ASSERT_TRUE(s.is_ok()) << s.message();
  }
  const std::string one = read_bytes(dir.file("t1.png"));
  EXPECT_FALSE(one.empty());
  EXPECT_EQ(one, read_bytes(dir.file("t2.png")));
  // Tiles of rows, merged: the same bytes.
  const Status s = test::bake_tiles_and_merge(normal_bake(dir, "textured.obj", "t1.png"), 3, dir.path(),
                                              {{dir.file("merged.png"), PixelFormat::png16}});
  ASSERT_TRUE(s.is_ok()) << s.message();
  EXPECT_TRUE(one == read_bytes(dir.file("merged.png")));
}

// glTF's normalTexture.scale multiplies x and y of the texture's normal: a
// scale of 0 is the flat high's (0, 0, 1).
TEST(HighNormalMaps, GltfScaleAppliesToXAndY) {
  test::TempDir dir;
  write_scene(dir, "");
  ASSERT_TRUE(save_mesh(dir.file("high.gltf"), grid(16, false, 0.002f)).is_ok());
  nlohmann::json doc = nlohmann::json::parse(read_bytes(dir.file("high.gltf")));
  doc["images"] = {{{"uri", "bump.png"}}};
  doc["textures"] = {{{"source", 0}}};
  ASSERT_EQ(doc["materials"].size(), 1u);  // "skin", written by save_mesh
  doc["materials"][0]["normalTexture"] = {{"index", 0}, {"scale", 0.0}};
  test::write_text(dir.file("high.gltf"), doc.dump());
  BakeReport report;
  Status s = bake_to(normal_bake(dir, "high.gltf", "flat.exr"), report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  EXPECT_TRUE(report.high_normal_maps);
  Image flat;
  ASSERT_TRUE(read_image(dir.file("flat.exr"), flat).is_ok());
  for (std::size_t i = 0; i < flat.pixels.size(); i += 3) {
    ASSERT_NEAR(flat.pixels[i], 0.5f, 1e-5f);
    ASSERT_NEAR(flat.pixels[i + 1], 0.5f, 1e-5f);
  }
  doc["materials"][0]["normalTexture"]["scale"] = 1.0;
  test::write_text(dir.file("high.gltf"), doc.dump());
  s = bake_to(normal_bake(dir, "high.gltf", "bumpy.exr"), report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  Image bumpy;
  ASSERT_TRUE(read_image(dir.file("bumpy.exr"), bumpy).is_ok());
  // Texel (x, y) at UV ((x + 0.5) / 128, 1 - (y + 0.5) / 128): the bump's normal there.
  double largest = 0.0;
  for (int y = 0; y < 128; ++y) {
    for (int x = 0; x < 128; ++x) {
      const glm::dvec3 a = texel_normal(bumpy, x, y);
      const glm::dvec3 b = bump_normal((x + 0.5) / 128, 1.0 - (y + 0.5) / 128);
      largest = std::max(largest, std::acos(std::clamp(glm::dot(a, b), -1.0, 1.0)) * 180.0 / kPi);
    }
  }
  EXPECT_LT(largest, 0.5);
}

// A normal texture that is not there: exit 2 naming the high file, the
// material and the path, before anything is baked; nothing written.
TEST(HighNormalMaps, MissingNormalTextureIsExitTwoNamingMaterialAndPath) {
  test::TempDir dir;
  write_scene(dir, "norm textures/gone.png\n");
  const test::CommandResult r =
      test::run_command(test::cli_path() + " bake --low " + dir.file("low.obj") + " --high " +
                        dir.file("textured.obj") + " --size 32 -o " + dir.file("out.png") + " 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("textured.obj"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("material 'skin'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("normal texture"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("gone.png"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir.file("out.png")));
  // off does not read it.
  const test::CommandResult off = test::run_command(
      test::cli_path() + " bake --low " + dir.file("low.obj") + " --high " + dir.file("textured.obj") +
      " --size 32 --high-normal-maps off -o " + dir.file("out.png") + " 2>&1");
  EXPECT_EQ(off.exit_code, 0) << off.output;
}

// Triangles without UV area (their corners' UVs collapsed): counted, and
// their texels keep the geometry's normal, bit for bit the texels of off
// (encoded one sample at a time beside perturbed ones, against the SIMD lanes).
TEST(HighNormalMaps, TrianglesWithoutUvsKeepTheGeometrysNormalAndAreCounted) {
  test::TempDir dir;
  write_scene(dir, "norm bump.png\n");
  Mesh high = grid(16, true, 0.0f);
  for (std::size_t v = 0; v < high.positions.size(); ++v) {
    if (high.positions[v].x < 0.45f) high.uvs[v] = glm::vec2(0.25f, 0.25f);
  }
  ASSERT_TRUE(save_mesh(dir.file("collapsed.obj"), high).is_ok());
  test::write_text(dir.file("collapsed.obj"),
                   "mtllib textured.mtl\n" + read_bytes(dir.file("collapsed.obj")));
  BakeReport report;
  ASSERT_TRUE(bake_to(normal_bake(dir, "collapsed.obj", "on.exr"), report).is_ok());
  EXPECT_TRUE(report.high_normal_maps);
  EXPECT_GT(report.encode.high_normal_map_no_uv, 128u * 40u * 4u);
  EXPECT_LT(report.encode.high_normal_map_no_uv, report.encode.high_normal_map_samples);
  EXPECT_GT(report.high_tangents.degenerate_uv_triangles, 0u);
  const nlohmann::json j = nlohmann::json::parse(report.to_json());
  EXPECT_EQ(j["fallbacks"]["high_normal_map_no_uv"].get<std::uint64_t>(),
            report.encode.high_normal_map_no_uv);
  EXPECT_NE(report.summary_line().find("high normal maps of 1 material"), std::string::npos);
  BakeOptions o = normal_bake(dir, "collapsed.obj", "off.exr");
  o.high_normal_maps = HighNormalMaps::off;
  ASSERT_TRUE(bake_to(o, report).is_ok());
  Image on, off;
  ASSERT_TRUE(read_image(dir.file("on.exr"), on).is_ok());
  ASSERT_TRUE(read_image(dir.file("off.exr"), off).is_ok());
  std::size_t same = 0, differ = 0;
  for (int y = 0; y < 128; ++y) {
    for (int x = 0; x < 128; ++x) {
      const bool equal = std::equal(on.at(x, y), on.at(x, y) + 3, off.at(x, y));
      if (x < 40) {
        EXPECT_TRUE(equal) << x << " " << y;  // x < 0.31: every sample on a collapsed triangle
      }
      (equal ? same : differ) += 1;
    }
  }
  EXPECT_GT(differ, 128u * 60u);  // the textured half is perturbed
  EXPECT_GE(same, 128u * 40u);
}

// Adaptive sampling encodes outside the map set and does not read them
// yet: auto bakes the geometry and says how many it left out; on is refused.
TEST(HighNormalMaps, AdaptiveSamplingLeavesThemOutOrRefusesOn) {
  test::TempDir dir;
  write_scene(dir, "norm bump.png\n");
  BakeOptions o = normal_bake(dir, "textured.obj", "adaptive.png");
  o.adaptive = true;
  BakeReport report;
  Status s = bake_to(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  EXPECT_FALSE(report.high_normal_maps);
  EXPECT_EQ(report.high_normal_textures_skipped, 1u);
  EXPECT_NE(report.summary_line().find("1 high normal texture not read"), std::string::npos);
  o.high_normal_maps = HighNormalMaps::on;
  s = bake_to(o, report);
  ASSERT_FALSE(s.is_ok());
  EXPECT_EQ(s.code(), StatusCode::bad_input);
  EXPECT_NE(s.message().find("adaptive"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace nmbake
