// Texture transfer (maps.hpp: base-color, roughness, metallic, emissive,
// opacity; textures.hpp): the high's textures carried onto the low's UVs,
// against analytic answers.
//
// The scene: a bumpy high heightfield whose UVs are its (x, y) scaled to
// [0, 1]^2, textured with known smooth functions g(s, t) (written by the test
// as 8- and 16-bit PNGs, sRGB-encoded), under a flat low of four charts laid
// out differently (straight, rotated 90 degrees, mirrored, rotated 180
// degrees). The rays run along z, so a low point (x, y) hits the high at the
// same (x, y): the expected texel is the mean of g over its samples' points.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>
#include <string>

#include "fbx_write.hpp"
#include "map_lab.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/image.hpp"
#include "nmbake/load.hpp"
#include "nmbake/task.hpp"
#include "nmbake/textures.hpp"
#include "scenes.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

constexpr double kPi = std::numbers::pi;

// The texture's linear values at UV (s, t), t up.
double red(double s, double t) { return 0.5 + 0.35 * std::sin(2 * kPi * s) * std::cos(2 * kPi * t); }
double green(double s, double t) { return 0.45 + 0.3 * std::cos(2 * kPi * (s + 0.5 * t)); }
double blue(double, double) { return 0.25; }
// Their largest second derivative along s or t.
constexpr double kMaxSecond = 0.35 * 4 * kPi * kPi;

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// An n x n texture of g, stored sRGB-encoded (a colour texture) or linear.
Image texture_image(int n, bool srgb) {
  Image image;
  image.width = image.height = n;
  image.channels = 3;
  image.pixels.resize(static_cast<std::size_t>(n) * n * 3);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double s = (i + 0.5) / n, t = 1.0 - (j + 0.5) / n;  // row 0 is the top
      const double v[3] = {red(s, t), green(s, t), blue(s, t)};
      for (int c = 0; c < 3; ++c) {
        const auto f = static_cast<float>(v[c]);
        image.at(i, j)[c] = srgb ? linear_to_srgb(f) : f;
      }
    }
  }
  return image;
}

struct TransferScene {
  Mesh low, high;
  float min_x = 0, min_y = 0, side = 1;
  glm::dvec2 uv_of(const glm::dvec3& p) const { return {(p.x - min_x) / side, (p.y - min_y) / side}; }
};

// The high heightfield with UVs from (x, y); a flat low at z = 0 in four
// charts, one per quadrant of the square, each laid out its own way.
TransferScene make_scene() {
  scenes::HeightfieldParams params;
  params.high_cells = 96;
  params.amplitude = 0.01f;
  scenes::ScenePair pair = scenes::make_heightfield(params);
  TransferScene scene;
  scene.high = std::move(pair.high);
  const Bounds b = compute_bounds(scene.high);
  scene.min_x = b.min.x;
  scene.min_y = b.min.y;
  scene.side = b.max.x - b.min.x;
  for (const glm::vec3& p : scene.high.positions) {
    scene.high.uvs.emplace_back((p.x - scene.min_x) / scene.side, (p.y - scene.min_y) / scene.side);
  }
  scene.high.materials = {{"scan", 0, static_cast<std::uint32_t>(scene.high.triangle_count())}};

  // Inset from the high's edge, so that every ray (border samples too) hits.
  Mesh& low = scene.low;
  const float inset = 0.05f * scene.side;
  const float h = (scene.side - 2 * inset) / 2;
  for (int q = 0; q < 4; ++q) {
    const float x0 = scene.min_x + inset + h * static_cast<float>(q % 2);
    const float y0 = scene.min_y + inset + h * static_cast<float>(q / 2);
    const auto base = static_cast<std::uint32_t>(low.positions.size());
    for (int k = 0; k < 4; ++k) {
      const float a = static_cast<float>(k == 1 || k == 2), c = static_cast<float>(k >= 2);  // corner (a, c)
      low.positions.emplace_back(x0 + h * a, y0 + h * c, 0.0f);
      low.normals.emplace_back(0.0f, 0.0f, 1.0f);
      // The chart's corner in its own square of the atlas (0.05 + 0.4 * ...).
      float u = a, v = c;
      if (q == 1) {  // rotated 90 degrees
        u = 1 - c;
        v = a;
      } else if (q == 2) {  // mirrored
        u = 1 - a;
      } else if (q == 3) {  // rotated 180 degrees
        u = 1 - a;
        v = 1 - c;
      }
      const float cu = 0.5f * static_cast<float>(q % 2), cv = 0.5f * static_cast<float>(q / 2);
      low.uvs.emplace_back(cu + 0.05f + 0.4f * u, cv + 0.05f + 0.4f * v);
    }
    for (const std::uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) low.indices.push_back(base + i);
  }
  return scene;
}

void write_scene(const test::TempDir& dir, const TransferScene& scene, const std::string& texture) {
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.obj"), scene.high).is_ok());
  test::write_text(dir.file("high.obj"), "mtllib high.mtl\n" + read_bytes(dir.file("high.obj")));
  test::write_text(dir.file("high.mtl"), "newmtl scan\nKd 0.8 0.8 0.8\nPr 0.6\nmap_Kd " + texture + "\n");
}

BakeOptions transfer_bake(const test::TempDir& dir, int size) {
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.obj")};
  o.width = o.height = size;
  o.samples = 4;
  o.padding = 0;
  o.maps = {MapKind::base_color, MapKind::roughness};
  o.outputs = {{dir.file("m_<MAP>.exr"), PixelFormat::exr_float}};
  return o;
}

// The largest and mean |baked - expected| of channel c over the covered texels.
scenes::MapError score(const test::TempDir& dir, const TransferScene& scene, int size, int c) {
  Image map;
  EXPECT_TRUE(read_image(dir.file("m_base-color.exr"), map).is_ok());
  const auto g = [&](const glm::dvec3& p) {
    const glm::dvec2 uv = scene.uv_of(p);
    return c == 0 ? red(uv.x, uv.y) : c == 1 ? green(uv.x, uv.y) : blue(uv.x, uv.y);
  };
  return scenes::score_map(map, c, scenes::expected_from_low_points(scene.low, size, size, 4, g));
}

// The bound of textures.hpp for this scene: a filter no wider than twice the
// larger of the sample's footprint w and the texture's texel T (trilinear
// blends toward the next level), per axis (w'^2 + T'^2) max|g''| / 8, two
// axes; plus the storage's rounding: half a step of the stored sRGB value,
// times the largest slope of the sRGB decoding, 2.4 / 1.055 (at 1).
double filter_bound(int map_size, int texture_size, int bits) {
  const double w =
      (0.45 / (0.4 * map_size)) / 2.0;  // UV per sample: a chart is 0.45 wide over 0.4 of the map
  const double t = 1.0 / texture_size;
  const double filter = 2 * (std::pow(2 * w, 2) + std::pow(2 * t, 2)) * kMaxSecond / 8;
  const double rounding = 2.4 / 1.055 * 0.5 / (bits == 16 ? 65535 : 255);
  return filter + rounding;
}

