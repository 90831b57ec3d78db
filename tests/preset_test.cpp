// Outputs as engines want them: every engine preset's map, decoded the way
// that engine documents (or its shader source shows) it decodes, gives back
// the high normal; the preset table, the flag and job-key overrides, the
// report and the key.
//
// The decodes below are written here from each engine's description
// (README, "Outputs as engines want them"), not taken from src/maps/encode.cpp,
// so a wrong inverse there cannot agree with itself.
#include "nmbake/preset.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <iostream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>

#include "nmbake/bake.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/job.hpp"
#include "nmbake/task.hpp"
#include "scenes.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

double angle_degrees(const glm::vec3& a, const glm::vec3& b) {
  const glm::dvec3 da(a), db(b);
  return glm::degrees(std::atan2(glm::length(glm::cross(da, db)), glm::dot(da, db)));
}

// What a renderer's interpolators hand the fragment shader at one point:
// the three corners of the low triangle and the barycentrics.
struct Fragment {
  glm::vec3 normal[3];
  glm::vec4 tangent[3];  // xyz + sign
  glm::vec2 bary;
  template <class V>
  V lerp(const V (&c)[3]) const {
    return c[0] * (1.0f - bary.x - bary.y) + c[1] * bary.x + c[2] * bary.y;
  }
  glm::vec3 N() const { return lerp(normal); }
  glm::vec3 T() const {
    const glm::vec4 t = lerp(tangent);
    return glm::vec3(t);
  }
  float sign() const { return lerp(tangent).w < 0.0f ? -1.0f : 1.0f; }
  // A bitangent computed in the vertex shader from the vertex's attributes
  // and interpolated.
  glm::vec3 vertex_bitangent(bool normalise_per_vertex) const {
    glm::vec3 b[3];
    for (int i = 0; i < 3; ++i) {
      b[i] = glm::cross(normal[i], glm::vec3(tangent[i])) * (tangent[i].w < 0.0f ? -1.0f : 1.0f);
      if (normalise_per_vertex) b[i] = glm::normalize(b[i]);
    }
    return lerp(b);
  }
};

using Decode = std::function<glm::vec3(const glm::vec3& rgb, const Fragment& f)>;

glm::vec3 unpack(const glm::vec3& rgb) { return 2.0f * rgb - 1.0f; }
float rebuilt_z(float x, float y) { return std::sqrt(std::max(0.0f, 1.0f - x * x - y * y)); }