TEST(Transfer, BaseColourMatchesTheAnalyticTextureOnEveryChartLayout) {
  const TransferScene scene = make_scene();
  for (const int bits : {16, 8}) {
    test::TempDir dir;
    const Image texture = texture_image(256, true);
    ASSERT_TRUE(
        write_image(texture, dir.file("albedo.png"), bits == 16 ? PixelFormat::png16 : PixelFormat::png8)
            .is_ok());
    write_scene(dir, scene, "albedo.png");
    BakeReport report;
    const Status s = bake(transfer_bake(dir, 128), report);
    ASSERT_TRUE(s.is_ok()) << s.message();
    const double bound = filter_bound(128, 256, bits);
    for (int c = 0; c < 3; ++c) {
      const scenes::MapError e = score(dir, scene, 128, c);
      EXPECT_GT(e.texels, 4u * 50u * 50u);
      EXPECT_LT(e.max, bound) << bits << "-bit, channel " << c << ": " << e.to_text();
      std::printf("%d-bit texture, channel %d: %s (bound %.2e)\n", bits, c, e.to_text().c_str(), bound);
    }
    // Roughness: Pr alone (no map_Pr), every sample counted as factor-only.
    Image roughness;
    ASSERT_TRUE(read_image(dir.file("m_roughness.exr"), roughness).is_ok());
    for (float v : roughness.pixels) ASSERT_TRUE(v == 0.6f || v == 0.0f) << v;
    bool counted = false;
    for (const MapReport& m : report.map_reports) {
      if (m.map == MapKind::roughness) counted = m.figure("factor_only_samples") > 0;
      if (m.map == MapKind::base_color) {
        EXPECT_EQ(m.figure("factor_only_samples"), 0);
      }
    }
    EXPECT_TRUE(counted);
  }
}

// UDIM textures: the high's UVs moved one tile right (1002), the MTL naming
// `albedo.<UDIM>.png`; the same errors as one texture.
TEST(Transfer, UdimTexturesAreReadPerTile) {
  TransferScene scene = make_scene();
  for (glm::vec2& uv : scene.high.uvs) uv.x += 1.0f;
  test::TempDir dir;
  ASSERT_TRUE(write_image(texture_image(256, true), dir.file("albedo.1002.png"), PixelFormat::png16).is_ok());
  write_scene(dir, scene, "albedo.<UDIM>.png");
  BakeReport report;
  const Status s = bake(transfer_bake(dir, 128), report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  for (int c = 0; c < 3; ++c) {
    const scenes::MapError e = score(dir, scene, 128, c);
    EXPECT_LT(e.max, filter_bound(128, 256, 16)) << e.to_text();
  }
  for (const MapReport& m : report.map_reports) {
    if (m.map == MapKind::base_color) {
      EXPECT_EQ(m.figure("missing_tile_samples"), 0);
    }
  }
}

// glTF: baseColorFactor times a texture placed by KHR_texture_transform
// (rotated a quarter turn, scaled by one half, offset), metallicRoughness's
// G and B channels for roughness and metallic, the sampler's wrap mode.
TEST(Transfer, GltfFactorsAndTextureTransform) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.gltf"), scene.high).is_ok());
  // The transform t = offset + R(rotation) (scale uv) in glTF's top-left UVs;
  // the image holds g at the inverse, so the bake must undo it exactly.
  // [0, 1]^2 lands on [0.25, 0.75]^2 of the image (roughness is not periodic).
  const double rotation = kPi / 2, scale = 0.5, ox = 0.25, oy = 0.75;
  const int n = 512;
  Image texture;
  texture.width = texture.height = n;
  texture.channels = 3;
  texture.pixels.resize(static_cast<std::size_t>(n) * n * 3);
  Image mr = texture;  // metallicRoughness: G = roughness 0.3 + 0.2 s, B = metallic 0.9
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double tx = (i + 0.5) / n - ox, ty = (j + 0.5) / n - oy;
      const double c = std::cos(rotation), sn = std::sin(rotation);
      // R^-1 = R^T: [c -s; s c]
      const double ux = (c * tx - sn * ty) / scale, uy = (sn * tx + c * ty) / scale;
      const double s_ = ux, t_ = 1.0 - uy;
      const double v[3] = {red(s_, t_), green(s_, t_), blue(s_, t_)};
      for (int k = 0; k < 3; ++k) texture.at(i, j)[k] = linear_to_srgb(static_cast<float>(v[k]));
      mr.at(i, j)[0] = 0.0f;
      mr.at(i, j)[1] = static_cast<float>(0.3 + 0.2 * std::clamp(s_, 0.0, 1.0));
      mr.at(i, j)[2] = 0.9f;
    }
  }
  ASSERT_TRUE(write_image(texture, dir.file("albedo.png"), PixelFormat::png16).is_ok());
  ASSERT_TRUE(write_image(mr, dir.file("mr.png"), PixelFormat::png16).is_ok());
  nlohmann::json doc = nlohmann::json::parse(read_bytes(dir.file("high.gltf")));
  nlohmann::json transform = {{"offset", {ox, oy}}, {"rotation", rotation}, {"scale", {scale, scale}}};
  doc["extensionsUsed"] = {"KHR_texture_transform"};
  doc["images"] = {{{"uri", "albedo.png"}}, {{"uri", "mr.png"}}};
  doc["samplers"] = {{{"wrapS", 10497}, {"wrapT", 10497}}};
  doc["textures"] = {{{"source", 0}, {"sampler", 0}}, {{"source", 1}, {"sampler", 0}}};
  doc["materials"][0]["pbrMetallicRoughness"] = {
      {"baseColorFactor", {0.5, 1.0, 1.0, 1.0}},
      {"baseColorTexture", {{"index", 0}, {"extensions", {{"KHR_texture_transform", transform}}}}},
      {"metallicRoughnessTexture", {{"index", 1}, {"extensions", {{"KHR_texture_transform", transform}}}}},
      {"roughnessFactor", 1.0},
      {"metallicFactor", 0.5}};
  test::write_text(dir.file("high.gltf"), doc.dump());
  BakeOptions o = transfer_bake(dir, 128);
  o.high_paths = {dir.file("high.gltf")};
  o.maps = {MapKind::base_color, MapKind::roughness, MapKind::metallic};
  BakeReport report;
  const Status st = bake(o, report);
  ASSERT_TRUE(st.is_ok()) << st.message();
  Image base, rough, metal;
  ASSERT_TRUE(read_image(dir.file("m_base-color.exr"), base).is_ok());
  ASSERT_TRUE(read_image(dir.file("m_roughness.exr"), rough).is_ok());
  ASSERT_TRUE(read_image(dir.file("m_metallic.exr"), metal).is_ok());
  const double bound = filter_bound(128, n / 2, 16);
  for (int c = 0; c < 3; ++c) {
    const auto g = [&](const glm::dvec3& p) {
      const glm::dvec2 uv = scene.uv_of(p);
      const double factor = c == 0 ? 0.5 : 1.0;
      return factor * (c == 0 ? red(uv.x, uv.y) : c == 1 ? green(uv.x, uv.y) : blue(uv.x, uv.y));
    };
    const scenes::MapError e =
        scenes::score_map(base, c, scenes::expected_from_low_points(scene.low, 128, 128, 4, g));
    EXPECT_GT(e.texels, 4u * 50u * 50u);
    EXPECT_LT(e.max, bound) << "channel " << c << ": " << e.to_text();
  }
  const scenes::MapError r = scenes::score_map(
      rough, 0, scenes::expected_from_low_points(scene.low, 128, 128, 4, [&](const glm::dvec3& p) {
        return 0.3 + 0.2 * scene.uv_of(p).x;
      }));
  EXPECT_LT(r.max, 2e-4) << r.to_text();
  const scenes::MapError m = scenes::score_map(
      metal, 0,
      scenes::expected_from_low_points(scene.low, 128, 128, 4, [](const glm::dvec3&) { return 0.45; }));
  EXPECT_LT(m.max, 1e-4) << m.to_text();
}