// The decodes, one per preset.
std::map<std::string, Decode> engine_decodes() {
  std::map<std::string, Decode> d;
  // Unity, built-in pipeline (Standard shader): binormal = cross(normal,
  // tangent) * w in the vertex shader, T, B, N interpolated and used as
  // they are; normal maps are DXT5nm/BC5: UnpackNormal rebuilds z =
  // sqrt(1 - saturate(dot(xy, xy))).
  d["unity"] = [](const glm::vec3& rgb, const Fragment& f) {
    const glm::vec3 t = unpack(rgb);
    const float z = std::sqrt(1.0f - std::clamp(t.x * t.x + t.y * t.y, 0.0f, 1.0f));
    return glm::normalize(t.x * f.T() + t.y * f.vertex_bitangent(false) + z * f.N());
  };
  // Unreal: TangentToWorld1 = cross(TangentToWorld2, TangentToWorld0) * w
  // in the pixel shader from the unnormalised interpolants, BC5 normal maps
  // with z rebuilt. Unreal's world is left-handed (its importer mirrors an
  // axis), where that cross product of components is minus the scene's
  // bitangent: in the scene's frame the decode reads x T - g B + z N, with g
  // the stored green (a "DirectX" map).
  d["unreal"] = [](const glm::vec3& rgb, const Fragment& f) {
    const glm::vec3 t = unpack(rgb);
    const glm::vec3 B = f.sign() * glm::cross(f.N(), f.T());
    return glm::normalize(t.x * f.T() - t.y * B + rebuilt_z(t.x, t.y) * f.N());
  };
  // Godot 4: binormal = normalize(cross(normal, tangent) * sign) per vertex;
  // the fragment shader normalises tangent, binormal and normal, ignores the
  // blue channel (z = sqrt(max(0, 1 - dot(xy, xy)))) and takes
  // normalize(tangent * x + binormal * y + normal * z).
  d["godot"] = [](const glm::vec3& rgb, const Fragment& f) {
    const glm::vec3 t = unpack(rgb);
    return glm::normalize(t.x * glm::normalize(f.T()) + t.y * glm::normalize(f.vertex_bitangent(true)) +
                          rebuilt_z(t.x, t.y) * glm::normalize(f.N()));
  };
  // Blender (Cycles' normal map node): the unnormalised interpolated tangent
  // and normal, B = sign * cross(normal, tangent), RGB, OpenGL green.
  const Decode per_pixel = [](const glm::vec3& rgb, const Fragment& f) {
    const glm::vec3 t = unpack(rgb);
    return glm::normalize(t.x * f.T() + t.y * (f.sign() * glm::cross(f.N(), f.T())) + t.z * f.N());
  };
  d["blender"] = per_pixel;
  // glTF 2.0: bitangent = cross(normal, tangent.xyz) * tangent.w; the
  // Khronos Sample Viewer computes it per vertex and normalises t, b, ng in
  // the fragment shader; the texel is normalize(rgb * 2 - 1) (scale 1).
  d["gltf"] = [](const glm::vec3& rgb, const Fragment& f) {
    const glm::vec3 t = glm::normalize(unpack(rgb));
    return glm::normalize(t.x * glm::normalize(f.T()) + t.y * glm::normalize(f.vertex_bitangent(false)) +
                          t.z * glm::normalize(f.N()));
  };
  // Maya (OpenGL green) and Substance (per fragment, OpenGL): MikkTSpace per pixel.
  d["maya"] = per_pixel;
  d["substance"] = per_pixel;
  // 3ds Max: DirectX green (Y-): the stored green is minus the scene's y.
  d["3dsmax"] = [](const glm::vec3& rgb, const Fragment& f) {
    const glm::vec3 t = unpack(rgb);
    return glm::normalize(t.x * f.T() - t.y * (f.sign() * glm::cross(f.N(), f.T())) + t.z * f.N());
  };
  return d;
}

// A coarse low sphere (2 x 2 cells a cube face: frames far from
// orthonormal inside a triangle) over a displaced high sphere, one sample a
// texel at 96^2, traced as the baker does.
struct SphereScene {
  scenes::ScenePair pair;
  LowSurface surface;
  TexelSamples samples;
  Hits hits;
  SphereScene() {
    scenes::SphereParams params;
    params.low_cells = 2;
    params.high_cells = 40;
    params.amplitude = 0.05f;
    pair = scenes::make_displaced_sphere(params);
    MeshStats mesh_stats;
    prepare_low_normals(pair.low, mesh_stats);
    normalize_normals(pair.high, mesh_stats);
    pad_for_embree(pair.high);
    SurfaceStats surface_stats;
    surface = build_low_surface(pair.low, nullptr, surface_stats);
    RasterStats raster_stats;
    rasterize(surface, 96, 96, 1, samples, raster_stats);
    HighScene scene;
    EXPECT_TRUE(HighScene::build(pair.high, BuildQuality::medium, false, scene).is_ok());
    RayOptions rays;
    rays.front = 0.2f;
    rays.back = 0.2f;
    TraceStats trace_stats;
    trace(scene, surface, samples, rays, hits, trace_stats);
  }
  glm::vec3 high_normal(std::size_t s) const {
    const std::uint32_t* v = &pair.high.indices[3 * static_cast<std::size_t>(hits.triangle[s])];
    const glm::vec2 b = hits.bary[s];
    return glm::normalize(pair.high.normals[v[0]] * (1.0f - b.x - b.y) + pair.high.normals[v[1]] * b.x +
                          pair.high.normals[v[2]] * b.y);
  }
  Fragment fragment(std::size_t s) const {
    Fragment f;
    const std::size_t base = 3 * static_cast<std::size_t>(samples.triangle[s]);
    for (int i = 0; i < 3; ++i) {
      f.normal[i] = surface.normal[base + i];
      f.tangent[i] = surface.tangent[base + i];
    }
    f.bary = samples.bary[s];
    return f;
  }
  // Largest angle between decode(map) and the high normal over the texels with a hit.
  double worst(const Image& map, const Decode& decode, std::size_t* texels = nullptr) const {
    double worst_angle = 0.0;
    std::size_t count = 0;
    for (std::size_t s = 0; s < samples.triangle.size(); ++s) {
      if (samples.triangle[s] < 0 || hits.triangle[s] < 0) continue;
      const float* p = &map.pixels[3 * s];
      worst_angle =
          std::max(worst_angle, angle_degrees(decode({p[0], p[1], p[2]}, fragment(s)), high_normal(s)));
      ++count;
    }
    if (texels) *texels = count;
    return worst_angle;
  }
};

const SphereScene& sphere_scene() {
  static const SphereScene scene;
  return scene;
}

Image encode_for(const SphereScene& scene, const EnginePreset& preset, EncodeStats& stats, int lanes = 8) {
  EncodeOptions options;
  options.green = preset.green;
  options.decode = preset.decode;
  Image map;
  detail::encode_in_lanes(scene.surface, scene.samples, scene.pair.high, scene.hits, options, map, stats,
                          lanes);
  return map;
}

TEST(EnginePreset, TableHasEveryEngineOnce) {
  std::vector<std::string> names;
  for (const EnginePreset& p : engine_presets()) names.push_back(p.name);
  EXPECT_EQ(names, (std::vector<std::string>{"unity", "unreal", "godot", "blender", "gltf", "maya", "3dsmax",
                                             "substance"}));
  EnginePreset p;
  EXPECT_FALSE(find_engine_preset("Unity", p));
  ASSERT_TRUE(find_engine_preset("unreal", p));
  EXPECT_EQ(p.green, GreenChannel::down);
  EXPECT_EQ(p.decode.bitangent, Bitangent::pixel);
  EXPECT_TRUE(p.decode.rebuild_blue);
}

// The test per preset: the map decoded as the engine decodes it gives back
// the high normal at every texel (float map, one sample a texel: only float
// rounding is left), and the map of the default decode does not (the rule
// matters on this mesh), so the test can fail.
class PresetDecode : public ::testing::TestWithParam<std::string> {};

TEST_P(PresetDecode, EngineDecodeGivesBackTheHighNormal) {
  const SphereScene& scene = sphere_scene();
  EnginePreset preset;
  ASSERT_TRUE(find_engine_preset(GetParam(), preset));
  const Decode decode = engine_decodes().at(GetParam());
  EncodeStats stats;
  const Image map = encode_for(scene, preset, stats);
  std::size_t texels = 0;
  const double worst = scene.worst(map, decode, &texels);
  EXPECT_GT(texels, 3000u);
  EXPECT_LT(worst, 0.01) << GetParam() << ": the engine's decode of its map, degrees";
  EXPECT_EQ(stats.below_horizon, 0u);
  EXPECT_EQ(stats.singular_frames, 0u);
  // The per-pixel, green-up map of a default bake, decoded by this engine:
  // wrong wherever the preset differs from the default.
  if (!(preset.decode == NormalDecode{}) || preset.green != GreenChannel::up) {
    EncodeStats default_stats;
    const Image plain = encode_for(scene, EnginePreset{"default", GreenChannel::up, {}}, default_stats);
    const double wrong = scene.worst(plain, decode);
    EXPECT_GT(wrong, 0.05) << GetParam();
    std::cout << "[ figures ] " << GetParam() << ": its map, its decode: max " << worst
              << " deg; a default map, its decode: max " << wrong << " deg\n";
  }
}