// The transfer scene with its high in four material ranges named `names`
// (a quarter each), written as dir/low.obj and dir/high.obj.
void write_four_material_scene(const test::TempDir& dir, const std::array<std::string, 4>& names) {
  TransferScene scene = make_scene();
  const auto n = static_cast<std::uint32_t>(scene.high.triangle_count());
  const std::uint32_t q = n / 4;
  scene.high.materials = {
      {names[0], 0, q}, {names[1], q, q}, {names[2], 2 * q, q}, {names[3], 3 * q, n - 3 * q}};
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.obj"), scene.high).is_ok());
}

// The id map in the materials' own colours: Kd as the DCC shows it
// (sRGB-encoded), a hue for a material without Kd and for two that share one.
TEST(Transfer, IdMapTakesTheMaterialsOwnColours) {
  test::TempDir dir;
  write_four_material_scene(dir, {"red", "plain", "grey_a", "grey_b"});
  test::write_text(dir.file("high.obj"), "mtllib high.mtl\n" + read_bytes(dir.file("high.obj")));
  test::write_text(dir.file("high.mtl"),
                   "newmtl red\nKd 0.5 0.1 0.05\nnewmtl plain\nNs 10\nnewmtl grey_a\nKd 0.8 0.8 0.8\n"
                   "newmtl grey_b\nKd 0.8 0.8 0.8\n");
  BakeOptions o = transfer_bake(dir, 32);
  o.maps = {MapKind::id};
  BakeReport report;
  const Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(report.id_names.size(), 4u);
  for (const auto& [name, color] : report.id_names) {
    if (name == "red") {
      EXPECT_EQ(color, glm::vec3(linear_to_srgb(0.5f), linear_to_srgb(0.1f), linear_to_srgb(0.05f)));
    } else {
      EXPECT_EQ(color, part_color(name)) << name;
    }
  }
}

// A palette file gives the artist's colours by name, shared ones included;
// the names it does not give are coloured as without it. Its mistakes are
// exit 2 naming the file (and line), before anything is written.
TEST(Transfer, IdPaletteGivesTheArtistsColours) {
  test::TempDir dir;
  write_four_material_scene(dir, {"red", "plain", "grey a", "grey_b"});
  test::write_text(dir.file("palette.toml"),
                   "# id colours\nred = \"#00FF00\"\n\"grey a\" = \"#123456\"\ngrey_b = \"#123456\"\n"
                   "absent = \"#ffffff\"\n");
  BakeOptions o = transfer_bake(dir, 32);
  o.maps = {MapKind::id};
  o.id_palette = dir.file("palette.toml");
  BakeReport report;
  Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(report.id_names.size(), 4u);
  const glm::vec3 grey(0x12 / 255.0f, 0x34 / 255.0f, 0x56 / 255.0f);
  for (const auto& [name, color] : report.id_names) {
    const glm::vec3 expected = name == "red" ? glm::vec3(0, 1, 0) : name == "plain" ? part_color(name) : grey;
    EXPECT_EQ(color, expected) << name;
  }
  // The map holds exactly those colours (EXR: the values as baked).
  Image map;
  ASSERT_TRUE(read_image(dir.file("m_id.exr"), map).is_ok());
  std::set<std::array<float, 3>> seen;
  for (std::size_t i = 0; i < map.pixels.size(); i += 3)
    seen.insert({map.pixels[i], map.pixels[i + 1], map.pixels[i + 2]});
  EXPECT_TRUE(seen.count({0.0f, 1.0f, 0.0f}));
  EXPECT_TRUE(seen.count({grey.r, grey.g, grey.b}));
  // Mistakes, through the command line.
  const std::string base = test::cli_path() + " bake --low " + dir.file("low.obj") + " --high " +
                           dir.file("high.obj") + " --size 32 --map id -o " + dir.file("x.png");
  test::write_text(dir.file("bad.toml"), "red = \"#00FF00\"\nplain = \"green\"\n");
  test::write_text(dir.file("broken.toml"), "red = \"#00FF00\"\nplain = \n");
  struct Case {
    std::string flags, expected;
  };
  for (const Case& c : {Case{"--id-palette " + dir.file("bad.toml"), dir.file("bad.toml") + ":2: 'plain'"},
                        Case{"--id-palette " + dir.file("broken.toml"), dir.file("broken.toml") + ":2"},
                        Case{"--id-palette " + dir.file("none.toml"), dir.file("none.toml")},
                        Case{"--id-palette " + dir.file("palette.toml") + " --id-source vertex-color",
                             "takes the colours as painted"}}) {
    SCOPED_TRACE(c.flags);
    const test::CommandResult r = test::run_command(base + " " + c.flags + " -q 2>&1");
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find(c.expected), std::string::npos) << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir.file("x.png")));
  }
}

// --id-source vertex-color: each triangle takes the colour most of its
// corners have; a high without colours is exit 2.
TEST(Transfer, IdMapFromVertexColours) {
  TransferScene scene = make_scene();
  const Bounds b = compute_bounds(scene.high);
  const float middle = 0.5f * (b.min.x + b.max.x);
  for (const glm::vec3& p : scene.high.positions) {
    scene.high.colors.push_back(p.x < middle ? glm::vec4(1, 0, 0, 1) : glm::vec4(0, 0, 1, 1));
  }
  test::TempDir dir;
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), scene.high).is_ok());
  BakeOptions o = transfer_bake(dir, 32);
  o.high_paths = {dir.file("high.ply")};
  o.maps = {MapKind::id};
  o.id_source = IdSource::vertex_color;
  BakeReport report;
  Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(report.id_names.size(), 2u);
  EXPECT_EQ(report.id_names[0].first, "#ff0000");
  EXPECT_EQ(report.id_names[0].second, glm::vec3(1, 0, 0));
  EXPECT_EQ(report.id_names[1].first, "#0000ff");
  Image map;
  ASSERT_TRUE(read_image(dir.file("m_id.exr"), map).is_ok());
  std::set<std::array<float, 3>> seen;
  for (std::size_t i = 0; i < map.pixels.size(); i += 3)
    seen.insert({map.pixels[i], map.pixels[i + 1], map.pixels[i + 2]});
  EXPECT_EQ(seen, (std::set<std::array<float, 3>>{{1, 0, 0}, {0, 0, 1}, {0, 0, 0}}));
  scene.high.colors.clear();
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), scene.high).is_ok());
  s = bake(o, report);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("no vertex colours"), std::string::npos) << s.message();
}

// The cache key holds the meshes' bytes; the files a bake reads besides
// them (MTL, textures, a glTF's buffers) are checked when an entry is
// fetched: a texture painted over, or a .bin whose .gltf did not change, is
// baked again (and stored in place of the old entry), never served stale.
TEST(Transfer, CachedBakesNoticeChangedTexturesAndBuffers) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  ASSERT_TRUE(write_image(texture_image(64, true), dir.file("albedo.png"), PixelFormat::png8).is_ok());
  write_scene(dir, scene, "albedo.png");
  ASSERT_TRUE(save_mesh(dir.file("high.gltf"), scene.high).is_ok());
  const auto run = [&](const std::string& high, const std::string& map) {
    return test::run_command(test::cli_path() + " bake --low " + dir.file("low.obj") + " --high " +
                             dir.file(high) + " --size 32 --map " + map + " --cache " + dir.file("cache") +
                             " -o " + dir.file("out.png") + " --report " + dir.file("r.json") + " 2>&1");
  };
  const auto cached = [&] {
    return nlohmann::json::parse(read_bytes(dir.file("r.json"))).value("cached", false);
  };
  test::CommandResult r = run("high.obj", "base-color");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string first = read_bytes(dir.file("out.png"));
  const nlohmann::json report = nlohmann::json::parse(read_bytes(dir.file("r.json")));
  EXPECT_EQ(report["input_files"], nlohmann::json({dir.file("high.mtl"), dir.file("albedo.png")}));
  r = run("high.obj", "base-color");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(cached());
  // The texture painted over: baked again, with the new colours.
  ASSERT_TRUE(write_image(texture_image(64, false), dir.file("albedo.png"), PixelFormat::png8).is_ok());
  r = run("high.obj", "base-color");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find(dir.file("albedo.png") + ": changed since the entry was stored"), std::string::npos)
      << r.output;
  EXPECT_FALSE(cached());
  EXPECT_TRUE(read_bytes(dir.file("out.png")) != first);
  const std::string second = read_bytes(dir.file("out.png"));
  r = run("high.obj", "base-color");
  EXPECT_TRUE(cached());
  EXPECT_TRUE(read_bytes(dir.file("out.png")) == second);
  // A glTF whose buffer changed under the same .gltf bytes.
  r = run("high.gltf", "normal");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string flat = read_bytes(dir.file("out.png"));
  // Every vertex but the lowest and highest moves (the accessor's min and
  // max, in the .gltf, stay as they were).
  Mesh moved = scene.high;
  const Bounds bounds = compute_bounds(moved);
  for (glm::vec3& p : moved.positions) {
    if (p.z != bounds.min.z && p.z != bounds.max.z) p.z = 0.5f * (p.z + 0.5f * (bounds.min.z + bounds.max.z));
  }
  MeshStats normal_stats;
  compute_vertex_normals(moved, normal_stats);
  const std::string gltf = read_bytes(dir.file("high.gltf"));
  ASSERT_TRUE(save_mesh(dir.file("high.gltf"), moved).is_ok());
  ASSERT_EQ(read_bytes(dir.file("high.gltf")), gltf);
  r = run("high.gltf", "normal");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(cached()) << r.output;
  EXPECT_TRUE(read_bytes(dir.file("out.png")) != flat);
}

// Packed outputs: each channel equals the channel of the map's own file at
// that depth (mapped, sRGB-encoded, dithered as the map alone is); an
// inverted channel is 1 minus it; a constant is its step.
TEST(Transfer, PackedChannelsEqualTheMapsBakedAlone) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  ASSERT_TRUE(write_image(texture_image(128, true), dir.file("albedo.png"), PixelFormat::png16).is_ok());
  write_scene(dir, scene, "albedo.png");
  BakeOptions o = transfer_bake(dir, 64);
  o.maps = {MapKind::base_color, MapKind::roughness, MapKind::height};
  o.outputs = {{dir.file("m_<MAP>.png"), PixelFormat::png8, true}};
  PackSpec pack, orm;
  ASSERT_TRUE(
      parse_pack(dir.file("p.png") + "=r:height,g:roughness,b:base-color.g,a:1-roughness", pack).is_ok());
  ASSERT_TRUE(parse_pack(dir.file("p16.tif") + "=r:height,g:0.25,b:base-color.r", orm).is_ok());
  o.packs = {pack, orm};
  BakeReport report;
  const Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  Image p, height, rough, base;
  ASSERT_TRUE(read_image(dir.file("p.png"), p).is_ok());
  ASSERT_TRUE(read_image(dir.file("m_height.png"), height).is_ok());
  ASSERT_TRUE(read_image(dir.file("m_roughness.png"), rough).is_ok());
  ASSERT_TRUE(read_image(dir.file("m_base-color.png"), base).is_ok());
  ASSERT_EQ(p.channels, 4);
  ASSERT_EQ(p.pixels.size(), height.pixels.size() * 4);
  for (std::size_t t = 0; t < height.pixels.size(); ++t) {
    ASSERT_EQ(p.pixels[4 * t], height.pixels[t]) << t;
    ASSERT_EQ(p.pixels[4 * t + 1], rough.pixels[t]) << t;
    ASSERT_EQ(p.pixels[4 * t + 2], base.pixels[3 * t + 1]) << t;
    ASSERT_NEAR(p.pixels[4 * t + 3], 1.0f - rough.pixels[t], 1.5f / 255) << t;
  }
  // 16-bit TIFF: the maps written at 16 bits are its channels.
  o.packs.clear();
  o.outputs = {{dir.file("w_<MAP>.tif"), PixelFormat::tiff16, true}};
  ASSERT_TRUE(bake(o, report).is_ok());
  Image t16, h16, b16;
  ASSERT_TRUE(read_image(dir.file("p16.tif"), t16).is_ok());
  ASSERT_TRUE(read_image(dir.file("w_height.tif"), h16).is_ok());
  ASSERT_TRUE(read_image(dir.file("w_base-color.tif"), b16).is_ok());
  ASSERT_EQ(t16.channels, 3);
  for (std::size_t t = 0; t < h16.pixels.size(); ++t) {
    ASSERT_EQ(t16.pixels[3 * t], h16.pixels[t]) << t;
    ASSERT_EQ(t16.pixels[3 * t + 1], std::round(0.25f * 65535) / 65535) << t;
    ASSERT_EQ(t16.pixels[3 * t + 2], b16.pixels[3 * t]) << t;
  }
}