INSTANTIATE_TEST_SUITE_P(Engines, PresetDecode,
                         ::testing::Values("unity", "unreal", "godot", "blender", "gltf", "maya", "3dsmax",
                                           "substance"));

// Each rule on its own changes the decode enough to be seen on this mesh:
// a map baked for one rule and decoded with another is off by more than
// the bound the right decode meets.
TEST(EnginePreset, EachRuleMatters) {
  const SphereScene& scene = sphere_scene();
  const auto decodes = engine_decodes();
  EncodeStats stats;
  EnginePreset unity, godot, gltf;
  ASSERT_TRUE(find_engine_preset("unity", unity) && find_engine_preset("godot", godot) &&
              find_engine_preset("gltf", gltf));
  // Per-vertex B (unity) read per pixel (blender's decode, z stored).
  EXPECT_GT(scene.worst(encode_for(scene, unity, stats), decodes.at("blender")), 0.05);
  // A normalised frame (gltf) read raw: the vertex-bitangent, raw decode.
  const Decode vertex_raw = [](const glm::vec3& rgb, const Fragment& f) {
    const glm::vec3 t = unpack(rgb);
    return glm::normalize(t.x * f.T() + t.y * f.vertex_bitangent(false) + t.z * f.N());
  };
  EXPECT_GT(scene.worst(encode_for(scene, gltf, stats), vertex_raw), 0.05);
  EXPECT_LT(
      scene.worst(
          encode_for(scene, EnginePreset{"x", GreenChannel::up, {Bitangent::vertex, false, false}}, stats),
          vertex_raw),
      0.01);
}

// Every decode gives the bytes of the per-sample path at any lane count.
TEST(EnginePreset, LanesMatchThePerSamplePathForEveryPreset) {
  const SphereScene& scene = sphere_scene();
  for (const EnginePreset& preset : engine_presets()) {
    EncodeStats a, b;
    const Image reference = encode_for(scene, preset, a, 1);
    for (const int lanes : {4, 8}) {
      const Image in_lanes = encode_for(scene, preset, b, lanes);
      ASSERT_EQ(reference.pixels.size(), in_lanes.pixels.size());
      EXPECT_TRUE(std::equal(reference.pixels.begin(), reference.pixels.end(), in_lanes.pixels.begin()))
          << preset.name << " at " << lanes << " lanes";
    }
  }
}

// rebuild_blue: a texel below the horizon (t.z < 0) is stored on it, and
// counted; others are left as they are.
TEST(EnginePreset, RebuiltBlueStoresTheHorizonBelowIt) {
  glm::vec3 t = glm::normalize(glm::vec3(0.6f, -0.8f, -0.3f));
  EXPECT_FALSE(onto_upper_hemisphere(t));
  EXPECT_NEAR(t.x, 0.6f, 1e-6f);
  EXPECT_NEAR(t.y, -0.8f, 1e-6f);
  EXPECT_EQ(t.z, 0.0f);
  glm::vec3 up = glm::normalize(glm::vec3(0.1f, 0.2f, 0.9f));
  const glm::vec3 before = up;
  EXPECT_TRUE(onto_upper_hemisphere(up));
  EXPECT_EQ(up, before);
  glm::vec3 down(0.0f, 0.0f, -1.0f);
  EXPECT_FALSE(onto_upper_hemisphere(down));
  EXPECT_EQ(down, glm::vec3(0.0f, 0.0f, 1.0f));
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Job files: the preset's rules are applied first, and green / bitangent /
// tbn / blue given anywhere (the bake or [defaults]) override it; an
// unknown preset names the line.
TEST(EnginePreset, JobKeysOverrideThePreset) {
  test::TempDir dir;
  test::write_text(dir.file("job.toml"),
                   "[defaults]\ngreen = \"up\"\n"
                   "[[bake]]\nname = \"a\"\nlow = \"l.obj\"\nhigh = \"h.ply\"\noutputs = [\"a.png\"]\npreset "
                   "= \"unreal\"\n"
                   "[[bake]]\nname = \"b\"\nlow = \"l.obj\"\nhigh = \"h.ply\"\noutputs = [\"b.tga\"]\n"
                   "bitangent = \"pixel\"\npreset = \"godot\"\ndither = \"off\"\n");
  std::vector<BakeJob> jobs;
  ASSERT_TRUE(load_job_file(dir.file("job.toml"), jobs).is_ok());
  ASSERT_EQ(jobs.size(), 2u);
  EXPECT_EQ(jobs[0].options.preset, "unreal");
  EXPECT_EQ(jobs[0].options.encode.green, GreenChannel::up);  // [defaults] green wins
  EXPECT_TRUE(jobs[0].options.encode.decode.rebuild_blue);
  EXPECT_TRUE(jobs[0].options.dither);
  // Given before the preset: still wins.
  EXPECT_EQ(jobs[1].options.encode.decode.bitangent, Bitangent::pixel);
  EXPECT_TRUE(jobs[1].options.encode.decode.unit_frame);
  EXPECT_FALSE(jobs[1].options.dither);
  EXPECT_EQ(jobs[1].options.outputs[0].format, PixelFormat::tga8);
  test::write_text(
      dir.file("bad.toml"),
      "[[bake]]\nlow = \"l.obj\"\nhigh = \"h.ply\"\noutputs = [\"a.png\"]\npreset = \"cryengine\"\n");
  const Status s = load_job_file(dir.file("bad.toml"), jobs);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("bad.toml:5: preset: expected one of: unity, unreal"), std::string::npos)
      << s.message();
}