// A pack of a map the bake does not make, or two outputs writing one file:
// exit 2 before anything is baked, nothing written.
TEST(Transfer, PackMistakesAreFoundBeforeTheBake) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  ASSERT_TRUE(write_image(texture_image(64, true), dir.file("albedo.png"), PixelFormat::png8).is_ok());
  write_scene(dir, scene, "albedo.png");
  BakeOptions o = transfer_bake(dir, 32);
  PackSpec pack;
  ASSERT_TRUE(parse_pack(dir.file("orm.png") + "=r:ao,g:roughness,b:metallic", pack).is_ok());
  o.packs = {pack};
  BakeReport report;
  Status s = bake(o, report);
  EXPECT_EQ(s.code(), StatusCode::bad_input);
  EXPECT_NE(s.message().find("it packs ao, which --map does not bake"), std::string::npos) << s.message();
  ASSERT_TRUE(parse_pack(dir.file("m_roughness.exr") + "=r:roughness", pack).is_ok());
  o.packs = {pack};
  s = bake(o, report);
  EXPECT_EQ(s.code(), StatusCode::bad_input);
  EXPECT_NE(s.message().find("is also written by another output"), std::string::npos) << s.message();
  EXPECT_FALSE(std::filesystem::exists(dir.file("m_base-color.exr")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("orm.png")));
  for (const char* bad : {"orm.png", "orm.png=g:ao", "orm.png=r:normal", "orm.png=r:ao,g:ao", "orm.png=r:2",
                          "orm.png=r:ao.r", "o_<MAP>.png=r:ao"}) {
    EXPECT_EQ(parse_pack(bad, pack).code(), StatusCode::bad_input) << bad;
  }
}

// Opacity and emission from MTL: map_d reads the texture's alpha (here a
// known function), d the factor of a material without one; Ke alone gives
// its colour, map_Ke replaces it.
TEST(Transfer, OpacityAndEmissionFromMtl) {
  TransferScene scene = make_scene();
  const auto n = static_cast<std::uint32_t>(scene.high.triangle_count());
  scene.high.materials = {{"masked", 0, n / 2}, {"glow", n / 2, n - n / 2}};
  test::TempDir dir;
  Image alpha = texture_image(128, false);
  Image rgba;
  rgba.width = rgba.height = 128;
  rgba.channels = 4;
  for (int j = 0; j < 128; ++j) {
    for (int i = 0; i < 128; ++i) {
      const float* p = alpha.at(i, j);
      rgba.pixels.insert(rgba.pixels.end(), {0.5f, 0.5f, 0.5f, p[0]});  // alpha = red(s, t), linear
    }
  }
  ASSERT_TRUE(write_image(rgba, dir.file("cutout.png"), PixelFormat::png16).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.obj"), scene.high).is_ok());
  test::write_text(dir.file("high.obj"), "mtllib high.mtl\n" + read_bytes(dir.file("high.obj")));
  test::write_text(dir.file("high.mtl"),
                   "newmtl masked\nd 0.3\nmap_d cutout.png\nnewmtl glow\nd 0.4\nKe 0.2 0.5 1.0\n");
  BakeOptions o = transfer_bake(dir, 64);
  o.maps = {MapKind::opacity, MapKind::emissive};
  BakeReport report;
  const Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  Image opacity, emissive;
  ASSERT_TRUE(read_image(dir.file("m_opacity.exr"), opacity).is_ok());
  ASSERT_TRUE(read_image(dir.file("m_emissive.exr"), emissive).is_ok());
  // Which material a point hits: the high's first half of triangles is its
  // lower rows (make_heightfield writes rows from y's minimum).
  const double split_y = scene.min_y + scene.side / 2;
  // Texels within two of the materials' border are not scored: a sample
  // there may fall either side (float against double).
  const auto expected = [&](const std::function<double(const glm::dvec3&, bool)>& f) {
    const double margin = 2.0 * scene.side / (0.4 * 64);
    scenes::ExpectedMap map = scenes::expected_from_low_points(
        scene.low, 64, 64, 4, [&](const glm::dvec3& p) { return f(p, p.y < split_y); });
    const scenes::ExpectedMap near = scenes::expected_from_low_points(
        scene.low, 64, 64, 4,
        [&](const glm::dvec3& p) { return std::abs(p.y - split_y) < margin ? 1.0 : 0.0; });
    for (std::size_t i = 0; i < map.value.size(); ++i) {
      if (near.value[i] > 0.0) map.value[i] = std::numeric_limits<double>::quiet_NaN();
    }
    return map;
  };
  const scenes::MapError e = scenes::score_map(opacity, 0, expected([&](const glm::dvec3& p, bool masked) {
                                                 const glm::dvec2 uv = scene.uv_of(p);
                                                 return masked ? red(uv.x, uv.y) : 0.4;
                                               }));
  EXPECT_GT(e.texels, 2000u);
  EXPECT_LT(e.max, filter_bound(64, 128, 16)) << e.to_text();
  const scenes::MapError glow = scenes::score_map(
      emissive, 2, expected([](const glm::dvec3&, bool masked) { return masked ? 0.0 : 1.0; }));
  EXPECT_LT(glow.max, 1e-6) << glow.to_text();
}

// PNG outputs of colour maps are sRGB-encoded (8-bit), EXR linear: the PNG
// read back and decoded equals the EXR within the 8-bit step.
TEST(Transfer, ColourMapsAreSrgbInPngAndLinearInExr) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  ASSERT_TRUE(write_image(texture_image(128, true), dir.file("albedo.png"), PixelFormat::png16).is_ok());
  write_scene(dir, scene, "albedo.png");
  BakeOptions o = transfer_bake(dir, 64);
  o.maps = {MapKind::base_color};
  o.outputs = {{dir.file("c.exr"), PixelFormat::exr_float}, {dir.file("c.png"), PixelFormat::png8}};
  o.dither = false;
  BakeReport report;
  ASSERT_TRUE(bake(o, report).is_ok());
  Image exr, png;
  ASSERT_TRUE(read_image(dir.file("c.exr"), exr).is_ok());
  ASSERT_TRUE(read_image(dir.file("c.png"), png).is_ok());
  ASSERT_EQ(exr.pixels.size(), png.pixels.size());
  double largest = 0;
  for (std::size_t i = 0; i < exr.pixels.size(); ++i) {
    largest = std::max(largest, std::abs(static_cast<double>(linear_to_srgb(exr.pixels[i]) - png.pixels[i])));
  }
  EXPECT_LE(largest, 0.5 / 255 + 1e-6);
}