// Through the CLI: --preset sets the rules, an explicit flag overrides its
// part whichever comes first, the report says what was used, and the key
// changes with each rule and with dither.
TEST(EnginePreset, CliFlagsOverrideThePresetAndTheReportSaysSo) {
  test::TempDir dir;
  scenes::SphereParams params;
  params.low_cells = 2;
  params.high_cells = 24;
  const scenes::ScenePair pair = scenes::make_displaced_sphere(params);
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), pair.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), pair.high).is_ok());
  const std::string base = test::cli_path() + " bake -q --low " + dir.file("low.obj") + " --high " +
                           dir.file("high.ply") + " --size 32 --samples 1";
  const test::CommandResult r = test::run_command(base + " --green up --preset unreal -o " +
                                                  dir.file("m.png") + " --report " + dir.file("r.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json report = nlohmann::json::parse(read_file(dir.file("r.json")));
  const nlohmann::json& e = report.at("encoding");
  EXPECT_EQ(e.at("preset"), "unreal");
  EXPECT_EQ(e.at("green"), "up");
  EXPECT_EQ(e.at("bitangent"), "pixel");
  EXPECT_EQ(e.at("tbn"), "raw");
  EXPECT_EQ(e.at("blue"), "rebuilt");
  EXPECT_EQ(e.at("dither_8bit"), true);
  const test::CommandResult bad = test::run_command(base + " --preset cryengine -o " + dir.file("x.png"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.output.find("--preset cryengine: expected one of: unity, unreal, godot"), std::string::npos)
      << bad.output;
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.png")));

  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.ply")};
  o.outputs = {{dir.file("m.png"), PixelFormat::png8}};
  BakeKey base_key, k;
  ASSERT_TRUE(bake_key(o, base_key).is_ok());
  const std::vector<std::function<void(BakeOptions&)>> changes = {
      [](BakeOptions& x) { x.encode.decode.bitangent = Bitangent::vertex; },
      [](BakeOptions& x) { x.encode.decode.unit_frame = true; },
      [](BakeOptions& x) { x.encode.decode.rebuild_blue = true; },
      [](BakeOptions& x) { x.dither = false; },
      [](BakeOptions& x) { x.preset = "blender"; },
  };
  for (const auto& change : changes) {
    BakeOptions c = o;
    change(c);
    ASSERT_TRUE(bake_key(c, k).is_ok());
    EXPECT_FALSE(k == base_key) << bake_key_text(c);
  }
}

}  // namespace
}  // namespace nmbake