// One thread or all: the same bytes.
TEST(Transfer, SameBytesForOneThreadAndAll) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  ASSERT_TRUE(write_image(texture_image(128, true), dir.file("albedo.png"), PixelFormat::png8).is_ok());
  write_scene(dir, scene, "albedo.png");
  BakeOptions o = transfer_bake(dir, 96);
  o.outputs = {{dir.file("all_<MAP>.png"), PixelFormat::png8}};
  BakeReport report;
  ASSERT_TRUE(bake(o, report).is_ok());
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    o.outputs = {{dir.file("one_<MAP>.png"), PixelFormat::png8}};
    ASSERT_TRUE(bake(o, report).is_ok());
  }
  // Tiles of rows, baked in any order and merged: the whole bake's bytes.
  const Status s =
      test::bake_tiles_and_merge(o, 3, dir.path(), {{dir.file("merged_<MAP>.png"), PixelFormat::png8}});
  ASSERT_TRUE(s.is_ok()) << s.message();
  for (const char* map : {"base-color", "roughness"}) {
    const std::string all = read_bytes(dir.file(std::string("all_") + map + ".png"));
    EXPECT_FALSE(all.empty());
    EXPECT_TRUE(all == read_bytes(dir.file(std::string("one_") + map + ".png"))) << map;
    EXPECT_TRUE(all == read_bytes(dir.file(std::string("merged_") + map + ".png"))) << map;
  }
}

// A texture that is not there: exit 2 naming the material and the path,
// nothing written.
TEST(Transfer, MissingTextureNamesTheMaterialAndThePath) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  write_scene(dir, scene, "textures/gone.png");
  BakeOptions o = transfer_bake(dir, 32);
  BakeReport report;
  const Status s = bake(o, report);
  ASSERT_FALSE(s.is_ok());
  EXPECT_EQ(s.code(), StatusCode::bad_input);
  EXPECT_NE(s.message().find("material 'scan'"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("gone.png"), std::string::npos) << s.message();
  EXPECT_FALSE(std::filesystem::exists(dir.file("m_base-color.exr")));
  // A missing MTL is named too.
  test::write_text(dir.file("high.obj"), "mtllib nowhere.mtl\n" + read_bytes(dir.file("high.obj")));
  std::filesystem::remove(dir.file("high.mtl"));
  const Status missing = bake(o, report);
  ASSERT_FALSE(missing.is_ok());
  EXPECT_NE(missing.message().find("mtllib 'nowhere.mtl'"), std::string::npos) << missing.message();
}

// Corner UVs do not change the high mesh: the same vertices, triangles and
// normals as a load without them, and the UVs of every corner.
TEST(Transfer, CornerUvsLeaveTheHighMeshAsItWas) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  write_scene(dir, scene, "albedo.png");
  for (const bool serial : {false, true}) {
    LoadOptions plain{false, true};
    plain.serial = serial;
    LoadOptions with = plain;
    with.corner_uvs = with.material_defs = true;
    Mesh a, b;
    LoadStats sa, sb;
    ASSERT_TRUE(load_mesh(dir.file("high.obj"), plain, a, sa).is_ok());
    ASSERT_TRUE(load_mesh(dir.file("high.obj"), with, b, sb).is_ok());
    EXPECT_TRUE(a.positions == b.positions);
    EXPECT_TRUE(a.indices == b.indices);
    EXPECT_TRUE(a.normals == b.normals);
    ASSERT_EQ(b.corner_uvs.size(), b.indices.size());
    for (std::size_t i = 0; i < b.indices.size(); ++i) {
      const glm::vec3 p = b.positions[b.indices[i]];
      EXPECT_NEAR(b.corner_uvs[i].x, (p.x - scene.min_x) / scene.side, 1e-5);
      EXPECT_NEAR(b.corner_uvs[i].y, (p.y - scene.min_y) / scene.side, 1e-5);
    }
    ASSERT_EQ(b.material_defs.size(), 1u);
    EXPECT_EQ(b.material_defs[0].name, "scan");
    EXPECT_FLOAT_EQ(b.material_defs[0].roughness, 0.6f);
    EXPECT_EQ(b.material_defs[0].base_color, glm::vec4(1.0f));  // map_Kd replaces Kd
    EXPECT_EQ(sb.corners_without_uvs, 0u);
  }
}

// ------------------------------------------------ FBX / Collada and embedded images

// `mesh` as a Collada file (Y up, metres: Assimp leaves the root as it is)
// with one material `material` on every triangle, whose diffuse is `diffuse`:
// a <color> or a <texture> of the file `image`. Reals with 9 significant
// digits (a float's). (Collada 1.4's <hex> embedded images make Debian's
// Assimp 5.2.5 abort on an assertion, ColladaParser.cpp:256: not tested.)
std::string collada_text(const Mesh& mesh, const std::string& material, const std::string& diffuse_color,
                         const std::string& image) {
  std::string out;
  char buffer[64];
  const auto real = [&](float v) {
    std::snprintf(buffer, sizeof buffer, "%.9g ", static_cast<double>(v));
    out += buffer;
  };
  out +=
      "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
      "<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">\n"
      "<asset><unit name=\"meter\" meter=\"1\"/><up_axis>Y_UP</up_axis></asset>\n";
  const bool textured = !image.empty();
  if (textured) {
    out += "<library_images><image id=\"img\" name=\"img\"><init_from>" + image;
    out += "</init_from></image></library_images>\n";
  }
  out += "<library_effects><effect id=\"fx\"><profile_COMMON>\n";
  if (textured) {
    out +=
        "<newparam sid=\"surface\"><surface type=\"2D\"><init_from>img</init_from></surface></newparam>\n"
        "<newparam sid=\"sampler\"><sampler2D><source>surface</source></sampler2D></newparam>\n";
  }
  out += "<technique sid=\"common\"><lambert><diffuse>";
  out +=
      textured ? "<texture texture=\"sampler\" texcoord=\"UVMap\"/>" : "<color>" + diffuse_color + "</color>";
  out += "</diffuse></lambert></technique></profile_COMMON></effect></library_effects>\n";
  out += "<library_materials><material id=\"mat\" name=\"" + material +
         "\"><instance_effect url=\"#fx\"/></material></library_materials>\n";
  const std::size_t n = mesh.positions.size();
  out +=
      "<library_geometries><geometry id=\"g\" name=\"g\"><mesh>\n<source id=\"pos\"><float_array "
      "id=\"pos-a\" "
      "count=\"" +
      std::to_string(3 * n) + "\">";
  for (const glm::vec3& p : mesh.positions) {
    real(p.x);
    real(p.y);
    real(p.z);
  }
  out +=
      "</float_array><technique_common><accessor source=\"#pos-a\" count=\"" + std::to_string(n) +
      "\" stride=\"3\"><param name=\"X\" type=\"float\"/><param name=\"Y\" type=\"float\"/><param name=\"Z\" "
      "type=\"float\"/></accessor></technique_common></source>\n";
  out += "<source id=\"uv\"><float_array id=\"uv-a\" count=\"" + std::to_string(2 * n) + "\">";
  for (const glm::vec2& uv : mesh.uvs) {
    real(uv.x);
    real(uv.y);
  }
  out += "</float_array><technique_common><accessor source=\"#uv-a\" count=\"" + std::to_string(n) +
         "\" stride=\"2\"><param name=\"S\" type=\"float\"/><param name=\"T\" "
         "type=\"float\"/></accessor></technique_common></source>\n";
  out += "<vertices id=\"v\"><input semantic=\"POSITION\" source=\"#pos\"/></vertices>\n";
  out += "<triangles material=\"sym\" count=\"" + std::to_string(mesh.triangle_count()) +
         "\"><input semantic=\"VERTEX\" source=\"#v\" offset=\"0\"/><input semantic=\"TEXCOORD\" "
         "source=\"#uv\" offset=\"0\" set=\"0\"/><p>";
  for (const std::uint32_t i : mesh.indices) out += std::to_string(i) + " ";
  out +=
      "</p></triangles>\n</mesh></geometry></library_geometries>\n"
      "<library_visual_scenes><visual_scene id=\"s\"><node id=\"high\" name=\"high\"><instance_geometry "
      "url=\"#g\"><bind_material><technique_common><instance_material symbol=\"sym\" target=\"#mat\">"
      "<bind_vertex_input semantic=\"UVMap\" input_semantic=\"TEXCOORD\" input_set=\"0\"/>"
      "</instance_material></technique_common></bind_material></instance_geometry></node></visual_scene>"
      "</library_visual_scenes>\n<scene><instance_visual_scene url=\"#s\"/></scene>\n</COLLADA>\n";
  return out;
}

// The largest difference between two images of the same size.
float largest_difference(const Image& a, const Image& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.pixels.size(), b.pixels.size());
  float most = 0.0f;
  for (std::size_t i = 0; i < std::min(a.pixels.size(), b.pixels.size()); ++i)
    most = std::max(most, std::abs(a.pixels[i] - b.pixels[i]));
  return most;
}

// An FBX or Collada high whose material's diffuse is a texture bakes the
// base colour its OBJ + MTL twin (map_Kd, the same image) bakes: a texture
// file beside the .dae; beside the .fbx under an absolute path from the
// artist's machine (found by its file name), and embedded in the .fbx (a
// Video's Content: Assimp's embedded texture). Read through the child
// process (load/isolated.hpp), so materials, corner UVs and the embedded
// image cross the pipe. Bit for bit: the FBX's coordinates are doubles,
// each read back to the float the OBJ holds, and the Collada's 9-digit
// reals read back to the same floats here (Assimp's fast_atoreal_move is
// not correctly rounded in general, so another file might differ in a
// last bit).
TEST(Transfer, FbxAndColladaMaterialsBakeAsTheirObjTwin) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  ASSERT_TRUE(write_image(texture_image(128, true), dir.file("albedo.png"), PixelFormat::png16).is_ok());
  write_scene(dir, scene, "albedo.png");
  BakeOptions o = transfer_bake(dir, 64);
  o.maps = {MapKind::base_color};
  BakeReport report;
  Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  Image from_obj;
  ASSERT_TRUE(read_image(dir.file("m_base-color.exr"), from_obj).is_ok());

  const std::string png = read_bytes(dir.file("albedo.png"));
  test::write_text(dir.file("high.dae"), collada_text(scene.high, "scan", "", "albedo.png"));
  gen::FbxModel model;
  model.material = "scan";
  model.texture = "C:\\Users\\artist\\textures\\albedo.png";
  ASSERT_TRUE(gen::write_fbx_binary(dir.file("high.fbx"), scene.high, model).is_ok());
  model.embedded = png;
  ASSERT_TRUE(gen::write_fbx_binary(dir.file("embedded.fbx"), scene.high, model).is_ok());
  for (const char* name : {"high.dae", "high.fbx", "embedded.fbx"}) {
    SCOPED_TRACE(name);
    const bool embedded = std::string(name) == "embedded.fbx";
    LoadOptions options{false, true};
    options.corner_uvs = options.material_defs = true;
    Mesh high;
    LoadStats stats;
    s = load_mesh(dir.file(name), options, high, stats);
    ASSERT_TRUE(s.is_ok()) << s.message();
    ASSERT_EQ(high.material_defs.size(), 1u);
    EXPECT_EQ(high.material_defs[0].name, "scan");
    EXPECT_EQ(high.corner_uvs.size(), high.indices.size());
    EXPECT_EQ(stats.corners_without_uvs, 0u);
    const TextureRef& ref = high.material_defs[0].base_color_texture;
    EXPECT_EQ(ref.problem, "");
    if (embedded) {
      ASSERT_EQ(ref.embedded, 0) << ref.path;
      ASSERT_EQ(high.embedded_images.size(), 1u);
      const std::vector<unsigned char>& bytes = high.embedded_images[0].bytes;
      EXPECT_TRUE(std::string(bytes.begin(), bytes.end()) == png);
      std::filesystem::rename(dir.file("albedo.png"), dir.file("elsewhere.png"));  // not read from the folder
    } else {
      EXPECT_EQ(ref.path, dir.file("albedo.png"));
    }
    o.high_paths = {dir.file(name)};
    s = bake(o, report);
    ASSERT_TRUE(s.is_ok()) << s.message();
    Image baked;
    ASSERT_TRUE(read_image(dir.file("m_base-color.exr"), baked).is_ok());
    EXPECT_EQ(largest_difference(from_obj, baked), 0.0f);
  }
  // A broken embedded texture in the FBX: exit 2 naming the file, the
  // material and the embedded image, nothing written.
  model.embedded = png.substr(0, 64) + std::string(64, 'x');
  ASSERT_TRUE(gen::write_fbx_binary(dir.file("broken.fbx"), scene.high, model).is_ok());
  std::filesystem::remove(dir.file("m_base-color.exr"));
  o.high_paths = {dir.file("broken.fbx")};
  s = bake(o, report);
  ASSERT_FALSE(s.is_ok());
  EXPECT_EQ(s.code(), StatusCode::bad_input) << s.message();
  EXPECT_NE(
      s.message().find(dir.file("broken.fbx") + ": material 'scan', base colour texture (embedded image 0)"),
      std::string::npos)
      << s.message();
  EXPECT_FALSE(std::filesystem::exists(dir.file("m_base-color.exr")));
}

// The id map colours an FBX or Collada material in its own diffuse colour,
// as an MTL's Kd (IdMapTakesTheMaterialsOwnColours).
TEST(Transfer, IdMapTakesTheFbxAndColladaDiffuseColour) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  test::write_text(dir.file("high.dae"), collada_text(scene.high, "red", "0.5 0.1 0.05 1", ""));
  gen::FbxModel model;
  model.material = "red";
  model.diffuse = glm::dvec3(0.5, 0.1, 0.05);
  ASSERT_TRUE(gen::write_fbx_binary(dir.file("high.fbx"), scene.high, model).is_ok());
  for (const char* name : {"high.dae", "high.fbx"}) {
    SCOPED_TRACE(name);
    BakeOptions o = transfer_bake(dir, 32);
    o.high_paths = {dir.file(name)};
    o.maps = {MapKind::id};
    BakeReport report;
    const Status s = bake(o, report);
    ASSERT_TRUE(s.is_ok()) << s.message();
    ASSERT_EQ(report.id_names.size(), 1u);
    EXPECT_EQ(report.id_names[0].first, "red");
    EXPECT_EQ(report.id_names[0].second,
              glm::vec3(linear_to_srgb(0.5f), linear_to_srgb(0.1f), linear_to_srgb(0.05f)));
  }
}

std::string base64(const std::string& bytes) {
  static const char* const kTable = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::size_t n = std::min<std::size_t>(3, bytes.size() - i);
    std::uint32_t v = 0;
    for (std::size_t k = 0; k < 3; ++k)
      v = (v << 8) | (k < n ? static_cast<unsigned char>(bytes[i + k]) : 0u);
    for (std::size_t k = 0; k < 4; ++k) out += k <= n ? kTable[(v >> (18 - 6 * k)) & 63] : '=';
  }
  return out;
}

// A .glb of the glTF `doc` whose buffer 0 is `bin` plus `image` (4-byte
// aligned), image 0 then a buffer view of those bytes.
std::string glb_with_image(nlohmann::json doc, std::string bin, const std::string& image) {
  while (bin.size() % 4 != 0) bin += '\0';
  const std::size_t offset = bin.size();
  bin += image;
  while (bin.size() % 4 != 0) bin += '\0';
  doc["buffers"] = {{{"byteLength", bin.size()}}};
  doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", image.size()}});
  doc["images"] = {{{"bufferView", doc["bufferViews"].size() - 1}, {"mimeType", "image/png"}}};
  std::string json = doc.dump();
  while (json.size() % 4 != 0) json += ' ';
  std::string out = "glTF";
  const auto u32 = [&](std::uint32_t v) {
    char b[4];
    std::memcpy(b, &v, 4);
    out.append(b, 4);
  };
  u32(2);
  u32(static_cast<std::uint32_t>(12 + 8 + json.size() + 8 + bin.size()));
  u32(static_cast<std::uint32_t>(json.size()));
  u32(0x4E4F534Au);  // JSON
  out += json;
  u32(static_cast<std::uint32_t>(bin.size()));
  u32(0x004E4942u);  // BIN
  out += bin;
  return out;
}

// The CRC-32 of PNG chunks (ISO 3309), to write a well-formed hostile header.
std::uint32_t crc32(const std::string& bytes) {
  std::uint32_t c = 0xffffffffu;
  for (const unsigned char b : bytes) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return ~c;
}

// A glTF image embedded in a .glb (a buffer view) or in a data: URI bakes
// the same bytes as the same PNG beside the .gltf.
TEST(Transfer, EmbeddedGltfImagesBakeAsTheirFiles) {
  const TransferScene scene = make_scene();
  test::TempDir dir;
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.gltf"), scene.high).is_ok());
  ASSERT_TRUE(write_image(texture_image(128, true), dir.file("albedo.png"), PixelFormat::png8).is_ok());
  nlohmann::json doc = nlohmann::json::parse(read_bytes(dir.file("high.gltf")));
  doc["textures"] = {{{"source", 0}}};
  doc["materials"][0]["pbrMetallicRoughness"] = {{"baseColorTexture", {{"index", 0}}}};
  nlohmann::json beside = doc;
  beside["images"] = {{{"uri", "albedo.png"}}};
  test::write_text(dir.file("high.gltf"), beside.dump());
  BakeOptions o = transfer_bake(dir, 64);
  o.maps = {MapKind::base_color};
  o.outputs = {{dir.file("m_<MAP>.png"), PixelFormat::png8}};
  o.high_paths = {dir.file("high.gltf")};
  BakeReport report;
  Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  const std::string from_file = read_bytes(dir.file("m_base-color.png"));
  ASSERT_FALSE(from_file.empty());

  const std::string png = read_bytes(dir.file("albedo.png"));
  const std::string bin = read_bytes(dir.file(doc["buffers"][0]["uri"].get<std::string>()));
  test::write_text(dir.file("high.glb"), glb_with_image(doc, bin, png));
  nlohmann::json data_uri = doc;
  data_uri["images"] = {{{"uri", "data:image/png;base64," + base64(png)}}};
  test::write_text(dir.file("inline.gltf"), data_uri.dump());
  std::filesystem::rename(dir.file("albedo.png"), dir.file("elsewhere.png"));  // not read from the folder
  for (const char* high : {"high.glb", "inline.gltf"}) {
    SCOPED_TRACE(high);
    std::filesystem::remove(dir.file("m_base-color.png"));
    o.high_paths = {dir.file(high)};
    s = bake(o, report);
    ASSERT_TRUE(s.is_ok()) << s.message();
    EXPECT_TRUE(read_bytes(dir.file("m_base-color.png")) == from_file);
  }
  // Two files with embedded images (several highs): the second file's
  // texture points at its own image, after the first file's.
  Mesh both;
  LoadStats both_stats;
  LoadOptions both_options{false, true};  // as a high is read
  both_options.material_defs = both_options.corner_uvs = true;
  s = load_meshes({dir.file("high.glb"), dir.file("inline.gltf")}, both_options, both, both_stats);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(both.embedded_images.size(), 2u);
  ASSERT_EQ(both.material_defs.size(), 2u);
  EXPECT_EQ(both.material_defs[0].base_color_texture.embedded, 0);
  EXPECT_EQ(both.material_defs[1].base_color_texture.embedded, 1);

  // A broken embedded image, and one whose header claims 100000 x 100000
  // (its CRC right, so the PNG reader takes the header): exit 2 naming the
  // file, the material and the embedded image, before anything is
  // allocated for the pixels or written.
  std::string huge = png;
  const auto put_u32 = [](std::string& bytes, std::size_t at, std::uint32_t v) {
    for (int k = 0; k < 4; ++k)
      bytes[at + static_cast<std::size_t>(k)] = static_cast<char>(v >> (24 - 8 * k));
  };
  put_u32(huge, 16, 100000);
  put_u32(huge, 20, 100000);
  put_u32(huge, 29, crc32(huge.substr(12, 17)));
  std::string broken = png.substr(0, 60) + std::string(40, 'x');
  for (const auto& [image, reason] :
       {std::pair{huge, std::string("65536 pixels a side")}, std::pair{broken, std::string()}}) {
    test::write_text(dir.file("high.glb"), glb_with_image(doc, bin, image));
    std::filesystem::remove(dir.file("m_base-color.png"));
    o.high_paths = {dir.file("high.glb")};
    s = bake(o, report);
    ASSERT_FALSE(s.is_ok());
    EXPECT_EQ(s.code(), StatusCode::bad_input) << s.message();
    EXPECT_NE(s.message().find(dir.file("high.glb")), std::string::npos) << s.message();
    EXPECT_NE(s.message().find("material '"), std::string::npos) << s.message();
    EXPECT_NE(s.message().find("embedded image 0"), std::string::npos) << s.message();
    EXPECT_NE(s.message().find(reason), std::string::npos) << s.message();
    EXPECT_FALSE(std::filesystem::exists(dir.file("m_base-color.png")));
  }
}

}  // namespace
}  // namespace nmbake
